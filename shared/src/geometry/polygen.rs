//! Random convex polyhedra from tangent planes of a sphere (the paper's section 2.1).
//!
//! `k` points are drawn uniformly on a sphere of radius `R`; the polyhedron is the intersection
//! of the half-spaces `p_i . x <= R^2` below their tangent planes. It is built as the exact polar
//! dual of the points' convex hull: a hull facet with unit normal `n` at distance `d` from the
//! origin gives the vertex `(R^2 / d) n`, a hull vertex (tangent point `i`) gives face `i`.
//!
//! A draw is redrawn when
//! - *unbounded*: the origin is not strictly inside the points' hull (exact orientation tests),
//! - *degenerate*: fewer than `k` hull vertices, i.e. two points closer than the hull's merge
//!   tolerance (one face would vanish), or all points on one plane,
//! - *elongated*: the farthest vertex is more than `max_elongation x R` from the centre.
//!
//! The counts of each kind of redraw travel with the object. Each object has its own random
//! stream, chosen by `(seed, k, index)`, so an object does not depend on what else is generated,
//! on the order of generation or on the number of threads.

use crate::geometry::hull::{self, side, HullError};
use crate::geometry::mesh::PolyMesh;
use crate::math::{unit_f64, Vec3};
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use thiserror::Error;

impl Params {
    /// The parameters' ranges: at least 4 faces, a positive finite radius, a cap above 1.
    pub fn check(&self) -> Result<(), PolygenError> {
        if self.faces < 4 {
            return Err(PolygenError::TooFewFaces(self.faces));
        }
        if !(self.radius > 0.0 && self.radius.is_finite()) {
            return Err(PolygenError::BadRadius(self.radius));
        }
        if self.max_elongation.is_nan() || self.max_elongation <= 1.0 {
            return Err(PolygenError::BadCap(self.max_elongation));
        }
        Ok(())
    }
}

/// Default elongation cap (farthest vertex over the inscribed radius `R`); see `docs/models/polygen.md`
/// for how it was chosen and what it changes.
pub const DEFAULT_MAX_ELONGATION: f64 = 5.0;

/// Two tangent points closer than this times `R` make a degenerate draw: the edge between their
/// faces would be flatter than this angle (radians), and the vertices along it are
/// ill-conditioned (a hull facet normal from a cross product of vectors this short loses
/// `log10(1 / MIN_SEPARATION_REL)` digits). A uniform draw of 1000 points has such a pair with
/// probability about 1e-7, so the rule does not bias the shapes.
pub const MIN_SEPARATION_REL: f64 = 1e-6;

/// A draw whose smallest face has less area than this times `R^2` is degenerate: two tangent
/// points so close that their faces would be slivers (face area scales with the points' distance).
pub const MIN_FACE_AREA_REL: f64 = 1e-12;

/// Draws per object before giving up (a cap below what `k` faces can reach never succeeds).
pub const MAX_DRAWS: u64 = 100_000;

/// What to generate.
#[derive(Clone, Debug)]
pub struct Params {
    /// Number of tangent planes = faces (at least 4).
    pub faces: usize,
    /// Radius of the sphere: the polyhedron's inscribed radius.
    pub radius: f64,
    /// Redraw when the farthest vertex is beyond `max_elongation x radius` (infinite: no cap).
    pub max_elongation: f64,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            faces: 8,
            radius: 1.0,
            max_elongation: DEFAULT_MAX_ELONGATION,
        }
    }
}

/// How many draws were thrown away, by reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Redraws {
    pub unbounded: u64,
    pub degenerate: u64,
    pub elongated: u64,
}

impl Redraws {
    pub fn total(&self) -> u64 {
        self.unbounded + self.degenerate + self.elongated
    }

    pub fn add(&mut self, other: &Redraws) {
        self.unbounded += other.unbounded;
        self.degenerate += other.degenerate;
        self.elongated += other.elongated;
    }
}

/// A generated polyhedron: its mesh (face `i` lies in the tangent plane at point `i`), the
/// tangent points, the redraws it took and its elongation (farthest vertex over `R`).
#[derive(Clone, Debug)]
pub struct Polyhedron {
    pub mesh: PolyMesh,
    pub tangent_points: Vec<Vec3>,
    pub redraws: Redraws,
    pub elongation: f64,
}

/// Why no polyhedron came out.
#[derive(Debug, Error, PartialEq)]
pub enum PolygenError {
    #[error("a polyhedron needs at least 4 faces, asked for {0}")]
    TooFewFaces(usize),
    #[error("the radius must be positive and finite, got {0}")]
    BadRadius(f64),
    #[error("the elongation cap must be greater than 1, got {0}")]
    BadCap(f64),
    #[error("no {faces}-faced draw met the elongation cap {cap} in {draws} draws; raise --max-elongation")]
    GaveUp { faces: usize, cap: f64, draws: u64 },
}

/// Why one draw of tangent points gives no polyhedron.
#[derive(Debug, Error, PartialEq)]
pub enum DrawError {
    #[error(
        "the origin is not strictly inside the tangent points' hull: the polyhedron is unbounded"
    )]
    Unbounded,
    #[error("the tangent points are degenerate ({0})")]
    Degenerate(String),
}

/// The polyhedron `{x : p_i . x <= |p_i|^2}` for tangent points `p_i` on a sphere of radius
/// `radius` (the points are used as given), and its elongation.
pub fn from_tangent_points(points: &[Vec3], radius: f64) -> Result<(PolyMesh, f64), DrawError> {
    let hull = hull::convex_hull(points).map_err(|e| match e {
        HullError::Flat => DrawError::Unbounded,
        other => DrawError::Degenerate(other.to_string()),
    })?;
    if hull.mesh.vertices.len() != points.len() {
        return Err(DrawError::Degenerate(format!(
            "{} of {} points are hull corners; points closer than the merge tolerance share a face",
            hull.mesh.vertices.len(),
            points.len()
        )));
    }
    let origin = Vec3::zeros();
    for (f, (_, d)) in hull.planes.iter().enumerate() {
        let idx = hull.mesh.face(f);
        let v = |k: usize| hull.mesh.vertices[idx[k] as usize];
        if *d <= 0.0 || side(&v(0), &v(1), &v(2), &origin) >= 0.0 {
            return Err(DrawError::Unbounded);
        }
    }
    let topo = hull
        .mesh
        .topology(None)
        .map_err(|e| DrawError::Degenerate(e.to_string()))?;
    // The closest pair of points on a sphere is a hull edge.
    for h in 0..hull.mesh.face_verts.len() {
        let f = topo.face_of[h] as usize;
        let (a, b) = (
            hull.mesh.face_verts[h],
            hull.mesh.face_verts[hull.mesh.next(h, f)],
        );
        if (hull.mesh.vertices[a as usize] - hull.mesh.vertices[b as usize]).norm()
            < MIN_SEPARATION_REL * radius
        {
            return Err(DrawError::Degenerate(format!(
                "tangent points {} and {} nearly coincide",
                a + 1,
                b + 1
            )));
        }
    }
    let r2 = radius * radius;
    // The output depends on the geometry only, not on the hull's internal order: hull vertex i
    // is tangent point i (all are corners, in input order); a dual vertex is numbered by the
    // sorted list of tangent points whose planes meet there, and computed from its hull facet
    // read from its smallest point; each face starts at its smallest vertex.
    let nf = hull.mesh.face_count();
    let cycles: Vec<Vec<u32>> = (0..nf)
        .map(|f| {
            let c = hull.mesh.face(f);
            let start = (0..c.len()).min_by_key(|&k| c[k]).unwrap_or(0);
            c[start..].iter().chain(&c[..start]).copied().collect()
        })
        .collect();
    let mut order: Vec<usize> = (0..nf).collect();
    let keys: Vec<Vec<u32>> = cycles
        .iter()
        .map(|c| {
            let mut k = c.clone();
            k.sort_unstable();
            k
        })
        .collect();
    order.sort_by(|&a, &b| keys[a].cmp(&keys[b]));
    let mut new_id = vec![0u32; nf];
    for (rank, &f) in order.iter().enumerate() {
        new_id[f] = rank as u32;
    }
    let mut mesh = PolyMesh::named("polyhedron");
    mesh.vertices = order
        .iter()
        .map(|&f| {
            let (n, d) =
                hull::polygon_plane(cycles[f].iter().map(|&i| hull.mesh.vertices[i as usize]));
            n * (r2 / d)
        })
        .collect();
    let mut ring = Vec::new();
    for v in 0..points.len() {
        ring.clear();
        ring.extend(
            hull.mesh
                .ring(&topo, v)
                .map(|h| new_id[topo.face_of[h] as usize]),
        );
        let start = (0..ring.len()).min_by_key(|&k| ring[k]).unwrap_or(0);
        ring.rotate_left(start);
        mesh.push_face(&ring);
    }
    if let Some(f) = (0..mesh.face_count())
        .find(|&f| crate::geometry::mass::MassProps::face_area(&mesh, f) < MIN_FACE_AREA_REL * r2)
    {
        return Err(DrawError::Degenerate(format!(
            "face {f} has almost no area: two tangent points nearly coincide"
        )));
    }
    let elongation = mesh.vertices.iter().map(|v| v.norm()).fold(0.0, f64::max) / radius;
    if !elongation.is_finite() {
        return Err(DrawError::Unbounded);
    }
    Ok((mesh, elongation))
}

/// The random stream of object `index` with `faces` faces under `seed`.
pub fn stream(seed: u64, faces: usize, index: u64) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    let mut rng = ChaCha8Rng::from_seed(key);
    rng.set_stream(((faces as u64) << 40) ^ index);
    rng
}

/// A point uniform on the sphere of radius `r` (uniform height and azimuth: Archimedes).
pub fn uniform_on_sphere(rng: &mut impl RngCore, r: f64) -> Vec3 {
    let z = 2.0 * unit_f64(rng.next_u64()) - 1.0;
    let phi = std::f64::consts::TAU * unit_f64(rng.next_u64());
    let s = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(s * phi.cos(), s * phi.sin(), z) * r
}

/// Object `index` of the family (`params`, `seed`): deterministic, independent of other objects.
pub fn generate(params: &Params, seed: u64, index: u64) -> Result<Polyhedron, PolygenError> {
    params.check()?;
    let k = params.faces;
    let mut rng = stream(seed, k, index);
    let mut redraws = Redraws::default();
    let mut points = Vec::with_capacity(k);
    for _ in 0..MAX_DRAWS {
        points.clear();
        points.extend((0..k).map(|_| uniform_on_sphere(&mut rng, params.radius)));
        match from_tangent_points(&points, params.radius) {
            Err(DrawError::Unbounded) => redraws.unbounded += 1,
            Err(DrawError::Degenerate(_)) => redraws.degenerate += 1,
            Ok((_, e)) if e > params.max_elongation => redraws.elongated += 1,
            Ok((mut mesh, elongation)) => {
                mesh.name = format!("p{k:02}_{index}");
                mesh.attrs.set("k", k);
                mesh.attrs.set("seed", seed);
                mesh.attrs.set("index", index);
                mesh.attrs.set("redraws", redraws.total());
                mesh.attrs.set("elongation", format!("{elongation:.6}"));
                return Ok(Polyhedron {
                    mesh,
                    tangent_points: points,
                    redraws,
                    elongation,
                });
            }
        }
    }
    Err(PolygenError::GaveUp {
        faces: k,
        cap: params.max_elongation,
        draws: MAX_DRAWS,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mass::MassProps;

    /// Checks the promises: k planar faces in the tangent planes, closed oriented convex
    /// manifold, no duplicated vertices, no zero-area face.
    fn check(mesh: &PolyMesh, points: &[Vec3], r: f64) {
        mesh.topology(None).expect("closed oriented manifold");
        assert_eq!(mesh.face_count(), points.len());
        assert_eq!(mesh.euler_characteristic(), 2);
        let scale = mesh.vertices.iter().map(|v| v.norm()).fold(r, f64::max);
        for (f, p) in points.iter().enumerate() {
            for &v in mesh.face(f) {
                let x = mesh.vertices[v as usize];
                // Vertex on its tangent plane p.x = R^2, to rounding relative to its size.
                assert!(
                    (p.dot(&x) - r * r).abs() <= 1e-9 * r * scale,
                    "face {f} not in its tangent plane"
                );
            }
            for q in points {
                for &v in mesh.face(f) {
                    assert!(
                        q.dot(&mesh.vertices[v as usize])
                            <= r * r * (1.0 + 1e-9) + 1e-9 * r * scale
                    );
                }
            }
        }
        let mut sorted: Vec<[u64; 3]> = mesh
            .vertices
            .iter()
            .map(|v| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()])
            .collect();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), mesh.vertices.len(), "duplicated vertices");
        let m = MassProps::of(mesh);
        assert!(m.volume > 0.0, "outward faces give positive volume");
        for f in 0..mesh.face_count() {
            let sub = PolyMesh::from_faces("f", mesh.vertices.clone(), &[mesh.face(f).to_vec()]);
            assert!(
                MassProps::face_area(&sub, 0) > 0.0,
                "face {f} has zero area"
            );
        }
    }

    #[test]
    fn templates_are_valid_and_deterministic() {
        for k in 4..=14 {
            let params = Params {
                faces: k,
                max_elongation: f64::INFINITY,
                ..Default::default()
            };
            let a = generate(&params, 7, 0).unwrap();
            check(&a.mesh, &a.tangent_points, 1.0);
            let b = generate(&params, 7, 0).unwrap();
            assert_eq!(a.mesh, b.mesh);
            assert_eq!(a.mesh.face_count(), k);
        }
    }

    #[test]
    fn cube_from_six_axis_points() {
        let pts: Vec<Vec3> = [
            Vec3::x(),
            -Vec3::x(),
            Vec3::y(),
            -Vec3::y(),
            Vec3::z(),
            -Vec3::z(),
        ]
        .into();
        let (mesh, e) = from_tangent_points(&pts, 1.0).unwrap();
        assert_eq!(mesh.vertices.len(), 8);
        assert!((e - 3f64.sqrt()).abs() < 1e-12);
        check(&mesh, &pts, 1.0);
    }

    #[test]
    fn nearly_co_circular_points_give_valence_four_or_a_tiny_edge() {
        // Four points on a circle of latitude (a square around +z) and four more around; the
        // square's corners are perturbed by eps off the circle.
        for eps in [0.0, 1e-15, 1e-12, 1e-9, 1e-6] {
            let mut pts = Vec::new();
            for i in 0..4 {
                let a = std::f64::consts::FRAC_PI_2 * i as f64 + 0.1;
                let z: f64 = 0.5 + if i == 0 { eps } else { 0.0 };
                let s: f64 = (1.0 - z * z).sqrt();
                pts.push(Vec3::new(s * a.cos(), s * a.sin(), z));
            }
            pts.extend([
                Vec3::new(0.0, 0.0, -1.0),
                Vec3::new(0.9, 0.0, -0.43).normalize(),
                Vec3::new(-0.6, 0.7, -0.2).normalize(),
                Vec3::new(0.0, 0.0, 1.0),
            ]);
            let (mesh, _) = from_tangent_points(&pts, 1.0).unwrap();
            check(&mesh, &pts, 1.0);
        }
    }

    #[test]
    fn nearly_coincident_points_give_a_tiny_face() {
        let params = Params {
            faces: 10,
            max_elongation: f64::INFINITY,
            ..Default::default()
        };
        let base = generate(&params, 3, 0).unwrap();
        let mut pts = base.tangent_points.clone();
        pts.push((pts[0] + Vec3::new(1e-5, -2e-5, 1e-5)).normalize());
        let (mesh, _) = from_tangent_points(&pts, 1.0).unwrap();
        check(&mesh, &pts, 1.0);
        assert_eq!(mesh.face_count(), 11);
        // Closer than MIN_SEPARATION_REL (or exactly equal): a degenerate draw.
        for d in [1e-9, 1e-13, 0.0] {
            let mut pts = base.tangent_points.clone();
            pts.push((pts[0] + Vec3::new(d, 0.0, 0.0)).normalize());
            let r = from_tangent_points(&pts, 1.0);
            assert!(
                matches!(r, Err(DrawError::Degenerate(_))),
                "distance {d}: {:?}",
                r.map(|x| x.1)
            );
        }
    }

    #[test]
    fn near_hemispherical_points_give_long_but_finite_spikes() {
        // Points within a hair of the z = 0 great circle, plus one pole: the origin is barely
        // inside, so vertices reach far out.
        let mut pts: Vec<Vec3> = (0..7)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 7.0;
                Vec3::new(a.cos(), a.sin(), -1e-4).normalize()
            })
            .collect();
        pts.push(Vec3::z());
        pts.push(-Vec3::z());
        let (mesh, e) = from_tangent_points(&pts, 1.0).unwrap();
        check(&mesh, &pts, 1.0);
        assert!(e > 1.0 && e.is_finite());
        // Without the south pole and with all points above the equator: unbounded.
        let up: Vec<Vec3> = pts[..8]
            .iter()
            .map(|p| Vec3::new(p.x, p.y, p.z.abs() + 1e-3).normalize())
            .collect();
        assert_eq!(
            from_tangent_points(&up, 1.0).unwrap_err(),
            DrawError::Unbounded
        );
    }

    #[test]
    fn many_faces() {
        let params = Params {
            faces: 1000,
            radius: 2.5,
            max_elongation: f64::INFINITY,
        };
        let p = generate(&params, 1, 0).unwrap();
        check(&p.mesh, &p.tangent_points, 2.5);
    }

    #[test]
    fn cap_is_respected_and_impossible_cap_is_an_error() {
        let params = Params {
            faces: 6,
            max_elongation: 2.5,
            ..Default::default()
        };
        for i in 0..20 {
            assert!(generate(&params, 5, i).unwrap().elongation <= 2.5);
        }
        // No tetrahedron has elongation below 3 (the regular one has exactly 3).
        let params = Params {
            faces: 4,
            max_elongation: 2.9,
            ..Default::default()
        };
        let err = generate(&Params { ..params }, 1, 0).unwrap_err();
        assert!(matches!(err, PolygenError::GaveUp { .. }));
    }

    /// Not a check: prints elongation quantiles per face count (run with --ignored --nocapture).
    #[test]
    #[ignore]
    fn elongation_distribution() {
        for k in [4, 5, 6, 8, 10, 12, 14] {
            let params = Params {
                faces: k,
                max_elongation: f64::INFINITY,
                ..Default::default()
            };
            let mut e: Vec<f64> = (0..4000)
                .map(|i| generate(&params, 1, i).unwrap().elongation)
                .collect();
            e.sort_by(f64::total_cmp);
            let q = |x: f64| e[((e.len() - 1) as f64 * x) as usize];
            let frac = |c: f64| e.iter().filter(|&&v| v > c).count() as f64 / e.len() as f64;
            println!("k={k:2} min {:.2} q10 {:.2} q50 {:.2} q90 {:.2} q99 {:.1} max {:.0}  >3 {:.3} >4 {:.3} >5 {:.3} >10 {:.4}",
                q(0.0), q(0.1), q(0.5), q(0.9), q(0.99), q(1.0), frac(3.0), frac(4.0), frac(5.0), frac(10.0));
        }
    }

    #[test]
    fn bad_parameters_are_errors() {
        assert_eq!(
            generate(
                &Params {
                    faces: 3,
                    ..Default::default()
                },
                1,
                0
            )
            .unwrap_err(),
            PolygenError::TooFewFaces(3)
        );
        assert!(generate(
            &Params {
                radius: -1.0,
                ..Default::default()
            },
            1,
            0
        )
        .is_err());
        assert!(generate(
            &Params {
                max_elongation: 0.5,
                ..Default::default()
            },
            1,
            0
        )
        .is_err());
    }
}
