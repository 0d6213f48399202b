//! OBJ meshes to shaded PNG pictures.

use crate::math::Vec3;
use crate::mesh::PolyMesh;

/// A UV sphere of radius `r` (closed, outward), `rings` x `segments`.
pub fn uv_sphere(r: f64, rings: usize, segments: usize) -> PolyMesh {
    let mut m = PolyMesh::named("sphere");
    m.vertices.push(Vec3::new(0.0, 0.0, r));
    for i in 1..rings {
        let th = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let ph = std::f64::consts::TAU * j as f64 / segments as f64;
            m.vertices
                .push(Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()) * r);
        }
    }
    m.vertices.push(Vec3::new(0.0, 0.0, -r));
    let south = (m.vertices.len() - 1) as u32;
    let at = |i: usize, j: usize| (1 + (i - 1) * segments + j % segments) as u32;
    for j in 0..segments {
        m.push_face(&[0, at(1, j), at(1, j + 1)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            m.push_face(&[at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    for j in 0..segments {
        m.push_face(&[at(rings - 1, j), south, at(rings - 1, j + 1)]);
    }
    m
}
