//! Roses: the mean contact normal force per direction, over equal-area bins of the sphere
//! (the paper's Fig. 16).
//!
//! The bins are `bands` bands of equal height in `z` (equal area, by Archimedes) times
//! `sectors` equal sectors in azimuth. A contact counts in the bin of its normal and in the bin
//! of the opposite direction (a contact has no preferred side), so the rose is centrally
//! symmetric.

use crate::geometry::mesh::PolyMesh;
use crate::math::Vec3;
use std::f64::consts::PI;

/// Sums and counts of normal forces per bin.
#[derive(Clone, Debug, PartialEq)]
pub struct Rose {
    pub bands: usize,
    pub sectors: usize,
    /// The sum of the normal forces in each bin, band by band.
    pub sum: Vec<f64>,
    pub count: Vec<u64>,
}

impl Rose {
    /// An empty rose.
    ///
    /// # Panics
    /// If `bands` or `sectors` is 0.
    pub fn new(bands: usize, sectors: usize) -> Rose {
        assert!(bands > 0 && sectors > 0, "a rose needs bins");
        Rose {
            bands,
            sectors,
            sum: vec![0.0; bands * sectors],
            count: vec![0; bands * sectors],
        }
    }

    /// The bin of unit direction `n`.
    pub fn bin(&self, n: &Vec3) -> usize {
        let band = (((n.z + 1.0) * 0.5 * self.bands as f64) as usize).min(self.bands - 1);
        let phi = n.y.atan2(n.x).rem_euclid(2.0 * PI);
        let sector = ((phi / (2.0 * PI) * self.sectors as f64) as usize).min(self.sectors - 1);
        band * self.sectors + sector
    }

    /// The centre direction of bin `k`.
    pub fn direction(&self, k: usize) -> Vec3 {
        let (band, sector) = (k / self.sectors, k % self.sectors);
        let z = -1.0 + (band as f64 + 0.5) * 2.0 / self.bands as f64;
        let phi = (sector as f64 + 0.5) * 2.0 * PI / self.sectors as f64;
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Counts a contact of unit normal `n` and normal force `force` (both ways).
    pub fn add(&mut self, n: &Vec3, force: f64) {
        for d in [*n, -*n] {
            let k = self.bin(&d);
            self.sum[k] += force;
            self.count[k] += 1;
        }
    }

    /// The mean normal force in bin `k`; 0 in an empty bin.
    pub fn mean(&self, k: usize) -> f64 {
        if self.count[k] == 0 {
            0.0
        } else {
            self.sum[k] / self.count[k] as f64
        }
    }

    /// The mean normal force over all contacts; 0 without contacts.
    pub fn overall_mean(&self) -> f64 {
        let n: u64 = self.count.iter().sum();
        if n == 0 {
            0.0
        } else {
            self.sum.iter().sum::<f64>() / n as f64
        }
    }

    /// The rose as a closed surface: a vertex at each bin's centre direction, at the distance
    /// of its mean force times `scale`, and one at each pole (the mean of the polar band);
    /// quadrilaterals between bands, triangles at the poles, wound outwards.
    pub fn mesh(&self, name: &str, scale: f64) -> PolyMesh {
        let (nb, ns) = (self.bands, self.sectors);
        let mut vertices: Vec<Vec3> = (0..nb * ns)
            .map(|k| self.direction(k) * (self.mean(k) * scale))
            .collect();
        let polar = |band: usize| -> f64 {
            (0..ns).map(|s| self.mean(band * ns + s)).sum::<f64>() / ns as f64 * scale
        };
        let (south, north) = ((nb * ns) as u32, (nb * ns + 1) as u32);
        vertices.push(Vec3::new(0.0, 0.0, -polar(0)));
        vertices.push(Vec3::new(0.0, 0.0, polar(nb - 1)));
        let at = |band: usize, sector: usize| (band * ns + sector % ns) as u32;
        let mut faces = Vec::with_capacity((nb + 1) * ns);
        for s in 0..ns {
            faces.push(vec![south, at(0, s + 1), at(0, s)]);
            for b in 0..nb - 1 {
                faces.push(vec![at(b, s), at(b, s + 1), at(b + 1, s + 1), at(b + 1, s)]);
            }
            faces.push(vec![north, at(nb - 1, s), at(nb - 1, s + 1)]);
        }
        PolyMesh::from_faces(name, vertices, &faces)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_hold_their_centres_and_the_rose_is_symmetric() {
        let mut rose = Rose::new(8, 16);
        for k in 0..rose.sum.len() {
            assert_eq!(rose.bin(&rose.direction(k)), k);
        }
        rose.add(&Vec3::new(0.3, -0.4, 0.866).normalize(), 10.0);
        let k = rose.bin(&Vec3::new(0.3, -0.4, 0.866).normalize());
        let opposite = rose.bin(&-Vec3::new(0.3, -0.4, 0.866).normalize());
        assert_ne!(k, opposite);
        assert_eq!((rose.mean(k), rose.mean(opposite)), (10.0, 10.0));
        assert_eq!(rose.overall_mean(), 10.0);
        // The poles go to the end bands.
        assert_eq!(rose.bin(&Vec3::z()) / 16, 7);
        assert_eq!(rose.bin(&-Vec3::z()) / 16, 0);
    }

    #[test]
    fn a_uniform_rose_is_a_closed_outward_sphere() {
        let mut rose = Rose::new(6, 12);
        for k in 0..rose.sum.len() {
            let d = rose.direction(k);
            rose.add(&d, 2.0);
        }
        let mesh = rose.mesh("rose", 0.5);
        let volume = crate::geometry::mass::MassProps::of(&mesh).volume;
        // A polyhedron inscribed in the unit sphere: positive volume, a little under 4/3 pi.
        assert!(
            volume > 0.8 * 4.0 / 3.0 * PI && volume < 4.0 / 3.0 * PI,
            "{volume}"
        );
        assert!(mesh.topology(None).is_ok());
    }
}
