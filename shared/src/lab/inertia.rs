//! Density scaling for quasi-static procedures: statics does not depend on inertia, so the
//! bodies' masses may be raised until the time step is set by the bodies that carry the load.

use crate::dem::world::World;
use crate::math::square;

/// Density scaling for a quasi-static preparation: raises every free body's mass, and all its
/// moments by one factor, until its own critical steps for translation and for rotation
/// ([`World::critical_dts`]) are both the largest translational step of any body, the one of
/// the heaviest. Statics does not depend on inertia, and the step is then set by the big
/// bodies that carry the packing, not by the smallest or spikiest one. Angular velocities are
/// kept. [`restore_inertia`] undoes it.
pub fn scale_inertia(w: &mut World) {
    let dts = w.critical_dts();
    let target = (dts.iter())
        .map(|d| d.0)
        .filter(|t| t.is_finite())
        .fold(0.0, f64::max);
    for (b, (t, r)) in w.bodies.iter_mut().zip(dts) {
        if b.fixed {
            continue;
        }
        let rotation = square(target / r);
        b.mass *= square(target / t);
        b.moments *= rotation;
        b.ang_mom *= rotation;
    }
}

/// Gives every body its true mass and moments back (after [`scale_inertia`]), keeping its
/// velocity and angular velocity, and sets the time step from them.
pub fn restore_inertia(w: &mut World, safety: f64) {
    for i in 0..w.bodies.len() {
        let (mass, moments) = w.inertia_of(w.bodies[i].shape, w.bodies[i].scale);
        let b = &mut w.bodies[i];
        b.ang_mom *= moments.x / b.moments.x;
        b.mass = mass;
        b.moments = moments;
    }
    w.dt = safety * w.critical_dt();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::shape::Shape;
    use crate::lab::pack::{cloud, Params};
    use crate::math::Vec3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn inertia_scaling_gives_every_body_the_largest_step_and_restoring_gives_the_true_inertia() {
        // Spiky and flat templates, sizes 1:4: the step was set by the smallest, spikiest one.
        let shapes: Vec<Shape> = [6, 9, 14]
            .map(|faces| {
                let q = crate::geometry::polygen::Params {
                    faces,
                    ..Default::default()
                };
                let m = crate::geometry::polygen::generate(&q, 7, 0).unwrap().mesh;
                Shape::from_mesh(&m).unwrap()
            })
            .into();
        let p = Params {
            diameter: 0.2,
            height: 0.4,
            count: Some(30),
            inertia_scaling: false,
            ..Params::default()
        };
        let mut w = cloud(shapes, &p).unwrap();
        let true_dt = w.critical_dt();
        let largest = (w.critical_dts().iter()).map(|d| d.0).fold(0.0, f64::max);
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for b in w.bodies.iter_mut() {
            b.vel = Vec3::new(rng.random(), rng.random(), rng.random());
            b.ang_mom = Vec3::new(rng.random(), rng.random(), rng.random()) * b.moments.x;
        }
        let before: Vec<(Vec3, Vec3)> = w.bodies.iter().map(|b| (b.vel, b.omega())).collect();
        scale_inertia(&mut w);
        for (t, r) in w.critical_dts() {
            assert!((t - largest).abs() < 1e-12 * largest, "{t} {largest}");
            assert!((r - largest).abs() < 1e-12 * largest, "{r} {largest}");
        }
        assert!(largest > 4.0 * true_dt, "{largest} against {true_dt}");
        for (b, (v, omega)) in w.bodies.iter().zip(&before) {
            assert_eq!(b.vel, *v);
            assert!((b.omega() - omega).norm() < 1e-12 * omega.norm());
        }
        restore_inertia(&mut w, p.safety);
        assert_eq!(w.dt, p.safety * true_dt);
        for (b, (v, omega)) in w.bodies.iter().zip(&before) {
            let (mass, moments) = w.inertia_of(b.shape, b.scale);
            assert_eq!((b.mass, b.moments), (mass, moments));
            assert_eq!(b.vel, *v);
            assert!((b.omega() - omega).norm() < 1e-12 * omega.norm());
        }
    }
}
