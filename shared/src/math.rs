//! Type aliases and small numeric helpers, so the code is not written against raw nalgebra types.

/// A point or vector in 3D, f64.
pub type Vec3 = nalgebra::Vector3<f64>;
/// A 3x3 matrix, f64 (inertia tensors, rotations).
pub type Mat3 = nalgebra::Matrix3<f64>;

/// A uniform f64 in [0, 1) from 53 random bits of a 64-bit word.
///
/// Written out rather than taken from `rand`'s distributions so that the mapping from generator
/// output to numbers is ours and cannot change with a `rand` release: same seed, same bytes.
pub fn unit_f64(bits: u64) -> f64 {
    (bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// `x * x`. With [`cube`] and [`pow5`], in place of `f64::powi`: its rounding is not
/// specified, and in practice it depended on inlining (LLVM folds a call whose argument it
/// knows with `pow`, and multiplies by repeated squaring otherwise), so one test scene moved
/// differently after an unrelated change elsewhere in the crate. These multiply in the order
/// the run-time `powi` did, so the numbers of runs from data are the same as before.
pub fn square(x: f64) -> f64 {
    x * x
}

/// `x * (x * x)`: see [`square`].
pub fn cube(x: f64) -> f64 {
    x * (x * x)
}

/// `x * ((x * x) * (x * x))`: see [`square`].
pub fn pow5(x: f64) -> f64 {
    let x2 = x * x;
    x * (x2 * x2)
}

/// Axis-aligned bounding box of points: (min, max). `None` for no points. Plain comparisons
/// per coordinate (nalgebra's `inf`/`sup` cost several times more in the contact loop).
pub fn bounding_box(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let (mut lo, mut hi) = (*points.first()?, points[0]);
    for p in &points[1..] {
        for k in 0..3 {
            if p[k] < lo[k] {
                lo[k] = p[k];
            }
            if p[k] > hi[k] {
                hi[k] = p[k];
            }
        }
    }
    Some((lo, hi))
}

/// Length of the bounding-box diagonal (0 for no points): the scale that relative tolerances use.
pub fn extent(points: &[Vec3]) -> f64 {
    bounding_box(points).map_or(0.0, |(lo, hi)| (hi - lo).norm())
}

/// Two unit vectors completing the unit vector `axis` to a right-handed orthonormal basis
/// (`axis x helper`, then `axis x` that), the helper being whichever of x and y is farther
/// from `axis`.
pub fn basis(axis: &Vec3) -> (Vec3, Vec3) {
    let helper = if axis.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let e1 = axis.cross(&helper).normalize();
    (e1, axis.cross(&e1))
}

/// Largest value of `n . x - d` over the box corners: <= 0 means the box is inside.
#[inline]
pub fn box_excess(n: &Vec3, d: f64, lo: &Vec3, hi: &Vec3) -> f64 {
    let corner = Vec3::new(
        if n.x > 0.0 { hi.x } else { lo.x },
        if n.y > 0.0 { hi.y } else { lo.y },
        if n.z > 0.0 { hi.z } else { lo.z },
    );
    n.dot(&corner) - d
}

/// Clips the convex polygon `poly` to the half-space `n . x <= d` in place (`tmp` and `dist`
/// are scratch); false when less than a polygon is left. A polygon wholly inside is left as it
/// is, without copying.
#[inline]
pub fn clip(
    poly: &mut Vec<Vec3>,
    tmp: &mut Vec<Vec3>,
    dist: &mut Vec<f64>,
    n: &Vec3,
    d: f64,
) -> bool {
    dist.clear();
    dist.extend(poly.iter().map(|p| n.dot(p) - d));
    clip_with(poly, tmp, dist)
}

/// [`clip`] with the vertices' distances above the plane given, `dist[k]` for `poly[k]`.
#[inline]
pub fn clip_with(poly: &mut Vec<Vec3>, tmp: &mut Vec<Vec3>, dist: &[f64]) -> bool {
    if dist.iter().all(|&s| s <= 0.0) {
        return poly.len() >= 3;
    }
    tmp.clear();
    // Edge i runs from vertex i to i + 1 (the last one back to the first): what is kept of it,
    // in that order.
    let mut edge = |p: &Vec3, q: &Vec3, sp: f64, sq: f64| {
        if sp <= 0.0 {
            tmp.push(*p);
        }
        if (sp < 0.0 && sq > 0.0) || (sp > 0.0 && sq < 0.0) {
            tmp.push(p + (q - p) * (sp / (sp - sq)));
        }
    };
    for (pq, s) in poly.windows(2).zip(dist.windows(2)) {
        edge(&pq[0], &pq[1], s[0], s[1]);
    }
    if let (Some(p), Some(q), Some(&sp), Some(&sq)) =
        (poly.last(), poly.first(), dist.last(), dist.first())
    {
        edge(p, q, sp, sq);
    }
    std::mem::swap(poly, tmp);
    poly.len() >= 3
}
/// A uniformly random rotation (Shoemake's method).
pub fn random_rotation(rng: &mut impl rand::Rng) -> nalgebra::UnitQuaternion<f64> {
    let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    let tau = 2.0 * std::f64::consts::PI;
    let (t2, t3) = (tau * u2, tau * u3);
    nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        b * t3.cos(),
        a * t2.sin(),
        a * t2.cos(),
        b * t3.sin(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn random_rotations_are_unit_and_spread_over_all_directions() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut mean = Vec3::zeros();
        let n = 20000;
        for _ in 0..n {
            let q = random_rotation(&mut rng);
            assert!((q.norm() - 1.0).abs() < 1e-12);
            mean += q * Vec3::x();
        }
        // Uniform directions average to zero within a few 1 / sqrt(n).
        assert!((mean / n as f64).norm() < 0.03, "{mean:?}");
    }
}
