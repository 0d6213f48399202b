//! The fabric of a contact network: the fabric tensor of the contact normals and its scalar
//! anisotropy.

use nalgebra::Matrix3;

/// The deviatoric anisotropy a_c = (15/2) sqrt(3/2 d:d) of `count` unit normals whose `n n^T`
/// sum to `fabric` (d the deviator of their mean); 0 for none.
pub fn anisotropy(fabric: &Matrix3<f64>, count: usize) -> f64 {
    if count == 0 {
        return 0.0;
    }
    let f = fabric / count as f64;
    let d = f - Matrix3::identity() * (f.trace() / 3.0);
    7.5 * (1.5 * d.component_mul(&d).sum()).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{random_rotation, Vec3};
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
