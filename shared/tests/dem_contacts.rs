//! Hard pairs. The overlap construction is checked against a
//! brute-force separating-axis test on thousands of poses: no overlapping pair is reported as
//! separated, no separated pair as overlapping, the normal never points from B back into A.

use nalgebra::UnitQuaternion;
use rand::{RngCore, SeedableRng};
use shared::dem::collision::overlap::{gap_proof, overlap, overlap_along, overlap_half_space};
use shared::dem::shape::{Posed, Shape};
use shared::geometry::mesh::cube;
use shared::geometry::polygen;
use shared::math::{unit_f64, Vec3};

/// Signed separation of two convex polyhedra by the separating-axis test over face normals and
/// edge-edge cross products: > 0 separated by that gap, < 0 overlapping by at least that.
fn sat_gap(sa: &Shape, a: &Posed, sb: &Shape, b: &Posed) -> f64 {
    let edges = |s: &Shape, p: &Posed| -> Vec<Vec3> {
        (0..s.face_count())
            .flat_map(|f| {
                let idx = s.face(f);
                (0..idx.len()).map(move |k| (idx[k], idx[(k + 1) % idx.len()]))
            })
            .filter(|(i, j)| i < j)
            .map(|(i, j)| p.vertices[j as usize] - p.vertices[i as usize])
            .collect()
    };
    let mut axes: Vec<Vec3> = a.normals.iter().chain(&b.normals).copied().collect();
    for ea in edges(sa, a) {
        for eb in edges(sb, b) {
            let c = ea.cross(&eb);
            if c.norm() > 1e-9 * ea.norm() * eb.norm() {
                axes.push(c.normalize());
            }
        }
    }
    axes.iter()
        .map(|n| {
            let (mina, maxa) = a
                .vertices
                .iter()
                .map(|v| n.dot(v))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| {
                    (l.min(x), h.max(x))
                });
            let (minb, maxb) = b
                .vertices
                .iter()
                .map(|v| n.dot(v))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| {
                    (l.min(x), h.max(x))
                });
            (minb - maxa).max(mina - maxb)
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

fn shapes() -> Vec<(Shape, f64)> {
    let mut out = vec![(Shape::from_mesh(&cube(0.5)).unwrap(), 0.02)];
    for (k, size) in [(6, 0.01), (9, 0.04), (14, 0.025), (8, 0.01)] {
        out.push((Shape::from_mesh(&template(k, 3)).unwrap(), size / 2.0));
    }
    out
}

/// The polygen template of `k` faces from `seed` (first object).
fn template(k: usize, seed: u64) -> shared::geometry::mesh::PolyMesh {
    let params = polygen::Params {
        faces: k,
        ..Default::default()
    };
    polygen::generate(&params, seed, 0).unwrap().mesh
}

/// A unit vector from a uniform draw in the cube [-1/2, 1/2]^3.
fn random_direction(rng: &mut impl RngCore) -> Vec3 {
    let mut u = || unit_f64(rng.next_u64()) - 0.5;
    Vec3::new(u(), u(), u()).normalize()
}

fn random_rotation(rng: &mut impl RngCore) -> UnitQuaternion<f64> {
    let mut u = || unit_f64(rng.next_u64()) * std::f64::consts::TAU;
    UnitQuaternion::from_euler_angles(u(), u(), u())
}

#[test]
fn random_poses_agree_with_the_separating_axis_test() {
    let shapes = shapes();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
    let (mut overlapping, mut separated, mut deep) = (0, 0, 0);
    for trial in 0..6000 {
        let (sa, ka) = &shapes[trial % shapes.len()];
        let (sb, kb) = &shapes[(trial / shapes.len()) % shapes.len()];
        let a = sa.posed(&Vec3::zeros(), &random_rotation(&mut rng), *ka);
        let reach = sa.radius * ka + sb.radius * kb;
        let dir = random_direction(&mut rng);
        let dist = reach * unit_f64(rng.next_u64());
        let b = sb.posed(&(dir * dist), &random_rotation(&mut rng), *kb);
        let gap = sat_gap(sa, &a, sb, &b);
        let size = (sa.radius * ka).min(sb.radius * kb);
        let o = overlap(sa, &a, sb, &b);
        if gap < -1e-9 * size {
            overlapping += 1;
            let o = o.unwrap_or_else(|| {
                panic!(
                    "trial {trial}: overlapping by {} but reported separated",
                    -gap
                )
            });
            let n = o.normal();
            assert!((n.norm() - 1.0).abs() < 1e-12 && o.volume > 0.0 && o.depth() > 0.0);
            // The culling axis (warm-started from the last normal in the engine) changes the
            // result only by round-off, conditioned as the problem is: measured worst over these
            // poses, depth 5e-13 x size (4e-7 when one body nearly swallows the other, where
            // S_B nearly cancels), contact point 2e-7 x size (a grazing overlap 6e-6 x size
            // deep), normal 4e-11. The worst axis, minus the normal, must still find the overlap.
            let swallowed = o.area_b.norm() < 1e-3 * o.volume.powf(2.0 / 3.0);
            for axis in [n, dir.cross(&Vec3::new(0.3, -0.5, 0.8))] {
                let p = overlap_along(sa, &a, sb, &b, &axis)
                    .unwrap_or_else(|| panic!("trial {trial}: axis {axis:?} separated"));
                let depth_tol = if swallowed { 1e-6 } else { 1e-10 };
                assert!(
                    (p.depth() - o.depth()).abs() <= depth_tol * size
                        && (p.centroid - o.centroid).norm() <= 1e-6 * size
                        && (p.normal() - n).norm() <= 1e-9,
                    "trial {trial}: axis {axis:?} gave {p:?}, centre line {o:?}"
                );
            }
            assert!(overlap_along(sa, &a, sb, &b, &-n).is_some());
            if -gap > 0.3 * size {
                deep += 1;
            } else {
                // Shallow: the normal points from A towards B (the side B is on along n).
                let (ca, cb) = (
                    a.vertices.iter().sum::<Vec3>() / a.vertices.len() as f64,
                    b.vertices.iter().sum::<Vec3>() / b.vertices.len() as f64,
                );
                let support_a = a
                    .vertices
                    .iter()
                    .map(|v| n.dot(v))
                    .fold(f64::NEG_INFINITY, f64::max);
                let support_b = b
                    .vertices
                    .iter()
                    .map(|v| n.dot(v))
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    support_b < support_a,
                    "trial {trial}: along n, B must start inside A's extent"
                );
                assert!(
                    n.dot(&(cb - ca)) > -0.5 * (cb - ca).norm(),
                    "trial {trial}: normal flipped"
                );
            }
        } else if gap > 1e-9 * size {
            separated += 1;
            assert!(
                o.is_none() && overlap_along(sa, &a, sb, &b, &-dir).is_none(),
                "trial {trial}: separated by {gap} but reported overlapping"
            );
        }
    }
    assert!(
        overlapping > 1000 && separated > 1000 && deep > 50,
        "{overlapping} overlapping ({deep} deep), {separated} separated"
    );
}

#[test]
fn named_hard_pairs() {
    let c = Shape::from_mesh(&cube(0.5)).unwrap();
    let id = UnitQuaternion::identity();
    let at = |p: Vec3, q: UnitQuaternion<f64>, s: f64| c.posed(&p, &q, s);
    let a = at(Vec3::zeros(), id, 1.0);
    let cases: Vec<(&str, Posed, bool)> = vec![
        (
            "exactly parallel faces, touching",
            at(Vec3::new(1.0, 0.3, 0.2), id, 1.0),
            false,
        ),
        (
            "exactly parallel faces, 1e-9 deep",
            at(Vec3::new(1.0 - 1e-9, 0.3, 0.2), id, 1.0),
            true,
        ),
        (
            "coincident edges, 1e-9 deep",
            at(Vec3::new(1.0 - 1e-9, 1.0 - 1e-9, 0.0), id, 1.0),
            true,
        ),
        (
            "vertex on vertex, 1e-9 deep",
            at(Vec3::new(1.0 - 1e-9, 1.0 - 1e-9, 1.0 - 1e-9), id, 1.0),
            true,
        ),
        (
            "vertex on vertex, 1e-9 apart",
            at(Vec3::new(1.0 + 1e-9, 1.0 + 1e-9, 1.0 + 1e-9), id, 1.0),
            false,
        ),
        (
            "small against large (1:4)",
            at(Vec3::new(0.5 + 0.125 - 1e-6, 0.1, -0.2), id, 0.25),
            true,
        ),
        (
            "deep overlap: half a size",
            at(
                Vec3::new(0.5, 0.0, 0.0),
                UnitQuaternion::from_euler_angles(0.3, 0.2, 0.1),
                1.0,
            ),
            true,
        ),
        (
            "small one almost swallowed",
            at(Vec3::new(0.4, 0.0, 0.0), id, 0.25),
            true,
        ),
        (
            "small one wholly inside (S_B = 0)",
            at(Vec3::new(0.1, 0.02, 0.0), id, 0.25),
            true,
        ),
    ];
    for (name, b, expect) in cases {
        let o = overlap(&c, &a, &c, &b);
        assert_eq!(o.is_some(), expect, "{name}");
        if let Some(o) = o {
            let n = o.normal();
            assert!(
                n.iter().all(|x| x.is_finite()) && (n.norm() - 1.0).abs() < 1e-12,
                "{name}: normal {n}"
            );
            assert!(
                n.x > 0.0,
                "{name}: the normal points from A (at the origin) towards B (+x): {n}"
            );
            assert!(
                o.depth() > 0.0 && o.depth().is_finite(),
                "{name}: depth {}",
                o.depth()
            );
        }
    }
}

/// A vertex of A pressed `delta` into a face of B (or into a plane wall), far from the origin
/// and from the centre of the bodies' box intersection, for depths from 1e-12 to 1e-4 of the
/// size. Any convex cap of height `delta` has `V / |S_B|` between `delta / 3` (a cone) and
/// `delta` (a prism), lies between the face and the vertex, and has the face's normal.
/// Guards the divergence sums' reference point: taken a body's size away, their round-off swamped
/// a grazing overlap's volume and gave a depth of 2.6 m (a pair of the Yade bed at kn = 1e8 N/m,
/// 1e-23 m^3 of noise over |S_B| = 5e-24 m^2), which blew the bed apart.
#[test]
fn grazing_vertex_contacts_have_the_depth_of_their_penetration() {
    let shapes = shapes();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let (mut worst_low, mut worst_high, mut worst_normal) = (f64::INFINITY, 0.0f64, 0.0f64);
    let mut checked = 0;
    for trial in 0..400 {
        let (sa, ka) = &shapes[trial % shapes.len()];
        let (sb, kb) = &shapes[(trial / shapes.len() + 1) % shapes.len()];
        let far = Vec3::new(0.31, -0.17, 0.23);
        let ra = random_rotation(&mut rng);
        let rb = random_rotation(&mut rng);
        let b0 = sb.posed(&Vec3::zeros(), &rb, *kb);
        let f = (rng.next_u64() % sb.face_count() as u64) as usize;
        let m = b0.normals[f];
        let idx = sb.face(f);
        let face_centre =
            idx.iter().map(|&i| b0.vertices[i as usize]).sum::<Vec3>() / idx.len() as f64;
        let a = sa.posed(&far, &ra, *ka);
        // A's lowest vertex along m.
        let p = *a
            .vertices
            .iter()
            .min_by(|u, v| m.dot(u).total_cmp(&m.dot(v)))
            .unwrap();
        let size = (sa.radius * ka).min(sb.radius * kb);
        for rel in [1e-12, 1e-10, 1e-8, 1e-6, 1e-4] {
            let delta = rel * size;
            // B's face centre at p + m delta: p lies delta inside B.
            let b = sb.posed(&(p + m * delta - face_centre), &rb, *kb);
            // Only the cap near p may touch B: skip poses where A reaches past the face's
            // edges (the face too small for A's blunt corner).
            let cap_fits = a
                .vertices
                .iter()
                .filter(|v| m.dot(&(*v - p)) < delta)
                .count()
                == 1;
            if !cap_fits {
                continue;
            }
            let slab = |o: &shared::dem::collision::overlap::Overlap| m.dot(&(o.centroid - p));
            let tol = 1e-9 * delta + 1e-15;
            for (o, normal) in [
                (overlap(sa, &a, sb, &b), -m),
                (overlap_half_space(sa, &a, &m, m.dot(&p) + delta), m),
            ] {
                let Some(o) = o else {
                    // Sub-picometre caps may round away; a deeper one must be found.
                    assert!(
                        rel < 1e-10,
                        "trial {trial}: {rel} x size reported separated"
                    );
                    continue;
                };
                let depth = o.depth();
                checked += 1;
                worst_low = worst_low.min(depth / delta);
                worst_high = worst_high.max(depth / delta);
                worst_normal = worst_normal.max((o.normal() - normal).norm() * delta);
                assert!(
                    depth >= delta / 3.0 * (1.0 - 1e-3) - tol && depth <= delta + tol,
                    "trial {trial}: penetration {delta:e} m gave depth {depth:e} m"
                );
                // The cap's normal is known to the coordinates' round-off over its size.
                assert!(
                    (o.normal() - normal).norm() <= 1e-9 + 1e-16 / delta,
                    "trial {trial}: normal {:?} for a face normal {normal:?}",
                    o.normal()
                );
                assert!(
                    slab(&o) >= -tol && slab(&o) <= delta + tol,
                    "trial {trial}: contact point {:e} m off the cap (depth {delta:e})",
                    slab(&o)
                );
            }
        }
    }
    eprintln!(
        "{checked} grazing caps: depth / penetration in [{worst_low:.4}, {worst_high:.4}], \
         normal off by {worst_normal:.1e} m / penetration"
    );
    assert!(checked > 1000, "only {checked} caps checked");
}

/// Large hulls find the vertices in the culling slab by climbing the vertex graph (from the
/// vertex their cube map of directions gives) instead of scanning every vertex. The vertex sets are the same, so the overlap must be
/// the same, bit for bit, as with the scan: checked on Ab_2 and Ab_3 hulls (about 200 and 770
/// vertices) and on a flat ellipsoid's hull (nearly coplanar vertices), from grazing to deep
/// overlaps and separated poses, culled along several axes. GJK's gap proofs climb too: they
/// must hold for every pose they are given for, and be found as often as with scanned supports;
/// a plane wall finds the same overlap by climbing to the lowest vertex.
#[test]
fn climbing_large_hulls_finds_the_same_overlap_as_scanning() {
    let mut large = Vec::new();
    for (k, levels) in [(6, 3), (9, 2), (14, 3), (11, 2)] {
        let p = template(k, 5);
        let smooth = shared::geometry::subdiv::subdivide(&p, &p.topology(None).unwrap(), levels);
        large.push(Shape::from_mesh(&smooth).unwrap());
    }
    // A flat ellipsoid (1 : 1 : 0.03) of 400 random surface points: many nearly coplanar
    // vertices on its faces, where heights differ by little.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let flat: Vec<Vec3> = (0..400)
        .map(|_| {
            let z = 2.0 * unit_f64(rng.next_u64()) - 1.0;
            let phi = std::f64::consts::TAU * unit_f64(rng.next_u64());
            let r = (1.0 - z * z).sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), 0.03 * z)
        })
        .collect();
    large
        .push(Shape::from_mesh(&shared::geometry::hull::convex_hull(&flat).unwrap().mesh).unwrap());
    for s in &large {
        assert!(
            s.climb.is_some(),
            "{} vertices: too few to climb",
            s.vertices.len()
        );
    }
    let scanning: Vec<Shape> = large
        .iter()
        .map(|s| Shape {
            climb: None,
            ..s.clone()
        })
        .collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let (mut touching, mut apart) = (0, 0);
    let mut proofs = [0usize; 4];
    for trial in 0..800 {
        let (i, j) = (trial % large.len(), (trial / large.len()) % large.len());
        let a = large[i].posed(&Vec3::zeros(), &random_rotation(&mut rng), 1.0);
        let dir = random_direction(&mut rng);
        let rb = random_rotation(&mut rng);
        // Half the poses near first touch along `dir` (bisection), half anywhere within reach.
        let at = |t: f64| large[j].posed(&(dir * t), &rb, 1.0);
        let reach = large[i].radius + large[j].radius;
        let t = if trial % 2 == 0 {
            let (mut lo, mut hi) = (0.0, reach);
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                if overlap(&scanning[i], &a, &scanning[j], &at(mid)).is_some() {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            hi - reach * 10f64.powf(-1.0 - 9.0 * unit_f64(rng.next_u64()))
        } else {
            reach * unit_f64(rng.next_u64())
        };
        let b = at(t);
        // A plane wall (outward normal `dir`) reaching into A from grazing to deep.
        let low = a
            .vertices
            .iter()
            .map(|v| dir.dot(v))
            .fold(f64::MAX, f64::min);
        let d = low + reach * (10f64.powf(-9.0 * unit_f64(rng.next_u64())) - 1e-6);
        assert_eq!(
            overlap_half_space(&large[i], &a, &dir, d),
            overlap_half_space(&scanning[i], &a, &dir, d),
            "trial {trial}: wall"
        );
        for axis in [
            dir,
            centre(&b) - centre(&a),
            dir.cross(&Vec3::new(0.3, -0.5, 0.8)),
        ] {
            let climbed = overlap_along(&large[i], &a, &large[j], &b, &axis);
            let scanned = overlap_along(&scanning[i], &a, &scanning[j], &b, &axis);
            assert_eq!(climbed, scanned, "trial {trial}, axis {axis:?}");
            // The gap proof with climbed supports: only ever for bodies apart (checked by a
            // full scan along the direction it hands back), by at least its spare distance
            // (what the engine lets the bodies move before proving it again), and as often
            // as with scans.
            let proof = gap_proof(&large[i], &a, &large[j], &b, &axis, &mut Default::default());
            if let Some(p) = proof {
                let d = p.axis.normalize();
                let top_a = a.vertices.iter().map(|v| d.dot(v)).fold(f64::MIN, f64::max);
                let low_b = b.vertices.iter().map(|v| d.dot(v)).fold(f64::MAX, f64::min);
                assert!(
                    top_a < low_b,
                    "trial {trial}: gap proof for touching bodies"
                );
                assert!(p.spare > 0.0, "trial {trial}: spare {}", p.spare);
                let gap = low_b - top_a;
                assert!(
                    gap >= p.spare * (1.0 - 1e-9),
                    "trial {trial}: gap {gap} below the spare {}",
                    p.spare
                );
                assert!(scanned.is_none());
            }
            let scan_proof = gap_proof(
                &scanning[i],
                &a,
                &scanning[j],
                &b,
                &axis,
                &mut Default::default(),
            );
            proofs[usize::from(proof.is_some()) * 2 + usize::from(scan_proof.is_some())] += 1;
            if climbed.is_some() {
                touching += 1;
            } else {
                apart += 1;
            }
        }
    }
    assert!(
        touching > 800 && apart > 200,
        "{touching} touching, {apart} apart"
    );
    // [neither, scan only, climb only, both]
    println!("gap proofs: {proofs:?}");
    assert!(
        proofs[3] > 150 && proofs[1] + proofs[2] <= proofs[3] / 50,
        "{proofs:?}"
    );
}

fn centre(p: &Posed) -> Vec3 {
    (p.lo + p.hi) * 0.5
}
