//! Particle rotations through a sequence of states (the paper's Eq. 10).
//!
//! A body's rotation since the first state is the angle of its orientation relative to its
//! first one, `angle(q0^-1 q)`, in `[0, pi]`: two orientations cannot tell a turn by `theta`
//! beyond `pi` from one by `2 pi - theta` the other way. The accumulated rotation adds up the
//! angles between consecutive states instead (at least the net angle, and what Eq. 10 means
//! by accumulated where the states are close enough that no body turns by `pi` between two).
//! Bodies are matched by index: every state must hold the same bodies.

use nalgebra::UnitQuaternion;

/// The first and the previous orientations, and each body's accumulated angle.
#[derive(Clone, Debug)]
pub struct Rotations {
    first: Vec<UnitQuaternion<f64>>,
    last: Vec<UnitQuaternion<f64>>,
    accumulated: Vec<f64>,
}

/// The mean net and accumulated rotation angles of the bodies (radians).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeanRotation {
    pub net: f64,
    pub accumulated: f64,
}

impl Rotations {
    /// Starts from the orientations of the first state.
    pub fn new(first: Vec<UnitQuaternion<f64>>) -> Rotations {
        Rotations {
            last: first.clone(),
            accumulated: vec![0.0; first.len()],
            first,
        }
    }

    /// The number of bodies followed.
    pub fn len(&self) -> usize {
        self.first.len()
    }

    pub fn is_empty(&self) -> bool {
        self.first.is_empty()
    }

    /// Takes the next state's orientations (as many as the first state's) and returns the
    /// mean rotation since the first; `None` for no bodies.
    ///
    /// # Panics
    /// If `now` does not hold as many orientations as the first state.
    pub fn advance(&mut self, now: &[UnitQuaternion<f64>]) -> Option<MeanRotation> {
        assert_eq!(now.len(), self.first.len(), "states of different bodies");
        if now.is_empty() {
            return None;
        }
        let mut net = 0.0;
        for (k, q) in now.iter().enumerate() {
            self.accumulated[k] += self.last[k].angle_to(q);
            net += self.first[k].angle_to(q);
        }
        self.last.copy_from_slice(now);
        let n = now.len() as f64;
        Some(MeanRotation {
            net: net / n,
            accumulated: self.accumulated.iter().sum::<f64>() / n,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use std::f64::consts::PI;

    #[test]
    fn net_angle_folds_beyond_pi_and_the_accumulated_one_does_not() {
        let axis = Vec3::z_axis();
        let mut r = Rotations::new(vec![UnitQuaternion::identity(); 2]);
        let mut last = None;
        for step in 1..=8 {
            // Body 0 turns 30 degrees per state about z, body 1 stays.
            let q = UnitQuaternion::from_axis_angle(&axis, step as f64 * PI / 6.0);
            last = r.advance(&[q, UnitQuaternion::identity()]);
        }
        let m = last.unwrap();
        // 240 degrees turned: net 120 degrees, accumulated 240; means over two bodies.
        assert!((m.net - PI / 3.0).abs() < 1e-12, "{m:?}");
        assert!((m.accumulated - 2.0 * PI / 3.0).abs() < 1e-12, "{m:?}");
    }
}
