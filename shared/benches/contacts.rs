//! Narrow-phase cost per touching pair, in contacts per second (one thread), for the shapes a
//! scene may use: the nine I_P templates, their Ab_3 hulls, and the Ab_3 hulls simplified to
//! 200, 100 and 50 vertices (`simplify`). Each pose touches with a thin overlap (1e-5 of the
//! size, what kn = 1e8 N/m gives under a few newtons) and is evaluated as the engine does for a
//! persistent contact: warm-started from its own normal. Run with `make bench`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use nalgebra::UnitQuaternion;
use rand::{RngCore, SeedableRng};
use shared::dem::collision::overlap::{overlap, overlap_along};
use shared::dem::shape::{Posed, Shape};
use shared::geometry::mesh::PolyMesh;
use shared::geometry::{hull, polygen, subdiv};
use shared::math::{unit_f64, Vec3};
use std::hint::black_box;

fn templates() -> Vec<PolyMesh> {
    (6..=14)
        .map(|k| {
            let p = polygen::Params {
                faces: k,
                ..Default::default()
            };
            polygen::generate(&p, 7, 0).unwrap().mesh
        })
        .collect()
}

fn shapes(meshes: &[PolyMesh]) -> Vec<Shape> {
    meshes
        .iter()
        .map(|m| Shape::from_mesh(m).unwrap())
        .collect()
}

/// Touching poses: B rotated at random and moved along a random direction until it just
/// overlaps A by about `rel` of A's radius.
fn poses(shapes: &[Shape], count: usize, rel: f64) -> Vec<(usize, Posed, usize, Posed, Vec3)> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let mut u = move || unit_f64(rng.next_u64());
    let mut out = Vec::new();
    while out.len() < count {
        let (i, j) = ((u() * 9.0) as usize % 9, (u() * 9.0) as usize % 9);
        let (sa, sb) = (&shapes[i], &shapes[j]);
        let mut rot = || UnitQuaternion::from_euler_angles(u() * 6.3, u() * 6.3, u() * 6.3);
        let (ra, rb) = (rot(), rot());
        let d = Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5).normalize();
        let a = sa.posed(&Vec3::zeros(), &ra, 1.0);
        let at = |t: f64| sb.posed(&(d * t), &rb, 1.0);
        // Bisection on the distance along d between overlapping and apart.
        let (mut lo, mut hi) = (0.0, sa.radius + sb.radius);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if overlap(sa, &a, sb, &at(mid)).is_some() {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let b = at(hi - rel * sa.radius);
        if let Some(o) = overlap(sa, &a, sb, &b) {
            out.push((i, a, j, b, o.normal()));
        }
    }
    out
}

fn bench(c: &mut Criterion) {
    let ip = templates();
    let ab3: Vec<PolyMesh> = ip
        .iter()
        .map(|m| subdiv::subdivide(m, &m.topology(None).unwrap(), 3))
        .collect();
    let budget = |n: usize| -> Vec<PolyMesh> {
        ab3.iter()
            .map(|m| hull::simplified_hull(&m.vertices, n).unwrap().mesh)
            .collect()
    };
    let sets = [
        ("I_P", shapes(&ip)),
        ("Ab_3 hull", shapes(&ab3)),
        ("Ab_3 hull, 200 vertices", shapes(&budget(200))),
        ("Ab_3 hull, 100 vertices", shapes(&budget(100))),
        ("Ab_3 hull, 50 vertices", shapes(&budget(50))),
    ];
    let count = 200;
    let mut g = c.benchmark_group("contacts");
    g.sample_size(10);
    g.throughput(Throughput::Elements(count as u64));
    for (name, set) in &sets {
        let p = poses(set, count, 1e-5);
        g.bench_function(format!("{name}: touching pairs, warm"), |b| {
            b.iter(|| {
                for (i, a, j, pb, n) in &p {
                    black_box(overlap_along(&set[*i], a, &set[*j], pb, n));
                }
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
