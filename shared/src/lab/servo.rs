//! Wall speeds that hold a stress: PFC's servo law, with integral action for a loose packing.

use super::boundary::{mean_stress, WallGeometry};
use crate::dem::contacts::Partner;
use crate::dem::wall::WallKind;
use crate::dem::world::World;

/// How a servo drives walls towards a stress (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoLaw {
    /// The stress to hold, Pa.
    pub pressure: f64,
    /// PFC's servo gain alpha, 0 to 1.
    pub gain: f64,
    /// The fastest a wall may move, as a strain rate of its distance from the middle, 1/s.
    pub max_strain_rate: f64,
    /// The same while there are fewer particle-particle contacts than particles (a loose
    /// cloud), 1/s.
    pub loose_strain_rate: f64,
    /// Steps over which the integral term sums the error (0: no integral action).
    pub integral_steps: u64,
    /// A wall whose stress is within half this relative tolerance of `pressure` rests.
    pub tolerance: f64,
}

/// The walls' speeds (inward positive, m/s, in the walls' order) under PFC's servo: each wall
/// `gain (p - sigma) A / (kn N dt)`, `N` its contacts (at least 1) and `A` its area, capped at
/// `max_strain_rate` times the wall's distance from the middle. With `common` (the integral
/// term, Pa), every wall moves at one strain rate instead, the smallest servo gain's acting on
/// the mean stress's error plus the integral: the specimen shrinks alike in every direction.
///
/// The gain is PFC's: it takes the wall's own contacts for the spring it pushes, but that spring
/// is in series with the whole packing, and a loose packing gives way as it rearranges: the
/// error decays over tens of thousands of steps instead of a few. The integral, the error
/// summed over `integral_steps`, makes up for that. It grows only while the walls are not at
/// their cap (no wind-up while the cloud is loose) and goes back to zero when the error changes
/// sign, so that it never drives the stress past the target.
pub fn servo(
    w: &World,
    p: &ServoLaw,
    geometry: &[WallGeometry],
    stresses: &[f64],
    counts: &[usize],
    common: Option<&mut f64>,
) -> Vec<f64> {
    let gain = |k: usize| wall_gain(w, p, &geometry[k], counts[k]);
    if let Some(integral) = common {
        let error = p.pressure - mean_stress(geometry, stresses);
        let g = (0..geometry.len())
            .map(|k| gain(k) / geometry[k].half)
            .fold(f64::INFINITY, f64::min);
        // Particle-particle contacts come first in the list.
        let pairs = w.contacts.lower_bound(&(Partner::Wall(0), 0));
        let cap = if 2 * pairs < w.bodies.len() {
            p.loose_strain_rate.max(p.max_strain_rate)
        } else {
            p.max_strain_rate
        };
        if error * *integral < 0.0 {
            *integral = 0.0;
        }
        let wanted = g * (error + *integral);
        if p.integral_steps > 0 && wanted.abs() < cap {
            *integral += error / p.integral_steps as f64;
        }
        let rate = wanted.clamp(-cap, cap);
        geometry.iter().map(|g| rate * g.half).collect()
    } else {
        // A wall within half the tolerance rests: a servo that chases every fluctuation
        // keeps shaking the packing it should let settle.
        (0..geometry.len())
            .map(|k| {
                let cap = p.max_strain_rate * geometry[k].half;
                let error = p.pressure - stresses[k];
                if error.abs() <= 0.5 * p.tolerance * p.pressure {
                    0.0
                } else {
                    (gain(k) * error).clamp(-cap, cap)
                }
            })
            .collect()
    }
}

/// PFC's servo gain of a wall (m/s per Pa): `gain A / (kn N dt)`, `N` its contacts (at
/// least 1) and `A` its area: the speed that closes `gain` of the stress error in a step on the
/// wall's own contacts' springs.
pub fn wall_gain(w: &World, p: &ServoLaw, geometry: &WallGeometry, count: usize) -> f64 {
    p.gain * geometry.area / (w.material.kn * count.max(1) as f64 * w.dt)
}

/// Moves the walls inward at `speeds` (see [`servo`]).
pub fn set_speeds(w: &mut World, speeds: &[f64]) {
    for (wall, &v) in w.walls.iter_mut().zip(speeds) {
        match &mut wall.kind {
            WallKind::Plane { normal, .. } => wall.velocity = *normal * v,
            WallKind::Cylinder { radial_rate, .. } => *radial_rate = -v,
            WallKind::Facets { .. } => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::shape::Shape;
    use crate::lab::boundary::{bounds, SIDE};
    use crate::lab::pack::{cloud, Params};

    #[test]
    fn the_compaction_servo_integrates_only_below_its_cap_and_resets_when_the_error_turns() {
        let cube = Shape::from_mesh(&crate::geometry::mesh::cube(0.5)).unwrap();
        let p = Params {
            count: Some(4),
            diameter: 0.1,
            height: 0.2,
            size_min: 0.01,
            size_max: 0.02,
            ..Params::default()
        };
        let w = cloud(vec![cube], &p).unwrap();
        let geometry = bounds(&w).geometry();
        let half = geometry.iter().map(|g| g.half).collect::<Vec<_>>();
        // Nothing on the walls: one contact's gain, so the walls go at the loose cloud's cap
        // and nothing is integrated.
        let mut integral = 0.0;
        let v = servo(
            &w,
            &p.servo_law(),
            &geometry,
            &[0.0; 3],
            &[0; 3],
            Some(&mut integral),
        );
        assert_eq!(integral, 0.0);
        for (v, h) in v.iter().zip(&half) {
            approx::assert_relative_eq!(*v, p.loose_strain_rate * h, max_relative = 1e-12);
        }
        // Near the target on stiff walls (a million contacts each): below the cap, so the error
        // adds up, a 2000th of it each step, and speeds the walls up by as much.
        let counts = [1_000_000; 3];
        let near = [0.99 * p.pressure; 3];
        let first = servo(
            &w,
            &p.servo_law(),
            &geometry,
            &near,
            &counts,
            Some(&mut integral),
        );
        approx::assert_relative_eq!(integral, 0.01 * p.pressure / 2000.0, max_relative = 1e-12);
        let second = servo(
            &w,
            &p.servo_law(),
            &geometry,
            &near,
            &counts,
            Some(&mut integral),
        );
        approx::assert_relative_eq!(
            second[SIDE] / first[SIDE],
            1.0 + 1.0 / 2000.0,
            max_relative = 1e-9
        );
        assert!(first[SIDE] > 0.0 && first[SIDE] < p.max_strain_rate * half[SIDE]);
        // Past the target: the integral starts again from zero at once, and the walls back out.
        let past = [1.01 * p.pressure; 3];
        let back = servo(
            &w,
            &p.servo_law(),
            &geometry,
            &past,
            &counts,
            Some(&mut integral),
        );
        approx::assert_relative_eq!(integral, -0.01 * p.pressure / 2000.0, max_relative = 1e-12);
        assert!(back.iter().all(|&v| v < 0.0), "{back:?}");
        // Without integral action it never grows.
        let q = Params {
            integral_steps: 0,
            ..p.clone()
        };
        let mut integral = 0.0;
        servo(
            &w,
            &q.servo_law(),
            &geometry,
            &near,
            &counts,
            Some(&mut integral),
        );
        assert_eq!(integral, 0.0);
    }
}
