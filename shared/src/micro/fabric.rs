//! The fabric of a contact network (the paper's Eqs. 11-19): the fabric tensors of the
//! contact normals, branch vectors and forces, their anisotropy tensors and scalar
//! anisotropies, and the stress-force-fabric relation.
//!
//! Conventions (those of [`crate::micro::stress`]): a contact between bodies A and B has its
//! unit normal `n` from A to B, its branch vector `l = x_B - x_A` (centroid to centroid) and
//! the force `f` on B, so a pressed contact has `f . n > 0`. Each is split along `n`:
//! `b^n = l . n`, `b^t t = l - b^n n` (t the unit direction of the branch's tangential part,
//! `b^t >= 0`), `f^n = f . n`, `f^t t = f - f^n n` (t the shear force's direction). The fabric
//! tensors of the paper's Eqs. 11-13 are means over the `N_c` contacts:
//!
//! ```text
//! Phi^c   = <n n>                         Psi^bn = <b^n n n / w>   Psi^bt = <b^t t n / w>
//! Omega^fn = <f^n n n / w>                Omega^ft = <f^t t n / w>,   w = 1 + A^c : n n
//! ```
//!
//! The tangential tensors are not symmetric; their symmetric parts enter the anisotropy
//! tensors (Eqs. 14-16, `'` the deviatoric part):
//! `A^c = 15/2 Phi^c'`, `A^bn = 15/2 Psi^bn' / b0`, `A^bt = 15/3 Psi^bt' / b0` with
//! `b0 = tr Psi^bn`, and `A^fn`, `A^ft` the same with `Omega` and `f0 = tr Omega^fn`. The
//! scalar anisotropy (Eq. 17) is `a = sign(A : s) sqrt(3/2 A : A)` for the deviatoric stress `s`
//! (positive when the fabric is stronger along the major principal stress).

use crate::dem::contacts::Partner;
use crate::dem::world::World;
use crate::math::{Mat3, Vec3};

/// A particle-particle contact as the fabric sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Unit normal from A to B.
    pub normal: Vec3,
    /// `x_B - x_A`.
    pub branch: Vec3,
    /// The force on B.
    pub force: Vec3,
}

/// The particle-particle contacts of a world (contacts with walls have no branch vector).
pub fn samples(w: &World) -> Vec<Sample> {
    w.contacts
        .iter()
        .filter_map(|(&(partner, b), c)| match partner {
            Partner::Body(a) => Some(Sample {
                normal: c.normal,
                branch: w.bodies[b as usize].pos - w.bodies[a as usize].pos,
                force: c.normal * c.normal_force + c.shear,
            }),
            Partner::Wall(_) => None,
        })
        .collect()
}

/// Why a contact set has no fabric.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FabricError {
    #[error("no particle-particle contacts")]
    NoContacts,
    #[error("the contact normals are too anisotropic for the second-order fit (1 + A^c:nn = {0:.3} for a contact)")]
    Anisotropic(f64),
    #[error("the mean normal {0} is not positive")]
    NotPressed(&'static str),
}

/// The fabric tensors of a contact set, their anisotropy tensors and the mean normal branch
/// length and force.
#[derive(Clone, Debug, PartialEq)]
pub struct Fabric {
    /// `N_c`.
    pub count: usize,
    pub phi_c: Mat3,
    pub psi_bn: Mat3,
    pub psi_bt: Mat3,
    pub omega_fn: Mat3,
    pub omega_ft: Mat3,
    /// `tr Psi^bn`, m.
    pub b0: f64,
    /// `tr Omega^fn`, N.
    pub f0: f64,
    /// The anisotropy tensors `A^c, A^bn, A^bt, A^fn, A^ft` (Eqs. 14-16), in that order.
    pub a: [Mat3; 5],
}

/// The deviatoric part of `m`'s symmetric part.
pub fn deviator(m: &Mat3) -> Mat3 {
    let s = (m + m.transpose()) * 0.5;
    s - Mat3::identity() * (s.trace() / 3.0)
}

/// The scalar anisotropy of Eq. 17, `sign(A : s) sqrt(3/2 A : A)`, for the deviatoric stress
/// (or any tensor along the loading) `s`; the sign is + where `A : s` is 0.
pub fn scalar(a: &Mat3, s: &Mat3) -> f64 {
    let size = (1.5 * a.component_mul(a).sum()).sqrt();
    if a.component_mul(s).sum() < 0.0 {
        -size
    } else {
        size
    }
}

/// The weights `1 / (1 + A^c : n n)` are refused below this denominator: the second-order
/// density of normals is then negative or nearly so in some direction, and the fit meaningless.
const SMALLEST_DENSITY: f64 = 0.05;

impl Fabric {
    /// The fabric of `samples`.
    pub fn of(samples: &[Sample]) -> Result<Fabric, FabricError> {
        if samples.is_empty() {
            return Err(FabricError::NoContacts);
        }
        let count = samples.len();
        let inv = 1.0 / count as f64;
        let phi_c = samples
            .iter()
            .fold(Mat3::zeros(), |m, s| m + s.normal * s.normal.transpose())
            * inv;
        let a_c = deviator(&phi_c) * 7.5;
        let (mut psi_bn, mut psi_bt, mut omega_fn, mut omega_ft) =
            (Mat3::zeros(), Mat3::zeros(), Mat3::zeros(), Mat3::zeros());
        for s in samples {
            let n = s.normal;
            let nn = n * n.transpose();
            let w = 1.0 + (nn.component_mul(&a_c)).sum();
            if w < SMALLEST_DENSITY {
                return Err(FabricError::Anisotropic(w));
            }
            let bn = s.branch.dot(&n);
            let fnorm = s.force.dot(&n);
            psi_bn += nn * (bn / w);
            psi_bt += (s.branch - n * bn) * n.transpose() / w;
            omega_fn += nn * (fnorm / w);
            omega_ft += (s.force - n * fnorm) * n.transpose() / w;
        }
        let (psi_bn, psi_bt, omega_fn, omega_ft) =
            (psi_bn * inv, psi_bt * inv, omega_fn * inv, omega_ft * inv);
        let (b0, f0) = (psi_bn.trace(), omega_fn.trace());
        if !(b0 > 0.0) {
            return Err(FabricError::NotPressed("branch length"));
        }
        if !(f0 > 0.0) {
            return Err(FabricError::NotPressed("force"));
        }
        let a = [
            a_c,
            deviator(&psi_bn) * (7.5 / b0),
            deviator(&psi_bt) * (5.0 / b0),
            deviator(&omega_fn) * (7.5 / f0),
            deviator(&omega_ft) * (5.0 / f0),
        ];
        Ok(Fabric {
            count,
            phi_c,
            psi_bn,
            psi_bt,
            omega_fn,
            omega_ft,
            b0,
            f0,
            a,
        })
    }

    /// The scalar anisotropies `a_c, a_bn, a_bt, a_fn, a_ft` (Eq. 17) against the deviatoric
    /// stress `s`.
    pub fn scalars(&self, s: &Mat3) -> [f64; 5] {
        self.a.map(|a| scalar(&a, s))
    }

    /// The stress ratio of Eq. 19, `q/p = 2/5 (a_c + a_bn + 3/2 a_bt + a_fn + 3/2 a_ft)`.
    pub fn ratio(&self, s: &Mat3) -> f64 {
        let [c, bn, bt, fnorm, ft] = self.scalars(s);
        0.4 * (c + bn + 1.5 * bt + fnorm + 1.5 * ft)
    }

    /// The stress of Eq. 18 over `volume`, with the second-order products of the normal
    /// anisotropies kept:
    /// `N_c f0 b0 / 3V [I + 2/5 (A^c + A^bn + 3/2 A^bt + A^fn + 3/2 A^ft)
    ///  + 1/35 sum_{x<y} (2 (A^x : A^y) I + 4 (A^x A^y + A^y A^x))]`, the sum over the pairs
    /// of `c, bn, fn` (the products with the tangential tensors and the third order left out).
    /// The products are the sphere's integral of the three second-order densities' product:
    /// exact for a contact set whose normals are isotropic to the sixth moment and whose
    /// branches and forces follow `b0 (1 + A^bn : n n)` and `f0 (1 + A^fn : n n)`.
    pub fn stress(&self, volume: f64) -> Mat3 {
        let [c, bn, bt, fnorm, ft] = &self.a;
        let i = Mat3::identity();
        let mut bracket = i + (c + bn + bt * 1.5 + fnorm + ft * 1.5) * 0.4;
        let normal = [c, bn, fnorm];
        for x in 0..3 {
            for y in x + 1..3 {
                let (a, b) = (normal[x], normal[y]);
                bracket += (i * (2.0 * a.component_mul(b).sum()) + (a * b + b * a) * 4.0) / 35.0;
            }
        }
        bracket * (self.count as f64 * self.f0 * self.b0 / (3.0 * volume))
    }

    /// The mean stress of Eq. 18's isotropic part, `N_c f0 b0 / 3V`.
    pub fn pressure(&self, volume: f64) -> f64 {
        self.count as f64 * self.f0 * self.b0 / (3.0 * volume)
    }
}

/// The deviatoric anisotropy a_c = (15/2) sqrt(3/2 d:d) of `count` unit normals whose `n n^T`
/// sum to `fabric` (d the deviator of their mean); 0 for none.
pub fn anisotropy(fabric: &Mat3, count: usize) -> f64 {
    if count == 0 {
        return 0.0;
    }
    let d = deviator(&(fabric / count as f64));
    7.5 * (1.5 * d.component_mul(&d).sum()).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{random_rotation, Vec3};
    use nalgebra::Matrix3;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn anisotropy_is_7_5_for_aligned_normals_and_7_5_over_root_n_for_random_ones() {
        let z = Vec3::z();
        assert!((anisotropy(&(z * z.transpose() * 10.0), 10) - 7.5).abs() < 1e-12);
        // Along the three axes alike: isotropic.
        let axes = Vec3::x() * Vec3::x().transpose()
            + Vec3::y() * Vec3::y().transpose()
            + z * z.transpose();
        assert!(anisotropy(&axes, 3) < 1e-12);
        // Isotropic random normals: the root mean square is Summary::anisotropy_noise's.
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let n = 500;
        let trials = 400;
        let mut sum2 = 0.0;
        for _ in 0..trials {
            let mut fabric = Matrix3::zeros();
            for _ in 0..n {
                let v = random_rotation(&mut rng) * z;
                fabric += v * v.transpose();
            }
            sum2 += crate::math::square(anisotropy(&fabric, n));
        }
        let rms = (sum2 / trials as f64).sqrt();
        let expected = 7.5 / (n as f64).sqrt();
        assert!(
            (rms / expected - 1.0).abs() < 0.05,
            "{rms} against {expected}"
        );
    }
}
