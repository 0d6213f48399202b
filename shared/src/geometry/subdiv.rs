//! Catmull-Clark subdivision: the paper's abrasion (its Eqs. 4-6).
//!
//! For a closed, consistently oriented polygon mesh (n-gons, any valence >= 3, convex or not):
//! - face point `f = mean of the face's vertices` (Eq. 4);
//! - edge point `e = (v1 + v2 + f1 + f2) / 4` (Eq. 5);
//! - vertex point `v' = Q/n + 2R/n + (n-3)S/n` (Eq. 6), `n` the valence, `Q` the mean of the
//!   face points around the vertex, `R` the mean of the midpoints of its edges, `S` the vertex.
//!
//! Each face of `n` corners becomes `n` quads `v' -> e(out) -> f -> e(in)`, orientation kept.
//! New vertices are numbered: vertex points, then edge points (in order of first use), then face
//! points. One level turns V vertices, E edges and F faces into V + E + F vertices and
//! sum(face sizes) = 2E quads.

use crate::geometry::mesh::{PolyMesh, Topology};
use crate::math::Vec3;

/// One level of Catmull-Clark subdivision. `topo` must be `mesh.topology(..)`.
pub fn catmull_clark(mesh: &PolyMesh, topo: &Topology) -> PolyMesh {
    let nv = mesh.vertices.len();
    let nf = mesh.face_count();
    let nh = mesh.face_verts.len();
    // Face points.
    let face_pts: Vec<Vec3> = (0..nf).map(|f| mesh.face_centroid(f)).collect();
    // Undirected edge ids, in order of first half-edge.
    let mut edge_of = vec![u32::MAX; nh];
    let mut edge_pts = Vec::with_capacity(nh / 2);
    for h in 0..nh {
        if edge_of[h] != u32::MAX {
            continue;
        }
        let t = topo.twin[h] as usize;
        let id = edge_pts.len() as u32;
        edge_of[h] = id;
        edge_of[t] = id;
        let f = topo.face_of[h] as usize;
        let a = mesh.vertices[mesh.face_verts[h] as usize];
        let b = mesh.vertices[mesh.face_verts[mesh.next(h, f)] as usize];
        edge_pts.push((a + b + face_pts[f] + face_pts[topo.face_of[t] as usize]) * 0.25);
    }
    // Vertex points: every outgoing half-edge of v brings one face (its face) and one edge.
    let mut q = vec![Vec3::zeros(); nv];
    let mut r = vec![Vec3::zeros(); nv];
    let mut valence = vec![0u32; nv];
    for h in 0..nh {
        let f = topo.face_of[h] as usize;
        let v = mesh.face_verts[h] as usize;
        let w = mesh.face_verts[mesh.next(h, f)] as usize;
        q[v] += face_pts[f];
        r[v] += (mesh.vertices[v] + mesh.vertices[w]) * 0.5;
        valence[v] += 1;
    }
    let ne = edge_pts.len();
    let mut out = PolyMesh::named(mesh.name.clone());
    out.attrs = mesh.attrs.clone();
    out.vertices.reserve(nv + ne + nf);
    for v in 0..nv {
        let n = valence[v] as f64;
        let (qm, rm) = (q[v] / n, r[v] / n);
        out.vertices
            .push(qm / n + rm * (2.0 / n) + mesh.vertices[v] * ((n - 3.0) / n));
    }
    out.vertices.extend_from_slice(&edge_pts);
    out.vertices.extend_from_slice(&face_pts);
    out.face_verts.reserve(4 * nh);
    out.face_start.reserve(nh);
    let (e0, f0) = (nv as u32, (nv + ne) as u32);
    for f in 0..nf {
        let (s, e) = (mesh.face_start[f] as usize, mesh.face_start[f + 1] as usize);
        for h in s..e {
            let prev = if h == s { e - 1 } else { h - 1 };
            out.push_face(&[
                mesh.face_verts[h],
                e0 + edge_of[h],
                f0 + f as u32,
                e0 + edge_of[prev],
            ]);
        }
    }
    out
}

/// `levels` levels of Catmull-Clark subdivision (0 returns a copy).
pub fn subdivide(mesh: &PolyMesh, topo: &Topology, levels: u32) -> PolyMesh {
    let mut cur = mesh.clone();
    let mut cur_topo = topo.clone();
    for level in 0..levels {
        cur = catmull_clark(&cur, &cur_topo);
        if level + 1 < levels {
            cur_topo = cur
                .topology(None)
                .expect("Catmull-Clark keeps a closed oriented manifold");
        }
    }
    cur
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mass::MassProps;
    use crate::geometry::mesh::cube;
    use approx::assert_relative_eq;

    #[test]
    fn cube_first_level_points() {
        let c = cube(1.0);
        let s = catmull_clark(&c, &c.topology(None).unwrap());
        // Corner points at 5/9, edge points at 3/4 of the half-width, face points on the faces.
        for v in &s.vertices[..8] {
            assert_relative_eq!(v.abs(), Vec3::repeat(5.0 / 9.0), epsilon = 1e-15);
        }
        for v in &s.vertices[8..20] {
            let mut a: Vec<f64> = v.iter().map(|x| x.abs()).collect();
            a.sort_by(f64::total_cmp);
            assert_relative_eq!(a.as_slice(), [0.0, 0.75, 0.75].as_slice(), epsilon = 1e-15);
        }
        for v in &s.vertices[20..] {
            assert_relative_eq!(v.norm(), 1.0, epsilon = 1e-15);
        }
    }

    #[test]
    fn counts_and_euler_characteristic() {
        let mut m = cube(1.0);
        for _ in 0..3 {
            let topo = m.topology(None).unwrap();
            let (v, e, f) = (m.vertices.len(), m.edge_count(), m.face_count());
            let corners = m.face_verts.len();
            let s = catmull_clark(&m, &topo);
            assert_eq!(s.vertices.len(), v + e + f);
            assert_eq!(s.face_count(), corners);
            assert!(s.faces().all(|q| q.len() == 4));
            assert_eq!(s.euler_characteristic(), 2);
            assert!(MassProps::of(&s).volume > 0.0, "orientation kept");
            m = s;
        }
    }

    #[test]
    fn once_abraded_cube_roundness_with_fan_convention() {
        let c = cube(1.0);
        let s = catmull_clark(&c, &c.topology(None).unwrap());
        assert_relative_eq!(MassProps::of(&s).s3d(), 0.953, epsilon = 5e-4);
    }

    #[test]
    fn commutes_with_affine_maps() {
        let c = crate::geometry::polygen::generate(
            &crate::geometry::polygen::Params {
                faces: 9,
                ..Default::default()
            },
            2,
            0,
        )
        .unwrap()
        .mesh;
        let a = nalgebra::Matrix3::new(1.0, 0.3, -0.2, 0.1, 2.0, 0.4, -0.5, 0.2, 0.7);
        let t = Vec3::new(3.0, -1.0, 0.5);
        let mut mapped = c.clone();
        for v in &mut mapped.vertices {
            *v = a * *v + t;
        }
        let s1 = subdivide(&c, &c.topology(None).unwrap(), 2);
        let s2 = subdivide(&mapped, &mapped.topology(None).unwrap(), 2);
        for (p, q) in s1.vertices.iter().zip(&s2.vertices) {
            assert_relative_eq!(a * p + t, *q, epsilon = 1e-12);
        }
        assert_eq!(s1.face_verts, s2.face_verts);
    }

    #[test]
    fn non_convex_mesh_with_valence_five_and_six() {
        // An L-shaped prism: non-convex, quads and a hexagon, mixed valences.
        let pts = [(0., 0.), (2., 0.), (2., 1.), (1., 1.), (1., 2.), (0., 2.)];
        let mut v: Vec<Vec3> = pts.iter().map(|&(x, y)| Vec3::new(x, y, 0.0)).collect();
        v.extend(pts.iter().map(|&(x, y)| Vec3::new(x, y, 1.0)));
        let mut faces = vec![vec![5, 4, 3, 2, 1, 0], vec![6, 7, 8, 9, 10, 11]];
        for i in 0..6u32 {
            let j = (i + 1) % 6;
            faces.push(vec![i, j, j + 6, i + 6]);
        }
        let m = PolyMesh::from_faces("L", v, &faces);
        let topo = m.topology(None).unwrap();
        let s = subdivide(&m, &topo, 3);
        assert_eq!(s.euler_characteristic(), 2);
        assert!(s.topology(None).is_ok());
        let vol = MassProps::of(&s).volume;
        assert!(vol > 0.0 && vol < 3.0);
    }
}
