//! Properties that must hold for any input the generators can make (proptest).

use proptest::prelude::*;
use shared::geometry::{hull, mass::MassProps, obj, polygen, subdiv};
use shared::math::Vec3;

fn polyhedron(k: usize, seed: u64) -> shared::geometry::mesh::PolyMesh {
    let params = polygen::Params {
        faces: k,
        ..Default::default()
    };
    polygen::generate(&params, seed, 0)
        .expect("default cap is reachable for k >= 5")
        .mesh
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn subdivision_keeps_a_closed_sphere_and_rounds(k in 5usize..16, seed in 0u64..1_000_000, levels in 1u32..4) {
        let m = polyhedron(k, seed);
        let s = subdiv::subdivide(&m, &m.topology(None).unwrap(), levels);
        prop_assert!(s.topology(None).is_ok());
        prop_assert_eq!(s.euler_characteristic(), 2);
        let (s0, s1) = (MassProps::of(&m).s3d(), MassProps::of(&s).s3d());
        prop_assert!(s1 > 0.0 && s1 <= 1.0);
        prop_assert!(s1 > s0, "abrasion rounds: {} -> {}", s0, s1);
    }

    #[test]
    fn hull_contains_its_points(seed in 0u64..1_000_000, n in 4usize..300, flat in 0.0f64..1.0) {
        let m = polyhedron(8, seed);
        // Points from a deformed polyhedron's subdivision plus random squashing.
        let pts: Vec<Vec3> = subdiv::subdivide(&m, &m.topology(None).unwrap(), 2)
            .vertices
            .iter()
            .take(n.max(4))
            .map(|p| Vec3::new(p.x, p.y, p.z * (0.05 + flat)))
            .collect();
        let h = match hull::convex_hull(&pts) {
            Ok(h) => h,
            Err(hull::HullError::Flat) => return Ok(()),
            Err(e) => return Err(TestCaseError::fail(e.to_string())),
        };
        prop_assert!(h.mesh.topology(None).is_ok());
        let tol = 1e-9 * shared::math::extent(&pts);
        for (n, d) in &h.planes {
            for p in &pts {
                prop_assert!(n.dot(p) - d <= tol);
            }
        }
    }

    #[test]
    fn obj_text_round_trips_exactly(k in 4usize..20, seed in 0u64..1_000_000, scale in -20i32..20) {
        let params = polygen::Params { faces: k, max_elongation: f64::INFINITY, ..Default::default() };
        let mut m = polygen::generate(&params, seed, 1).unwrap().mesh;
        for v in &mut m.vertices {
            *v *= 10f64.powf(f64::from(scale));
        }
        let text = obj::to_string(std::slice::from_ref(&m));
        let back = obj::read_all(text.as_bytes()).unwrap();
        prop_assert_eq!(&back[0].mesh, &m);
    }

    #[test]
    fn roundness_is_invariant_to_rigid_motion_and_scale(k in 5usize..15, seed in 0u64..1_000_000, a in -3.0f64..3.0, b in -3.0f64..3.0, s in 0.001f64..1000.0) {
        let m = polyhedron(k, seed);
        let r = nalgebra::Rotation3::from_euler_angles(a, b, a * b);
        let mut moved = m.clone();
        for v in &mut moved.vertices {
            *v = r * (*v * s) + Vec3::new(5.0, -7.0, 11.0);
        }
        let (x, y) = (MassProps::of(&m).s3d(), MassProps::of(&moved).s3d());
        prop_assert!((x - y).abs() < 1e-10, "{} vs {}", x, y);
    }
}
