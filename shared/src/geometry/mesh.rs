//! Polygon meshes and their half-edge topology.
//!
//! A [`PolyMesh`] stores vertices and n-gon faces in compressed rows (`face_start`,
//! `face_verts`), counter-clockwise seen from outside. [`PolyMesh::topology`] checks that the mesh
//! is a closed, consistently oriented 2-manifold and returns the [`Topology`] (half-edge twins)
//! that subdivision, hulls and duals walk on.
//!
//! Half-edge `h` is face corner `h` of `face_verts`: it runs from `face_verts[h]` to the next
//! corner of the same face.

use crate::math::Vec3;
use thiserror::Error;

/// `key=value` attributes of one object, in the order they were set (carried in the OBJ stream as
/// `#@ key=value` lines; see `docs/formats/obj-stream.md`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Attrs(pub Vec<(String, String)>);

impl Attrs {
    /// The value of `key`, if set.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.0
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// Sets `key` to `value`, replacing an earlier value in place.
    pub fn set(&mut self, key: &str, value: impl ToString) {
        let value = value.to_string();
        match self.0.iter_mut().find(|(k, _)| k == key) {
            Some(slot) => slot.1 = value,
            None => self.0.push((key.to_string(), value)),
        }
    }
}

/// A polygon mesh: named, with attributes, vertices and n-gon faces.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PolyMesh {
    pub name: String,
    pub attrs: Attrs,
    pub vertices: Vec<Vec3>,
    /// Face `f` is `face_verts[face_start[f]..face_start[f + 1]]`; `face_start` has one more
    /// entry than there are faces and starts with 0.
    pub face_start: Vec<u32>,
    pub face_verts: Vec<u32>,
}

/// Why a mesh is not a closed, consistently oriented 2-manifold. `line` is the OBJ line of the
/// face concerned where the caller supplied face lines. `face`, `other` and `BadIndex::vertex`
/// and `RepeatedVertex::vertex` are 0-based; `a`, `b` and the vertex of
/// `UnusedVertex`/`NonManifoldVertex` are 1-based. Its `Display` numbers everything from 1
/// within the object, as OBJ does; [`MeshError::counted_from`] numbers from another base (0 for
/// the JSON state, whose face lists count from 0).
#[derive(Debug, Error, PartialEq)]
#[error("{}", self.counted_from(1))]
pub enum MeshError {
    Empty,
    DegenerateFace {
        face: usize,
        line: Option<u64>,
        count: usize,
    },
    RepeatedVertex {
        face: usize,
        line: Option<u64>,
        vertex: u32,
    },
    BadIndex {
        face: usize,
        line: Option<u64>,
        vertex: u32,
    },
    BoundaryEdge {
        face: usize,
        line: Option<u64>,
        a: u32,
        b: u32,
    },
    NonManifoldEdge {
        face: usize,
        line: Option<u64>,
        a: u32,
        b: u32,
        count: usize,
    },
    FlippedFace {
        face: usize,
        line: Option<u64>,
        other: usize,
        other_line: Option<u64>,
        a: u32,
        b: u32,
    },
    UnusedVertex {
        vertex: u32,
    },
    NonManifoldVertex {
        vertex: u32,
    },
}

impl MeshError {
    /// The message, faces and vertices numbered from `base` (1 as OBJ counts, 0 as the JSON
    /// state does).
    pub fn counted_from(&self, base: u64) -> String {
        // From 0-based and from 1-based indices.
        let z = |i: usize| i as u64 + base;
        let o = |i: u32| u64::from(i) + base - 1;
        match self {
            MeshError::Empty => "the mesh has no faces".into(),
            MeshError::DegenerateFace { face, line, count } => format!(
                "face {}{} has {count} distinct vertices; a face needs at least 3",
                z(*face),
                at(*line)
            ),
            MeshError::RepeatedVertex { face, line, vertex } => format!(
                "face {}{} repeats vertex {}; a face goes round distinct vertices",
                z(*face),
                at(*line),
                z(*vertex as usize)
            ),
            MeshError::BadIndex { face, line, vertex } => format!(
                "face {}{} uses vertex {} which does not exist",
                z(*face),
                at(*line),
                z(*vertex as usize)
            ),
            MeshError::BoundaryEdge { face, line, a, b } => format!(
                "edge {}-{} of face {}{} has no neighbour: the mesh is open (boundary edge)",
                o(*a),
                o(*b),
                z(*face),
                at(*line)
            ),
            MeshError::NonManifoldEdge { face, line, a, b, count } => format!(
                "edge {}-{} is shared by {count} faces (first: face {}{}); a manifold edge has exactly 2",
                o(*a),
                o(*b),
                z(*face),
                at(*line)
            ),
            MeshError::FlippedFace { face, line, other, other_line, a, b } => format!(
                "face {}{} runs edge {}-{} in the same direction as face {}{}: one of them is flipped (inconsistent orientation)",
                z(*face),
                at(*line),
                o(*a),
                o(*b),
                z(*other),
                at(*other_line)
            ),
            MeshError::UnusedVertex { vertex } => {
                format!("vertex {} is not used by any face", o(*vertex))
            }
            MeshError::NonManifoldVertex { vertex } => format!(
                "vertex {} joins two or more separate fans of faces (non-manifold vertex)",
                o(*vertex)
            ),
        }
    }
}

fn at(line: Option<u64>) -> String {
    line.map_or(String::new(), |l| format!(" (line {l})"))
}

/// Half-edge adjacency of a closed, consistently oriented 2-manifold polygon mesh.
#[derive(Clone, Debug)]
pub struct Topology {
    /// The opposite half-edge of each half-edge.
    pub twin: Vec<u32>,
    /// The face of each half-edge.
    pub face_of: Vec<u32>,
    /// One outgoing half-edge of each vertex.
    pub vert_out: Vec<u32>,
}

impl PolyMesh {
    /// An empty mesh with a name.
    pub fn named(name: impl Into<String>) -> Self {
        PolyMesh {
            name: name.into(),
            face_start: vec![0],
            ..Default::default()
        }
    }

    /// A mesh from vertices and faces given as index lists.
    pub fn from_faces(name: impl Into<String>, vertices: Vec<Vec3>, faces: &[Vec<u32>]) -> Self {
        let mut m = PolyMesh::named(name);
        m.vertices = vertices;
        for f in faces {
            m.push_face(f);
        }
        m
    }

    /// Appends a face.
    pub fn push_face(&mut self, verts: &[u32]) {
        if self.face_start.is_empty() {
            self.face_start.push(0);
        }
        self.face_verts.extend_from_slice(verts);
        self.face_start.push(self.face_verts.len() as u32);
    }

    /// Number of faces.
    pub fn face_count(&self) -> usize {
        self.face_start.len().saturating_sub(1)
    }

    /// The vertex indices of face `f`.
    pub fn face(&self, f: usize) -> &[u32] {
        &self.face_verts[self.face_start[f] as usize..self.face_start[f + 1] as usize]
    }

    /// Iterates over the faces as index slices.
    pub fn faces(&self) -> impl Iterator<Item = &[u32]> + '_ {
        (0..self.face_count()).map(move |f| self.face(f))
    }

    /// The mean of a face's vertices (the fan centre used for area, volume and rendering).
    pub fn face_centroid(&self, f: usize) -> Vec3 {
        let idx = self.face(f);
        idx.iter().map(|&i| self.vertices[i as usize]).sum::<Vec3>() / idx.len() as f64
    }

    /// The half-edge after `h` in its face.
    #[inline]
    pub fn next(&self, h: usize, face: usize) -> usize {
        if h + 1 == self.face_start[face + 1] as usize {
            self.face_start[face] as usize
        } else {
            h + 1
        }
    }

    /// The half-edge before `h` in its face.
    #[inline]
    pub fn prev(&self, h: usize, face: usize) -> usize {
        if h == self.face_start[face] as usize {
            self.face_start[face + 1] as usize - 1
        } else {
            h - 1
        }
    }

    /// Number of undirected edges, counting each face side once per pair (closed meshes only).
    pub fn edge_count(&self) -> usize {
        self.face_verts.len() / 2
    }

    /// V - E + F (2 for a closed sphere-like mesh).
    pub fn euler_characteristic(&self) -> i64 {
        self.vertices.len() as i64 - self.edge_count() as i64 + self.face_count() as i64
    }

    /// Checks that the mesh is a closed, consistently oriented 2-manifold in which every vertex
    /// is used, and returns its half-edge topology. `face_lines` (one OBJ line per face) lets the
    /// errors name the line.
    pub fn topology(&self, face_lines: Option<&[u64]>) -> Result<Topology, MeshError> {
        let line = |f: usize| face_lines.and_then(|l| l.get(f).copied());
        let nf = self.face_count();
        if nf == 0 {
            return Err(MeshError::Empty);
        }
        let nh = self.face_verts.len();
        let nv = self.vertices.len();
        let mut face_of = vec![0u32; nh];
        for f in 0..nf {
            let idx = self.face(f);
            for &v in idx {
                if v as usize >= nv {
                    return Err(MeshError::BadIndex {
                        face: f,
                        line: line(f),
                        vertex: v,
                    });
                }
            }
            // A face needs three distinct corners and no corner repeated.
            let mut sorted: Vec<u32> = idx.to_vec();
            sorted.sort_unstable();
            let repeated = sorted.windows(2).find(|w| w[0] == w[1]).map(|w| w[0]);
            sorted.dedup();
            if sorted.len() < 3 {
                return Err(MeshError::DegenerateFace {
                    face: f,
                    line: line(f),
                    count: sorted.len(),
                });
            }
            if let Some(vertex) = repeated {
                return Err(MeshError::RepeatedVertex {
                    face: f,
                    line: line(f),
                    vertex,
                });
            }
            for h in self.face_start[f]..self.face_start[f + 1] {
                face_of[h as usize] = f as u32;
            }
        }
        // Pair half-edges by their undirected edge: sort by (min, max) key.
        let dest = |h: usize| self.face_verts[self.next(h, face_of[h] as usize)];
        let mut keyed: Vec<(u64, u32)> = (0..nh)
            .map(|h| {
                let (a, b) = (self.face_verts[h], dest(h));
                let (lo, hi) = if a < b { (a, b) } else { (b, a) };
                (((lo as u64) << 32) | hi as u64, h as u32)
            })
            .collect();
        keyed.sort_unstable();
        let mut twin = vec![u32::MAX; nh];
        let mut i = 0;
        while i < nh {
            let mut j = i + 1;
            while j < nh && keyed[j].0 == keyed[i].0 {
                j += 1;
            }
            let h0 = keyed[i].1 as usize;
            let (a, b) = (self.face_verts[h0], dest(h0));
            let f0 = face_of[h0] as usize;
            match j - i {
                1 => {
                    return Err(MeshError::BoundaryEdge {
                        face: f0,
                        line: line(f0),
                        a: a + 1,
                        b: b + 1,
                    })
                }
                2 => {
                    let h1 = keyed[i + 1].1 as usize;
                    if self.face_verts[h1] == a {
                        let f1 = face_of[h1] as usize;
                        return Err(MeshError::FlippedFace {
                            face: f1.max(f0),
                            line: line(f1.max(f0)),
                            other: f1.min(f0),
                            other_line: line(f1.min(f0)),
                            a: a + 1,
                            b: b + 1,
                        });
                    }
                    twin[h0] = h1 as u32;
                    twin[h1] = h0 as u32;
                }
                count => {
                    return Err(MeshError::NonManifoldEdge {
                        face: f0,
                        line: line(f0),
                        a: a + 1,
                        b: b + 1,
                        count,
                    })
                }
            }
            i = j;
        }
        // Every vertex used, and its faces form one fan.
        let mut vert_out = vec![u32::MAX; nv];
        let mut degree = vec![0u32; nv];
        for h in 0..nh {
            let v = self.face_verts[h] as usize;
            degree[v] += 1;
            if vert_out[v] == u32::MAX {
                vert_out[v] = h as u32;
            }
        }
        let topo = Topology {
            twin,
            face_of,
            vert_out,
        };
        for (v, &deg) in degree.iter().enumerate() {
            if deg == 0 {
                return Err(MeshError::UnusedVertex {
                    vertex: v as u32 + 1,
                });
            }
            if self.ring(&topo, v).count() != deg as usize {
                return Err(MeshError::NonManifoldVertex {
                    vertex: v as u32 + 1,
                });
            }
        }
        Ok(topo)
    }

    /// The outgoing half-edges of vertex `v`, counter-clockwise seen from outside (each belongs
    /// to the next face around `v`). Requires a topology from [`PolyMesh::topology`].
    pub fn ring<'a>(&'a self, topo: &'a Topology, v: usize) -> impl Iterator<Item = usize> + 'a {
        let start = topo.vert_out[v] as usize;
        let mut h = Some(start);
        std::iter::from_fn(move || {
            let cur = h?;
            let prev = self.prev(cur, topo.face_of[cur] as usize);
            let nxt = topo.twin[prev] as usize;
            h = (nxt != start).then_some(nxt);
            Some(cur)
        })
        .take(self.face_verts.len())
    }
}

/// A cube with half-width `h` centred at the origin (6 quads, outward).
pub fn cube(h: f64) -> PolyMesh {
    let mut m = cuboid(Vec3::new(h, h, h));
    m.name = "cube".into();
    m
}

/// A box with half-widths `h` centred at the origin (6 quads, outward).
pub fn cuboid(h: Vec3) -> PolyMesh {
    let v = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 1 { h.x } else { -h.x },
                if i & 2 == 2 { h.y } else { -h.y },
                if i & 4 == 4 { h.z } else { -h.z },
            )
        })
        .collect();
    let faces = [
        vec![0, 2, 3, 1],
        vec![4, 5, 7, 6],
        vec![0, 1, 5, 4],
        vec![2, 6, 7, 3],
        vec![0, 4, 6, 2],
        vec![1, 3, 7, 5],
    ];
    PolyMesh::from_faces("cuboid", v, &faces)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cube_is_a_closed_oriented_manifold() {
        let c = cube(1.0);
        let topo = c.topology(None).unwrap();
        assert_eq!(c.euler_characteristic(), 2);
        for v in 0..8 {
            assert_eq!(c.ring(&topo, v).count(), 3);
        }
    }

    #[test]
    fn flipped_face_is_named() {
        let mut c = cube(1.0);
        c.face_verts[4..8].reverse();
        let lines: Vec<u64> = (10..16).collect();
        let err = c.topology(Some(&lines)).unwrap_err();
        assert!(matches!(err, MeshError::FlippedFace { .. }), "{err}");
        assert!(err.to_string().contains("line 11"), "{err}");
    }

    /// Messages number faces and vertices from 1 as OBJ does, or from 0 as the JSON state
    /// does, for the same error.
    #[test]
    fn messages_count_from_the_format_s_base() {
        let mut c = cube(1.0);
        c.face_verts[5] = 9; // face 1 (0-based) names vertex 9 of 8
        let err = c.topology(None).unwrap_err();
        assert_eq!(
            err.to_string(),
            "face 2 uses vertex 10 which does not exist"
        );
        assert_eq!(
            err.counted_from(0),
            "face 1 uses vertex 9 which does not exist"
        );
        let mut c = cube(1.0);
        c.vertices.push(Vec3::zeros());
        let err = c.topology(None).unwrap_err();
        assert_eq!(err.to_string(), "vertex 9 is not used by any face");
        assert_eq!(err.counted_from(0), "vertex 8 is not used by any face");
    }

    #[test]
    fn open_mesh_is_rejected() {
        let c = cube(1.0);
        let faces: Vec<Vec<u32>> = c.faces().take(5).map(|f| f.to_vec()).collect();
        let open = PolyMesh::from_faces("open", c.vertices.clone(), &faces);
        assert!(matches!(
            open.topology(None),
            Err(MeshError::BoundaryEdge { .. })
        ));
    }

    #[test]
    fn edge_shared_by_three_faces_is_rejected() {
        let mut c = cube(1.0);
        c.vertices.push(Vec3::new(0.0, -3.0, 0.0));
        c.push_face(&[0, 1, 8]);
        assert!(matches!(
            c.topology(None),
            Err(MeshError::NonManifoldEdge { count: 3, .. })
        ));
    }

    #[test]
    fn degenerate_face_and_bad_index_are_rejected() {
        let mut c = cube(1.0);
        c.push_face(&[0, 0, 1]);
        assert!(matches!(
            c.topology(None),
            Err(MeshError::DegenerateFace { .. })
        ));
        let mut c = cube(1.0);
        c.face_verts[0] = 99;
        assert!(matches!(
            c.topology(None),
            Err(MeshError::BadIndex { vertex: 99, .. })
        ));
    }

    #[test]
    fn two_cubes_sharing_a_vertex_are_non_manifold() {
        let a = cube(1.0);
        let mut m = a.clone();
        // A second cube touching the first only at vertex 7 = (1,1,1).
        let off = Vec3::new(2.0, 2.0, 2.0);
        let base = m.vertices.len() as u32;
        m.vertices.extend(a.vertices.iter().map(|v| v + off));
        for f in a.faces() {
            let g: Vec<u32> = f
                .iter()
                .map(|&i| if i == 0 { 7 } else { i + base })
                .collect();
            m.push_face(&g);
        }
        // Vertex 7 is checked before the unused vertex `base`, so the pinch is what is reported.
        let err = m.topology(None).unwrap_err();
        assert_eq!(err, MeshError::NonManifoldVertex { vertex: 8 });
    }
}
