//! The average stress of a packing from its contacts, and its coordination numbers.
//!
//! Sign convention: compression positive. A contact's force `f` acts on its body B (the
//! partner A gets `-f`), and its normal points from A to B, so a pressed contact has
//! `f . (x_B - x_A) > 0`.

use crate::dem::contacts::Partner;
use crate::dem::world::World;
use crate::math::Mat3;

/// The average stress of the contacts in `volume` (the paper's Eq. 8,
/// `sigma_ij = (1/V) sum_c f_i l_j`), and the part of the particle pairs alone.
///
/// A pair's branch vector runs from A's centroid to B's. A wall contact has no second body:
/// its branch is the half from the contact point to the body's centroid, which is what the
/// body-centred form `-(1/V) sum_bodies sum_contacts f (x_c - x_b)` gives for every contact
/// (for a pair its two halves add up to the whole branch). In equilibrium that is the
/// boundary's stress; the pairs alone leave out the layer of half particles along the walls
/// (on a quick `pack` specimen about 83 kPa of the 100 kPa the walls carry).
pub fn contact_stress(w: &World, volume: f64) -> (Mat3, Mat3) {
    let (mut full, mut pairs) = (Mat3::zeros(), Mat3::zeros());
    for (&(partner, b), c) in &w.contacts {
        let f = c.normal * c.normal_force + c.shear;
        let xb = w.bodies[b as usize].pos;
        let branch = match partner {
            Partner::Body(a) => xb - w.bodies[a as usize].pos,
            Partner::Wall(_) => xb - c.point,
        };
        let term = f * branch.transpose();
        full += term;
        if matches!(partner, Partner::Body(_)) {
            pairs += term;
        }
    }
    (full / volume, pairs / volume)
}

/// The six components of `sigma`'s symmetric part, `(sigma + sigma^T) / 2`: xx, yy, zz, xy,
/// xz, yz (a stress record's; `sum f_i l_j` itself is not symmetric out of equilibrium).
pub fn symmetric_components(sigma: &Mat3) -> [f64; 6] {
    let s = (sigma + sigma.transpose()) * 0.5;
    [
        s[(0, 0)],
        s[(1, 1)],
        s[(2, 2)],
        s[(0, 1)],
        s[(0, 2)],
        s[(1, 2)],
    ]
}

/// The mean stress `p = sigma_ii / 3` and the deviatoric stress `q = sqrt(3/2 s_ij s_ij)`
/// (Eq. 9) of `sigma`'s symmetric part.
pub fn invariants(sigma: &Mat3) -> (f64, f64) {
    let sym = (sigma + sigma.transpose()) * 0.5;
    let p = sym.trace() / 3.0;
    let s = sym - Mat3::identity() * p;
    (p, (1.5 * s.component_mul(&s).sum()).sqrt())
}

/// The coordination number `2 C / N` (`C` particle-particle contacts, `N` particles) and the
/// mechanical one without rattlers, `(2 C - N1) / (N - N0 - N1)` (`N0`, `N1` the particles of
/// no and of one particle contact); 0 where there are no particles.
pub fn coordination(w: &World) -> (f64, f64) {
    let n = w.bodies.len();
    let mut ends = vec![0usize; n];
    let mut pairs = 0usize;
    for &(partner, b) in w.contacts.keys() {
        if let Partner::Body(a) = partner {
            ends[a as usize] += 1;
            ends[b as usize] += 1;
            pairs += 1;
        }
    }
    let n0 = ends.iter().filter(|&&e| e == 0).count();
    let n1 = ends.iter().filter(|&&e| e == 1).count();
    let mech = n as f64 - n0 as f64 - n1 as f64;
    (
        if n > 0 {
            2.0 * pairs as f64 / n as f64
        } else {
            0.0
        },
        if mech > 0.0 {
            (2.0 * pairs as f64 - n1 as f64) / mech
        } else {
            0.0
        },
    )
}

/// A contact slides when its friction mobility `|f_t| / (mu f_n)` exceeds this (the paper's
/// criterion, Fig. 14).
pub const SLIDING_MOBILITY: f64 = 0.9999;

/// The particle-particle contacts and how many of them slide (mobility above
/// [`SLIDING_MOBILITY`] with the material's friction `mu`; a contact without normal force
/// slides if it carries any shear force).
pub fn sliding(w: &World) -> (usize, usize) {
    let mu = w.material.friction;
    let (mut pairs, mut slide) = (0, 0);
    for (&(partner, _), c) in &w.contacts {
        if let Partner::Body(_) = partner {
            pairs += 1;
            if c.shear.norm() > SLIDING_MOBILITY * mu * c.normal_force {
                slide += 1;
            }
        }
    }
    (pairs, slide)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    /// The off-diagonal terms are the means of the two triangles', not the upper one's.
    #[test]
    fn the_components_are_the_symmetric_part_s() {
        let sigma = Mat3::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0);
        assert_eq!(symmetric_components(&sigma), [1.0, 5.0, 9.0, 3.0, 5.0, 7.0]);
    }

    #[test]
    fn invariants_of_a_triaxial_state() {
        // sigma1 = 300, sigma2 = sigma3 = 100: p = 166.7, q = 200.
        let s = Mat3::from_diagonal(&Vec3::new(100.0, 100.0, 300.0));
        let (p, q) = invariants(&s);
        assert!((p - 500.0 / 3.0).abs() < 1e-12);
        assert!((q - 200.0).abs() < 1e-12);
        // Isotropic: q = 0; an antisymmetric part changes nothing.
        let mut iso = Mat3::identity() * 50.0;
        iso[(0, 1)] = 3.0;
        iso[(1, 0)] = -3.0;
        assert_eq!(invariants(&iso), (50.0, 0.0));
    }
}
