//! The contact law: the paper's linear spring-slider (PFC's linear model) for one contact.
//!
//! For a contact of body B with its partner A (a body of lower id, or a wall), with unit normal
//! `n` from A to B, depth `delta`, contact point `x` and the velocity of B's material point at
//! `x` relative to A's, `v`:
//! - normal force `F_n = kn delta n` (no tension: a contact exists only while the bodies
//!   overlap);
//! - shear force: the last step's shear force `F_s` is carried onto the new tangent plane
//!   (projected, magnitude kept) and turned about `n` with the pair (by the mean of the two
//!   bodies' spins about `n` over the step, so that a pair turning rigidly keeps its force
//!   fixed relative to the bodies), then `F_s <- F_s - ks v_t dt` with `v_t` the tangential part
//!   of `v`; Coulomb limit `|F_s| <= mu F_n` (`mu` the friction or the wall friction), the
//!   excess is slip, its work dissipated;
//! - the force on B is `F_n + F_s`, on A the opposite, both at `x`.
//!
//! [`Material`] holds the parameters with the paper's Table 1 as defaults; [`Contact`] is what a
//! contact carries from step to step. docs/models/contact.md has the whole model.

use crate::math::Vec3;

/// Material and contact parameters (SI units). Defaults are the paper's Table 1.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// kg/m^3
    pub density: f64,
    /// Normal stiffness, N/m.
    pub kn: f64,
    /// Shear stiffness, N/m.
    pub ks: f64,
    /// Particle-particle friction coefficient.
    pub friction: f64,
    /// Particle-wall friction coefficient (the paper: 0).
    pub wall_friction: f64,
    /// Local damping coefficient alpha (0..1).
    pub damping: f64,
}

/// A [`Material`] parameter out of its range: the field (as the scene's material record names
/// it), the range and the value.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{field} must be {rule}, got {value}")]
pub struct MaterialError {
    pub field: &'static str,
    pub rule: &'static str,
    pub value: f64,
}

impl Material {
    /// Checks every parameter: density and kn positive, ks, the frictions 0 or more, damping
    /// in [0, 1), all finite.
    pub fn check(&self) -> Result<(), MaterialError> {
        let fields: [(&'static str, f64, bool, &'static str); 6] = [
            (
                "density",
                self.density,
                self.density > 0.0,
                "a positive density in kg/m^3",
            ),
            ("kn", self.kn, self.kn > 0.0, "a positive stiffness in N/m"),
            (
                "ks",
                self.ks,
                self.ks >= 0.0,
                "a stiffness of 0 or more in N/m",
            ),
            (
                "friction",
                self.friction,
                self.friction >= 0.0,
                "a friction coefficient of 0 or more",
            ),
            (
                "wall_friction",
                self.wall_friction,
                self.wall_friction >= 0.0,
                "a friction coefficient of 0 or more",
            ),
            (
                "damping",
                self.damping,
                (0.0..1.0).contains(&self.damping),
                "in [0, 1)",
            ),
        ];
        match fields
            .into_iter()
            .find(|&(_, v, ok, _)| !(ok && v.is_finite()))
        {
            Some((field, value, _, rule)) => Err(MaterialError { field, rule, value }),
            None => Ok(()),
        }
    }
}

impl Default for Material {
    fn default() -> Self {
        Material {
            density: 2600.0,
            kn: 1e8,
            ks: 5e7,
            friction: 0.5,
            wall_friction: 0.0,
            damping: 0.3,
        }
    }
}
/// One contact: geometry, forces (on body `b` of the key; the partner `a` gets the opposite),
/// and the shear spring carried to the next step.
#[derive(Clone, Debug, PartialEq)]
pub struct Contact {
    /// Unit normal from the partner to the body.
    pub normal: Vec3,
    pub point: Vec3,
    pub depth: f64,
    pub normal_force: f64,
    /// Energy stored by the normal force: the work done against it since the contact began,
    /// summed step by step with the trapezoidal rule. The depth `V / |S_B|` is not the
    /// distance the force moves through: for faces pressed flat together this is
    /// `Fn^2 / 2kn` exactly, for a vertex pressed into a face three times that.
    pub potential: f64,
    pub shear: Vec3,
    pub sliding: bool,
}

impl Contact {
    /// Energy stored in the normal and shear springs: `potential + |Fs|^2 / 2ks` (no shear term
    /// without a shear spring).
    pub fn elastic_energy(&self, m: &Material) -> f64 {
        let shear = if m.ks > 0.0 {
            0.5 * self.shear.norm_squared() / m.ks
        } else {
            0.0
        };
        self.potential + shear
    }
}

/// The energy a contact stores when its force has grown linearly over its depth (faces pressed
/// flat, `Fn^2 / 2kn`): where a contact's stored work starts, new or re-stiffened.
pub fn flat_potential(normal_force: f64, depth: f64) -> f64 {
    0.5 * normal_force * depth
}

/// What the law gives for one contact this step: the contact to keep, the force on body B
/// (`F_n + F_s`) and the energy the slip dissipated.
pub struct LawForce {
    pub contact: Contact,
    pub force: Vec3,
    pub slip_energy: f64,
}

/// The linear law for a contact of normal `n` (unit, from A to B), `depth` and `point`, whose
/// B moves at `rel` against A at the point and whose bodies turn about `n` at `spin` (rad/s,
/// the mean of A's and B's angular velocities along `n`), given its state `last` from the last
/// step (`None` for a new contact); `friction` is the Coulomb coefficient that applies
/// (particles' or walls'), `dt` the time step.
///
/// The contact's stored energy is the work done against its normal force over the step (the
/// mean of the last and this step's force over the point's relative displacement); a new
/// contact starts as if pressed flat (exact for a scene built with overlaps of flat contacts,
/// and a step's penetration otherwise).
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn linear(
    m: &Material,
    dt: f64,
    n: Vec3,
    depth: f64,
    point: Vec3,
    rel: Vec3,
    spin: f64,
    last: Option<&Contact>,
    friction: f64,
) -> LawForce {
    let fn_ = m.kn * depth;
    let vt = rel - n * n.dot(&rel);
    let potential = match last {
        Some(c) => c.potential - 0.5 * (c.normal * c.normal_force + n * fn_).dot(&rel) * dt,
        None => flat_potential(fn_, depth),
    };
    // Carry the stored shear force onto the new tangent plane and turn it with the pair about
    // `n` (by the step's angle to first order: a turn of 1e-3 rad a step is short by 3e-10
    // rad), keeping its magnitude.
    let old = last.map_or(Vec3::zeros(), |c| c.shear);
    let mut shear = old - n * n.dot(&old);
    shear += n.cross(&shear) * (spin * dt);
    let len = shear.norm();
    if len > 0.0 {
        shear *= old.norm() / len;
    }
    let trial = shear - vt * (m.ks * dt);
    let limit = friction * fn_;
    let t = trial.norm();
    let (shear, sliding, slip_energy) = if t > limit {
        // Energy lost in the slip: the limit force over the slip (t - limit) / ks.
        (trial * (limit / t), true, limit * (t - limit) / m.ks)
    } else {
        (trial, false, 0.0)
    };
    LawForce {
        contact: Contact {
            normal: n,
            point,
            depth,
            normal_force: fn_,
            potential,
            shear,
            sliding,
        },
        force: n * fn_ + shear,
        slip_energy,
    }
}
