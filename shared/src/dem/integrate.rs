//! Time integration of rigid bodies: local damping, leapfrog translation and the symplectic
//! splitting of free rotation.

use crate::dem::world::Body;
use crate::math::Vec3;
use nalgebra::UnitQuaternion;

/// PFC local damping of a force (or moment) `f` against velocity `v`: `-alpha |f_i| sign(v_i)`.
pub fn local_damping(f: &Vec3, v: &Vec3, alpha: f64) -> Vec3 {
    if alpha == 0.0 {
        return Vec3::zeros();
    }
    Vec3::from_fn(|i, _| {
        if v[i] == 0.0 {
            0.0
        } else {
            -alpha * f[i].abs() * v[i].signum()
        }
    })
}

/// Advances the orientation of a free rigid rotor with world angular momentum `l` by `dt`:
/// symmetric splitting into rotations about the principal axes (1, 2, 3, 2, 1 with half steps
/// on the outer ones). Each sub-step is an exact rotation, so |L| is kept exactly.
pub fn free_rotation(rot: &mut UnitQuaternion<f64>, l: &Vec3, moments: &Vec3, dt: f64) {
    let mut turn = Turn::of(rot, l);
    for (axis, h) in SPLITTING {
        turn.sub_step(axis, h, moments, dt);
    }
    *rot = turn.orientation();
}

/// [`free_rotation`] of every free body of `bodies`, about its angular momentum, four at a
/// time: each sub-step's turn hangs on the last one's (a chain of some 80 cycles), and four
/// bodies' chains side by side keep the core busy (a body at a time, the rotation was two
/// thirds of the bodies' motion per step). The same numbers as one at a time.
pub fn free_rotations(bodies: &mut [Body], dt: f64) {
    for group in bodies.chunks_mut(4) {
        let mut turns: [Option<Turn>; 4] = [None; 4];
        for (t, b) in turns.iter_mut().zip(group.iter()) {
            *t = (!b.fixed).then(|| Turn::of(&b.rot, &b.ang_mom));
        }
        for (axis, h) in SPLITTING {
            for (t, b) in turns.iter_mut().zip(group.iter()) {
                if let Some(t) = t {
                    t.sub_step(axis, h, &b.moments, dt);
                }
            }
        }
        for (t, b) in turns.iter().zip(group.iter_mut()) {
            if let Some(t) = t {
                b.rot = t.orientation();
            }
        }
    }
}

/// The symmetric splitting of a free rotation into turns about the principal axes: (axis,
/// share of the step).
const SPLITTING: [(usize, f64); 5] = [(0, 0.5), (1, 0.5), (2, 1.0), (1, 0.5), (0, 0.5)];

/// A free rotation under way: the angular momentum in the body's frame and the orientation
/// quaternion's parts.
#[derive(Clone, Copy)]
struct Turn {
    pi: Vec3,
    w: f64,
    v: Vec3,
}

impl Turn {
    fn of(rot: &UnitQuaternion<f64>, l: &Vec3) -> Turn {
        let q = rot.quaternion();
        Turn {
            pi: rot.inverse_transform_vector(l),
            w: q.w,
            v: q.imag(),
        }
    }

    /// The turn about principal axis `axis` for a share `h` of the step:
    /// r = (cos theta/2, sin theta/2 e); the body's angular momentum turns back by theta in
    /// the plane of the other two axes, and the orientation becomes q r. Written out per axis
    /// (a general quaternion product and rotation, with libm's sine and cosine, cost more).
    #[inline(always)]
    fn sub_step(&mut self, axis: usize, h: f64, moments: &Vec3, dt: f64) {
        let Turn { pi, w, v } = self;
        let theta = pi[axis] / moments[axis] * h * dt;
        if theta == 0.0 {
            return;
        }
        let (s, c) = half_angle_sin_cos(0.5 * theta);
        let (cos, sin) = (c * c - s * s, 2.0 * s * c);
        let (b, d) = ((axis + 1) % 3, (axis + 2) % 3);
        (pi[b], pi[d]) = (cos * pi[b] + sin * pi[d], cos * pi[d] - sin * pi[b]);
        let mut cross = Vec3::zeros(); // v x e
        (cross[b], cross[d]) = (v[d], -v[b]);
        let along = v[axis];
        *v = *v * c + cross * s;
        v[axis] += *w * s;
        *w = *w * c - along * s;
    }

    /// The orientation, normalized.
    fn orientation(&self) -> UnitQuaternion<f64> {
        let norm = (self.w * self.w + self.v.norm_squared()).sqrt();
        UnitQuaternion::new_unchecked(nalgebra::Quaternion::from_parts(
            self.w / norm,
            self.v / norm,
        ))
    }
}

/// `(sin x, cos x)`: by their series for the small angles of a step's turn (to round-off
/// below 1e-2: the next terms are under 1e-21 of the sum), else libm's.
pub(crate) fn half_angle_sin_cos(x: f64) -> (f64, f64) {
    if x.abs() >= 1e-2 {
        return x.sin_cos();
    }
    // Multiplied by the reciprocals: a division in this chain costs as much as the rest.
    let x2 = x * x;
    let sin = x * (1.0 - x2 * (1.0 / 6.0) * (1.0 - x2 * (1.0 / 20.0) * (1.0 - x2 * (1.0 / 42.0))));
    let cos = 1.0
        - x2 * 0.5
            * (1.0 - x2 * (1.0 / 12.0) * (1.0 - x2 * (1.0 / 30.0) * (1.0 - x2 * (1.0 / 56.0))));
    (sin, cos)
}
