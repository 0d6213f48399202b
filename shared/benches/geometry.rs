//! Throughput of the geometry kernels in process, in objects per second (and bytes per second
//! for the OBJ text): polygen, one Catmull-Clark level from each level, roundness (validation,
//! mass properties and hull), OBJ writing and parsing. Run with `make bench`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use shared::geometry::mass::MassProps;
use shared::geometry::mesh::PolyMesh;
use shared::geometry::{hull, obj, polygen, subdiv};
use std::hint::black_box;

/// The nine templates' families: `per_k` polyhedra for each face count 6..14.
fn polyhedra(per_k: u64) -> Vec<PolyMesh> {
    (6..=14)
        .flat_map(|k| (0..per_k).map(move |i| (k, i)))
        .map(|(k, i)| {
            polygen::generate(
                &polygen::Params {
                    faces: k,
                    ..Default::default()
                },
                1,
                i,
            )
            .unwrap()
            .mesh
        })
        .collect()
}

fn abrade_all(meshes: &[PolyMesh]) -> Vec<PolyMesh> {
    meshes
        .iter()
        .map(|m| subdiv::catmull_clark(m, &m.topology(None).unwrap()))
        .collect()
}

fn bench(c: &mut Criterion) {
    let n = 18; // objects per iteration: 2 per face count
    let mut g = c.benchmark_group("geometry");
    g.sample_size(20);
    g.throughput(Throughput::Elements(n));
    g.bench_function("polygen objects", |b| b.iter(|| black_box(polyhedra(2))));
    let mut level = polyhedra(2);
    for l in 1..=3 {
        let input = level.clone();
        g.bench_function(format!("abrade level {l} objects"), |b| {
            b.iter(|| black_box(abrade_all(&input)))
        });
        level = abrade_all(&input);
    }
    let ab3 = level;
    g.bench_function(
        "roundness Ab3 objects (validate, mass, hull, hull mass)",
        |b| {
            b.iter(|| {
                for m in &ab3 {
                    m.topology(None).unwrap();
                    black_box(MassProps::of(m));
                    let h = hull::convex_hull(&m.vertices).unwrap();
                    black_box(MassProps::of(&h.mesh));
                }
            })
        },
    );
    g.bench_function("hull only Ab3 objects", |b| {
        b.iter(|| {
            for m in &ab3 {
                black_box(hull::convex_hull(&m.vertices).unwrap());
            }
        })
    });
    let text = obj::to_string(&ab3);
    g.throughput(Throughput::Bytes(text.len() as u64));
    g.bench_function("OBJ write Ab3 bytes", |b| {
        b.iter(|| black_box(obj::to_string(&ab3)))
    });
    g.bench_function("OBJ parse Ab3 bytes", |b| {
        b.iter(|| black_box(obj::read_all(text.as_bytes()).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
