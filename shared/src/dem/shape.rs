//! Rigid convex shapes for the DEM: the convex hull of a mesh, in its principal frame.
//!
//! A [`Shape`] is a template at unit scale and unit density: vertices and outward face planes
//! in the principal frame (origin at the centroid, axes along the principal axes of inertia,
//! moments ascending), volume, principal moments, bounding radius, and where that frame sits in
//! the source mesh's frame. A body scales it uniformly: lengths by `s`, volume by `s^3`, moments
//! per unit density by `s^5`.

use crate::geometry::hull::{self, HullError};
use crate::geometry::mass::MassProps;
use crate::geometry::mesh::PolyMesh;
use crate::geometry::subdiv::subdivide;
use crate::math::{Mat3, Vec3};
use nalgebra::{Rotation3, SymmetricEigen, UnitQuaternion};
use thiserror::Error;

/// The most vertices a shape may have: the engine's structures for a shape grow faster than its
/// vertices (the paper's Ab_3 shapes have about 760; `simplify` cuts a hull to a budget).
pub const MAX_VERTICES: usize = 50_000;

/// Why a mesh gives no usable shape.
#[derive(Debug, Error, PartialEq)]
pub enum ShapeError {
    #[error("shape '{0}': {1}")]
    Hull(String, HullError),
    #[error("shape '{0}' has {1} vertices, more than {MAX_VERTICES} (cut it with simplify --vertices N)")]
    TooManyVertices(String, usize),
    #[error("shape '{0}' has no volume ({1:e})")]
    NoVolume(String, f64),
    #[error("shape '{0}' is too large for its mass properties in floating point (volume {1:e}): scale it down")]
    Overflow(String, f64),
    #[error("shape '{0}' is too slender for its inertia in floating point (principal moments {1:e}, {2:e}, {3:e}; the least must be at least {MIN_MOMENT_RATIO:e} of the largest, a rod of about 1:45 000)")]
    Slender(String, f64, f64, f64),
}

/// The least principal moment over the largest that a shape may have: a rod whose length is
/// about 45 000 times its width. The rounding of a more slender shape's inertia tensor is of
/// the order of its least moment, so its principal frame and moments are noise.
pub const MIN_MOMENT_RATIO: f64 = 1e-9;

/// A convex template in its principal frame, unit scale and density.
#[derive(Clone, Debug)]
pub struct Shape {
    pub name: String,
    pub vertices: Vec<Vec3>,
    pub face_start: Vec<u32>,
    pub face_verts: Vec<u32>,
    /// The faces around each vertex (compressed rows: see [`incidence`]).
    pub vertex_face_start: Vec<u32>,
    pub vertex_faces: Vec<u32>,
    /// Unit outward normal and offset of each face: `n . x <= d` inside.
    pub normals: Vec<Vec3>,
    pub offsets: Vec<f64>,
    pub volume: f64,
    /// Principal moments of inertia per unit density, ascending.
    pub moments: Vec3,
    /// Largest vertex distance from the centroid.
    pub radius: f64,
    /// The source mesh's centroid and the rotation from the principal frame to the mesh frame.
    pub centroid_in_mesh: Vec3,
    pub frame_in_mesh: UnitQuaternion<f64>,
    /// For shapes of many vertices: the graph to find extreme vertices by hill climbing.
    pub climb: Option<Climb>,
}

/// A shape made from another ([`Shape::abraded`], [`Shape::simplified`]), with where its
/// principal frame sits in the other's: centroid and rotation.
pub type Remade = (Shape, Vec3, UnitQuaternion<f64>);

/// Below this many vertices the narrow phase scans them all (cheaper than climbing).
pub const CLIMB_MIN: usize = 48;

/// The vertex graph of a large convex shape, for finding the vertices above a plane without
/// scanning them all. Neighbours are the other vertices of the faces around a vertex (for a
/// triangulated hull, its edge neighbours; a vertex lying inside a face's edge still reaches the
/// face's corners). A linear function on a convex polytope has no local maximum on this graph
/// but its maximum, and the vertices above any level stay connected through it.
#[derive(Clone, Debug)]
pub struct Climb {
    neighbor_start: Vec<u32>,
    neighbors: Vec<u32>,
    /// Where a climb starts: for each cell of a cube map of directions (shape frame,
    /// [`START_CELLS`] x [`START_CELLS`] cells on each of the six faces), the vertex farthest
    /// along the cell's central direction. A climb from there is a step or two.
    starts: Vec<u32>,
    /// The face planes by columns (normals' x, y, z and the offsets), for scans that the
    /// compiler can vectorize, grouped by the cube-map cell of their normals
    /// ([`Climb::clearances`]): group `g` is `groups[g].start..groups[g + 1].start`, its faces
    /// `group_faces[..]`.
    planes: [Vec<f64>; 4],
    group_faces: Vec<u32>,
    groups: Vec<PlaneGroup>,
    /// Per face, a sphere holding its polygon (shape frame): the vertices' mean and the
    /// largest distance from it.
    pub face_spheres: Vec<(Vec3, f64)>,
}

/// Face planes whose normals lie in a cone: a bound on how far inside them all a point is.
#[derive(Clone, Debug)]
struct PlaneGroup {
    /// Where the group's planes start in [`Climb`]'s columns.
    start: u32,
    /// The cone: its axis (unit) and the cosine and sine of its half-angle.
    axis: Vec3,
    cos: f64,
    sin: f64,
    /// The least offset of the group's planes (shape frame).
    offset: f64,
}

impl PlaneGroup {
    /// A lower bound on `scale d_f - n_f . p` over the group's planes: the least offset less
    /// the most any unit normal in the cone reaches along `p`, less a round-off allowance
    /// far above that of the distances themselves.
    fn least_inside(&self, p: &Vec3, norm: f64, scale: f64) -> f64 {
        let along = self.axis.dot(p);
        let reach = if along >= norm * self.cos {
            norm
        } else {
            let across = (norm * norm - along * along).max(0.0).sqrt();
            along * self.cos + across * self.sin
        };
        let d = self.offset * scale;
        d - reach - 1e-12 * (d.abs() + norm)
    }
}

/// Cells along each edge of a face of [`Climb`]'s cube map of directions.
pub const START_CELLS: usize = 4;

/// The cube-map cell of direction `d` (shape frame): face by the largest component, then the
/// other two components over it.
fn start_cell(d: &Vec3) -> usize {
    let a = d.iamax();
    let (u, v) = ((a + 1) % 3, (a + 2) % 3);
    let face = 2 * a + usize::from(d[a] < 0.0);
    let m = d[a].abs();
    let cell = |x: f64| {
        let c = ((x / m + 1.0) * 0.5 * START_CELLS as f64).floor();
        (c.max(0.0) as usize).min(START_CELLS - 1) // NaN (a zero d) goes to 0 too
    };
    (face * START_CELLS + cell(d[u])) * START_CELLS + cell(d[v])
}

impl Climb {
    /// The graph of a shape with `vertices` and faces (compressed rows, with the faces around
    /// each vertex, and their planes `n . x <= d`), or `None` below [`CLIMB_MIN`] vertices.
    pub fn of(
        vertices: &[Vec3],
        face_start: &[u32],
        face_verts: &[u32],
        vertex_face_start: &[u32],
        vertex_faces: &[u32],
        (normals, offsets): (&[Vec3], &[f64]),
    ) -> Option<Climb> {
        if vertices.len() < CLIMB_MIN {
            return None;
        }
        let mut neighbor_start = vec![0u32];
        let mut neighbors = Vec::new();
        let mut around = Vec::new();
        for v in 0..vertices.len() {
            around.clear();
            let faces = vertex_face_start
                .get(v..v + 2)
                .map_or(&[][..], |r| &vertex_faces[r[0] as usize..r[1] as usize]);
            for &f in faces {
                let f = f as usize;
                let corners = &face_verts[face_start[f] as usize..face_start[f + 1] as usize];
                around.extend(corners.iter().copied().filter(|&w| w as usize != v));
            }
            around.sort_unstable();
            around.dedup();
            neighbors.extend_from_slice(&around);
            neighbor_start.push(neighbors.len() as u32);
        }
        let n = START_CELLS as f64;
        let starts = (0..6 * START_CELLS * START_CELLS)
            .map(|k| {
                let (face, i, j) = (
                    k / (START_CELLS * START_CELLS),
                    (k / START_CELLS) % START_CELLS,
                    k % START_CELLS,
                );
                let (a, sign) = (face / 2, if face % 2 == 0 { 1.0 } else { -1.0 });
                let mut d = Vec3::zeros();
                d[a] = sign;
                d[(a + 1) % 3] = -1.0 + (2 * i + 1) as f64 / n;
                d[(a + 2) % 3] = -1.0 + (2 * j + 1) as f64 / n;
                (0..vertices.len())
                    .max_by(|&p, &q| d.dot(&vertices[p]).total_cmp(&d.dot(&vertices[q])))
                    .unwrap_or(0) as u32
            })
            .collect();
        // Planes grouped by the cell of their normal, in face order within a group.
        let mut group_faces: Vec<u32> = (0..normals.len() as u32).collect();
        group_faces.sort_by_key(|&f| start_cell(&normals[f as usize]));
        let groups: Vec<PlaneGroup> = group_faces
            .chunk_by(|&f, &g| start_cell(&normals[f as usize]) == start_cell(&normals[g as usize]))
            .scan(0u32, |start, members| {
                let normal = |&f: &u32| normals[f as usize];
                let axis = members.iter().map(normal).sum::<Vec3>().normalize();
                // Padded: the cone holds every member's normal with room for round-off.
                let cos = (members.iter().map(|f| axis.dot(&normal(f))))
                    .fold(1.0f64, f64::min)
                    .clamp(-1.0, 1.0)
                    - 1e-9;
                let group = PlaneGroup {
                    start: *start,
                    axis,
                    cos,
                    sin: (1.0 - cos * cos).max(0.0).sqrt(),
                    offset: (members.iter().map(|&f| offsets[f as usize]))
                        .fold(f64::INFINITY, f64::min),
                };
                *start += members.len() as u32;
                Some(group)
            })
            .collect();
        let column = |k: usize| {
            (group_faces.iter())
                .map(|&f| normals[f as usize][k])
                .collect()
        };
        let offsets: Vec<f64> = group_faces.iter().map(|&f| offsets[f as usize]).collect();
        let face_spheres = (face_start.windows(2))
            .map(|r| {
                let corners = &face_verts[r[0] as usize..r[1] as usize];
                let at = |&i: &u32| vertices[i as usize];
                let mean = corners.iter().map(at).sum::<Vec3>() / corners.len() as f64;
                let radius = (corners.iter().map(|i| (at(i) - mean).norm())).fold(0.0, f64::max);
                (mean, radius)
            })
            .collect();
        Some(Climb {
            neighbor_start,
            neighbors,
            starts,
            planes: [column(0), column(1), column(2), offsets],
            group_faces,
            groups,
            face_spheres,
        })
    }

    /// How far the point `local` (shape frame) lies inside the face planes of the shape at
    /// `scale`, `scale d_f - n_f . local` in world units (a body's offsets scale with it, its
    /// normals do not): calls `near(f)` for each face `f` it is less than `limit` inside (in
    /// no particular order), and returns a lower bound on the least of the others, at least
    /// `limit` (infinite when there are none). A group of planes whose bound
    /// ([`PlaneGroup::least_inside`]) is at least `limit` is not scanned, its bound standing for
    /// its planes: on an Ab_3 hull, for a point near its surface, most of its ~1 500 planes face
    /// away.
    pub fn clearances(
        &self,
        local: &Vec3,
        scale: f64,
        limit: f64,
        mut near: impl FnMut(u32, f64),
    ) -> f64 {
        let [x, y, z, d] = &self.planes;
        let norm = local.norm();
        let end = |g: usize| self.groups.get(g + 1).map_or(d.len(), |n| n.start as usize);
        let inside = |k: usize| d[k] * scale - (x[k] * local.x + y[k] * local.y + z[k] * local.z);
        // The groups that may hold near planes are scanned; every other plane is at least its
        // group's bound inside, so the least of those bounds and of the scanned far planes is a
        // lower bound on the clearance (scanning those groups for the exact least too was a
        // quarter of finding an Ab_3 structure, for a clearance that only says when to look
        // again).
        let mut far = f64::INFINITY;
        for (g, group) in self.groups.iter().enumerate() {
            let bound = group.least_inside(local, norm, scale);
            if bound >= limit {
                far = far.min(bound);
                continue;
            }
            for k in group.start as usize..end(g) {
                let v = inside(k);
                if v < limit {
                    near(self.group_faces[k], v);
                } else {
                    far = far.min(v);
                }
            }
        }
        far
    }

    /// A vertex near the top along `d` (world) for a body turned by `rot`: where to climb from.
    pub fn start(&self, rot: &Rotation3<f64>, d: &Vec3) -> usize {
        self.starts[start_cell(&rot.inverse_transform_vector(d))] as usize
    }

    /// Steepest ascent of `height` over the graph from vertex `from`: the first vertex with no
    /// higher neighbour (on a convex polytope, for a linear height, a top), and its height.
    pub fn ascend(&self, from: usize, mut height: impl FnMut(usize) -> f64) -> (usize, f64) {
        let (mut at, mut top) = (from, height(from));
        loop {
            let mut next = at;
            for &w in self.neighbors(at) {
                let h = height(w as usize);
                if h > top {
                    (top, next) = (h, w as usize);
                }
            }
            if next == at {
                return (at, top);
            }
            at = next;
        }
    }

    /// The vertices next to `v`.
    pub fn neighbors(&self, v: usize) -> &[u32] {
        &self.neighbors[self.neighbor_start[v] as usize..self.neighbor_start[v + 1] as usize]
    }
}

impl Shape {
    /// The convex hull of `mesh`'s vertices, moved to its principal frame.
    pub fn from_mesh(mesh: &PolyMesh) -> Result<Shape, ShapeError> {
        if mesh.vertices.len() > MAX_VERTICES {
            return Err(ShapeError::TooManyVertices(
                crate::text::excerpt(&mesh.name),
                mesh.vertices.len(),
            ));
        }
        let h = hull::convex_hull(&mesh.vertices)
            .map_err(|e| ShapeError::Hull(mesh.name.clone(), e))?;
        let props = MassProps::of(&h.mesh);
        if props.volume <= 0.0 {
            return Err(ShapeError::NoVolume(mesh.name.clone(), props.volume));
        }
        // Coordinates beyond ~1e100 overflow the inertia (a size to the fifth power), and the
        // principal frame of an infinite tensor is not a rotation.
        if !(props.volume.is_finite() && props.inertia.iter().all(|x| x.is_finite())) {
            return Err(ShapeError::Overflow(mesh.name.clone(), props.volume));
        }
        let (rot, moments) = principal_axes(&props.inertia);
        if !(rot.iter().all(|x| x.is_finite()) && moments.iter().all(|x| x.is_finite())) {
            return Err(ShapeError::Overflow(mesh.name.clone(), props.volume));
        }
        if !(moments[0] >= MIN_MOMENT_RATIO * moments[2]) {
            let [a, b, c] = [moments[0], moments[1], moments[2]];
            return Err(ShapeError::Slender(mesh.name.clone(), a, b, c));
        }
        let vertices: Vec<Vec3> = h
            .mesh
            .vertices
            .iter()
            .map(|v| rot.transpose() * (v - props.centroid))
            .collect();
        let normals: Vec<Vec3> = h.planes.iter().map(|(n, _)| rot.transpose() * n).collect();
        let offsets: Vec<f64> = h
            .planes
            .iter()
            .map(|(n, d)| d - n.dot(&props.centroid))
            .collect();
        let radius = vertices.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let frame = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rot));
        let (vertex_face_start, vertex_faces) = incidence(&h.mesh.face_start, &h.mesh.face_verts);
        let climb = Climb::of(
            &vertices,
            &h.mesh.face_start,
            &h.mesh.face_verts,
            &vertex_face_start,
            &vertex_faces,
            (&normals, &offsets),
        );
        Ok(Shape {
            name: mesh.name.clone(),
            vertices,
            face_start: h.mesh.face_start,
            face_verts: h.mesh.face_verts,
            vertex_face_start,
            vertex_faces,
            normals,
            offsets,
            volume: props.volume,
            moments,
            radius,
            centroid_in_mesh: props.centroid,
            frame_in_mesh: frame,
            climb,
        })
    }

    /// The paper's abrasion of this shape (Ab_`levels` from it): the convex hull of its surface
    /// subdivided `levels` times by Catmull-Clark, which lies inside it. See [`Shape::remade`]
    /// for what is returned.
    pub fn abraded(&self, levels: u32) -> Result<Remade, String> {
        self.remade(|mesh| {
            let topo = mesh.topology(None).map_err(|e| e.to_string())?;
            Ok(subdivide(mesh, &topo, levels))
        })
    }

    /// This shape cut to `budget` vertices ([`hull::simplified_hull`], inside it): the
    /// engine's side of the `simplify` tool. See [`Shape::remade`] for what is returned.
    pub fn simplified(&self, budget: usize) -> Result<Remade, String> {
        self.remade(|mesh| {
            Ok(hull::simplified_hull(&mesh.vertices, budget)
                .map_err(|e| e.to_string())?
                .mesh)
        })
    }

    /// The shape of the hull of `make(this shape's mesh)` (mesh in this shape's frame). The new
    /// shape has its own principal frame; also returned is where that frame sits in this
    /// shape's frame (centroid and rotation), to keep a body in place. `centroid_in_mesh` and
    /// `frame_in_mesh` still refer to the source mesh.
    fn remade(
        &self,
        make: impl FnOnce(&PolyMesh) -> Result<PolyMesh, String>,
    ) -> Result<Remade, String> {
        let mesh = self.posed_mesh(&Vec3::zeros(), &UnitQuaternion::identity(), 1.0);
        let mut made = make(&mesh).map_err(|e| format!("shape '{}': {e}", self.name))?;
        made.name = self.name.clone();
        let mut out = Shape::from_mesh(&made).map_err(|e| e.to_string())?;
        let (offset, turn) = (out.centroid_in_mesh, out.frame_in_mesh);
        out.centroid_in_mesh = self.centroid_in_mesh + self.frame_in_mesh * offset;
        out.frame_in_mesh = self.frame_in_mesh * turn;
        Ok((out, offset, turn))
    }

    /// The shape as a mesh named after it, scaled by `scale`, rotated by `rot` and moved to
    /// `pos` (the shape's own frame for the identity pose).
    pub fn posed_mesh(&self, pos: &Vec3, rot: &UnitQuaternion<f64>, scale: f64) -> PolyMesh {
        PolyMesh {
            name: self.name.clone(),
            vertices: (self.vertices.iter())
                .map(|v| pos + rot * (v * scale))
                .collect(),
            face_start: self.face_start.clone(),
            face_verts: self.face_verts.clone(),
            ..Default::default()
        }
    }

    /// The largest top eigenvalue over the vertices `v` of `M^-1/2 (|v|^2 - v v^T) M^-1/2`, `M`
    /// the principal moments per unit density: how fast a spring at a vertex can turn the body
    /// (`omega^2` per unit stiffness, at unit scale and density; see
    /// [`crate::dem::world::World::critical_dt`]). At most `radius^2 / moments.min()`, and equal to
    /// it for equal moments.
    pub fn rotation_rate(&self) -> f64 {
        let d = Mat3::from_diagonal(&self.moments.map(|m| 1.0 / m.sqrt()));
        self.vertices
            .iter()
            .map(|v| {
                let a = d * (Mat3::identity() * v.norm_squared() - v * v.transpose()) * d;
                SymmetricEigen::new(a).eigenvalues.max()
            })
            .fold(0.0, f64::max)
    }

    /// Number of faces.
    pub fn face_count(&self) -> usize {
        self.face_start.len() - 1
    }

    /// Vertex indices of face `f`.
    pub fn face(&self, f: usize) -> &[u32] {
        &self.face_verts[self.face_start[f] as usize..self.face_start[f + 1] as usize]
    }

    /// Faces around vertex `v`.
    pub fn faces_at(&self, v: usize) -> &[u32] {
        &self.vertex_faces
            [self.vertex_face_start[v] as usize..self.vertex_face_start[v + 1] as usize]
    }

    /// The shape scaled by `scale`, rotated by `rot` and moved to `pos`, in world coordinates.
    pub fn posed(&self, pos: &Vec3, rot: &UnitQuaternion<f64>, scale: f64) -> Posed {
        let mut out = Posed::default();
        self.pose_into(pos, rot, scale, &mut out);
        out
    }

    /// [`Shape::posed`] into `out`, reusing its buffers (same values).
    pub fn pose_into(&self, pos: &Vec3, rot: &UnitQuaternion<f64>, scale: f64, out: &mut Posed) {
        self.pose_with(pos, rot, scale, out, true, true);
    }

    /// [`Shape::pose_into`] for the contact search. A large shape ([`Shape::climb`]) leaves its
    /// face planes to [`Posed::plane`], since a contact needs only the few near it (an Ab_3 hull
    /// has about 1500; posing them all was a fifth of a step). With `lazy` it also leaves its
    /// vertices to [`Posed::vertex`] (a contact reads a few dozen of 758), and its box comes
    /// from climbing to its six extreme vertices, padded for a climb that stops short by
    /// round-off (the box only culls: a larger one changes no contact, though the pairs'
    /// margins follow its size). That pays while the shapes' own vertices stay in cache: see
    /// the world's `LAZY_HULLS_MAX_BYTES`.
    pub fn pose_for_contacts(
        &self,
        pos: &Vec3,
        rot: &UnitQuaternion<f64>,
        scale: f64,
        out: &mut Posed,
        lazy: bool,
    ) {
        let small = self.climb.is_none();
        let Some(c) = self.climb.as_ref().filter(|_| lazy) else {
            return self.pose_with(pos, rot, scale, out, true, small);
        };
        self.pose_with(pos, rot, scale, out, false, false);
        let pad = BOX_PAD_REL * self.radius * scale;
        let world = |i: usize| out.vertex(self, i);
        let (mut lo, mut hi) = (Vec3::zeros(), Vec3::zeros());
        // Each climb starts from where the last pose's ended (a body turns little in a step,
        // so its extreme vertices mostly stay), else from the cube map. A climb ends at the
        // top from any vertex: the start changes its cost, not the box.
        let last = out
            .tops
            .filter(|t| t.iter().all(|&v| (v as usize) < self.vertices.len()));
        let mut tops = [0u32; 6];
        for k in 0..3 {
            let d = Vec3::ith(k, 1.0);
            let from = |side: usize, d: &Vec3| match last {
                Some(t) => t[2 * k + side] as usize,
                None => c.start(&out.rot, d),
            };
            let (top, h) = c.ascend(from(0, &d), |i| world(i)[k]);
            let (bottom, l) = c.ascend(from(1, &-d), |i| -world(i)[k]);
            (hi[k], lo[k]) = (h + pad, -l - pad);
            (tops[2 * k], tops[2 * k + 1]) = (top as u32, bottom as u32);
        }
        (out.lo, out.hi, out.tops) = (lo, hi, Some(tops));
    }

    fn pose_with(
        &self,
        pos: &Vec3,
        rot: &UnitQuaternion<f64>,
        scale: f64,
        out: &mut Posed,
        vertices: bool,
        planes: bool,
    ) {
        let r = rot.to_rotation_matrix();
        out.rot = r;
        out.orientation = *rot;
        out.pos = *pos;
        out.scale = scale;
        out.travel = None;
        out.vertices.clear();
        if vertices {
            out.vertices
                .extend(self.vertices.iter().map(|v| pos + r * (v * scale)));
        }
        out.normals.clear();
        out.offsets.clear();
        if planes {
            out.normals.extend(self.normals.iter().map(|n| out.rot * n));
            out.offsets.extend(
                self.offsets
                    .iter()
                    .zip(&out.normals)
                    .map(|(d, n)| plane_offset(*d, n, pos, scale)),
            );
        }
        if vertices {
            let (lo, hi) = crate::math::bounding_box(&out.vertices).expect("a shape has vertices");
            out.lo = lo;
            out.hi = hi;
        }
    }
}

/// The faces around each vertex of the faces `face_start`/`face_verts`, as compressed rows:
/// vertex `v`'s faces are `faces[start[v]..start[v + 1]]`, ascending.
pub fn incidence(face_start: &[u32], face_verts: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let count = face_verts
        .iter()
        .map(|&v| v as usize + 1)
        .max()
        .unwrap_or(0);
    let mut start = vec![0u32; count + 1];
    for &v in face_verts {
        start[v as usize + 1] += 1;
    }
    for v in 0..count {
        start[v + 1] += start[v];
    }
    let mut next = start.clone();
    let mut faces = vec![0u32; face_verts.len()];
    for f in 0..face_start.len().saturating_sub(1) {
        for &v in &face_verts[face_start[f] as usize..face_start[f + 1] as usize] {
            faces[next[v as usize] as usize] = f as u32;
            next[v as usize] += 1;
        }
    }
    (start, faces)
}

/// Principal axes of a symmetric inertia tensor: a proper rotation whose columns are the axes
/// (moments ascending; each axis signed so that its largest component is positive, the third
/// fixed by handedness) and the moments.
pub fn principal_axes(inertia: &Mat3) -> (Mat3, Vec3) {
    let eig = SymmetricEigen::new(*inertia);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let mut rot = Mat3::zeros();
    for (k, &i) in order.iter().enumerate().take(2) {
        let mut axis: Vec3 = eig.eigenvectors.column(i).into_owned();
        // The solver's vectors are unit and orthogonal only to its own tolerance (a tensor with
        // moments 1e53 and 0 gave norms of 1 + 7e-16): made so to rounding here, so that the
        // frame converts to a quaternion directly.
        if k == 1 {
            axis -= rot.column(0).dot(&axis) * rot.column(0);
        }
        axis.normalize_mut();
        let big = (0..3)
            .max_by(|&a, &b| axis[a].abs().total_cmp(&axis[b].abs()))
            .unwrap_or(0);
        if axis[big] < 0.0 {
            axis = -axis;
        }
        rot.set_column(k, &axis);
    }
    let third = rot.column(0).cross(&rot.column(1));
    rot.set_column(2, &third);
    let moments = Vec3::new(
        eig.eigenvalues[order[0]],
        eig.eigenvalues[order[1]],
        eig.eigenvalues[order[2]],
    );
    (rot, moments)
}

/// A shape placed in the world: vertices, face planes and bounding box in world coordinates.
/// The planes may be left out ([`Shape::pose_for_contacts`]): [`Posed::plane`] has them all.
#[derive(Clone, Debug, Default)]
pub struct Posed {
    pub vertices: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub offsets: Vec<f64>,
    pub lo: Vec3,
    pub hi: Vec3,
    /// The pose: world = pos + rot (scale x); `orientation` is `rot` as the body's quaternion.
    pub rot: Rotation3<f64>,
    pub orientation: UnitQuaternion<f64>,
    pub pos: Vec3,
    pub scale: f64,
    /// A large hull posed lazily: the vertices its box's six climbs ended at (highest and
    /// lowest along x, y, z), where the next pose's climbs start.
    pub tops: Option<[u32; 6]>,
    /// The body's odometer when posed, if it has one (the world's bodies do; [`Travel`]), by
    /// which kept structures tell the motion since they were found. `None` (each pose makes
    /// it so) counts as unknown motion.
    pub travel: Option<Travel>,
}

impl Posed {
    /// How many vertices this pose of `s` has ([`Posed::vertex`]).
    pub fn vertex_count(&self, s: &Shape) -> usize {
        if self.vertices.is_empty() {
            s.vertices.len()
        } else {
            self.vertices.len()
        }
    }

    /// World position of vertex `i` of `s` (the shape this is a pose of): the posed one, or the
    /// same numbers computed now when the vertices were left out (a large shape posed for
    /// contacts: a contact reads a few dozen of its 758 vertices, and posing them all wrote
    /// 18 KiB per body and step).
    #[inline]
    pub fn vertex(&self, s: &Shape, i: usize) -> Vec3 {
        if self.vertices.is_empty() {
            self.pos + self.rot * (s.vertices[i] * self.scale)
        } else {
            self.vertices[i]
        }
    }

    /// World normal and offset of face `f` of `s` (the shape this is a pose of): the posed
    /// plane, or the same numbers computed now when the planes were left out.
    #[inline(always)]
    pub fn plane(&self, s: &Shape, f: usize) -> (Vec3, f64) {
        match (self.normals.get(f), self.offsets.get(f)) {
            (Some(n), Some(d)) => (*n, *d),
            _ => {
                let n = self.rot * s.normals[f];
                (n, plane_offset(s.offsets[f], &n, &self.pos, self.scale))
            }
        }
    }
}

/// An odometer reading: a bound on how far any point of a body has moved since a reading of 0,
/// as the sum of each step's [`motion_bound`] in units of [`TRAVEL_UNIT`], each rounded up.
/// Whole units make the difference of two readings exact: as sums of floats, readings of a
/// metre apart a million steps would have lost ~1e-10 m to rounding, more than the margins
/// (1e-9 of a particle's size) that the bounds are checked against. [`TRAVEL_UNKNOWN`] (also
/// where the sum runs out of range, at 16 km) reads as no bound.
pub type Travel = u64;

/// The unit of [`Travel`], m: 2^-50 (8.9e-16 m).
pub const TRAVEL_UNIT: f64 = 1.0 / (1u64 << 50) as f64;

/// A reading of an unknown odometer.
pub const TRAVEL_UNKNOWN: Travel = u64::MAX;

/// Reading `t` after a motion of bound `bound`, m (rounded up to whole units).
pub fn travel_after(t: Travel, bound: f64) -> Travel {
    let units = (bound / TRAVEL_UNIT).ceil();
    // A NaN motion, or one beyond the range, is no bound.
    let in_range = units < (TRAVEL_UNKNOWN - t) as f64;
    if t == TRAVEL_UNKNOWN || units.is_nan() || !in_range {
        return TRAVEL_UNKNOWN;
    }
    t + units as u64
}

/// A bound on how far any point of a body has moved, m, between odometer readings `from` and
/// `to` (infinite when either is unknown, or `to` comes before `from`).
pub fn travelled(from: Travel, to: Travel) -> f64 {
    if from == TRAVEL_UNKNOWN || to == TRAVEL_UNKNOWN || to < from {
        return f64::INFINITY;
    }
    // Up by a part in 2^52, over the conversion's rounding.
    (to - from) as f64 * TRAVEL_UNIT * (1.0 + f64::EPSILON)
}

/// A bound on how far any point within `radius` of a body's centroid can be from where it was
/// when the body's centroid was at `from.0` with orientation `from.1`, now that they are `to`:
/// the centroid's displacement plus the chord of the rotation between, `2 r sin(theta / 2)`,
/// which is `2 r` times the length of the vector part of `to.1 from.1^-1`. A step's bound is
/// what a body's odometer adds (see the world's `Odometer`).
pub fn motion_bound(
    from: (&Vec3, &UnitQuaternion<f64>),
    to: (&Vec3, &UnitQuaternion<f64>),
    radius: f64,
) -> f64 {
    let (shift, turn) = motion(from, to);
    shift.norm() + 2.0 * radius * turn.norm()
}

/// The centroid's displacement from `from` to `to`, and the vector part of the rotation
/// between (`sin(theta / 2)` times its axis): what the motion bounds measure.
#[inline(always)]
fn motion(from: (&Vec3, &UnitQuaternion<f64>), to: (&Vec3, &UnitQuaternion<f64>)) -> (Vec3, Vec3) {
    let turn = to.1 * from.1.inverse();
    (to.0 - from.0, turn.imag())
}

/// How far a large hull's box, found by climbing, is padded out: a fraction of its radius, far
/// above the ~1e-14 of the coordinates a climb can stop short by.
const BOX_PAD_REL: f64 = 1e-10;

/// The world offset of a face plane of offset `d` (shape frame) and world normal `n`.
fn plane_offset(d: f64, n: &Vec3, pos: &Vec3, scale: f64) -> f64 {
    d * scale + n.dot(pos)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hard case the OBJ fuzzer found: a shape so large that its inertia overflows is refused
    /// with a message (its hull's coordinates are beyond the hull's range), not fitted a
    /// rotation from NaN (which never converges); one merely large is taken.
    #[test]
    fn a_shape_too_large_for_its_inertia_is_refused_and_a_large_one_taken() {
        let huge = crate::geometry::mesh::cube(1e120);
        let e = Shape::from_mesh(&huge).unwrap_err();
        assert!(
            matches!(e, ShapeError::Hull(_, HullError::TooLarge(..))),
            "{e}"
        );
        assert!(e.to_string().contains("beyond 1e50"), "{e}");
        let large = Shape::from_mesh(&crate::geometry::mesh::cube(1e50)).unwrap();
        assert!((large.radius / (1e50 * 3f64.sqrt()) - 1.0).abs() < 1e-12);
    }
    use crate::geometry::mesh::cube;
    use approx::assert_relative_eq;

    /// Odometer readings are whole units: a metre on, a million steps of 1e-13 m read back as
    /// 1e-7 m to the unit (as floats each step's sum would round by ~1e-16 m), never less than
    /// the motion; unknown readings, a reading out of range and a motion of NaN read as no bound.
    #[test]
    fn odometer_readings_differ_exactly() {
        let start = travel_after(0, 1.0);
        let mut t = start;
        for _ in 0..1_000_000 {
            t = travel_after(t, 1e-13);
        }
        let step = (1e-13 / TRAVEL_UNIT).ceil() as u64;
        assert_eq!(t - start, 1_000_000 * step);
        let moved = travelled(start, t);
        assert!((1e-7..1e-7 * (1.0 + 1e-2)).contains(&moved), "{moved}");
        assert_eq!(travelled(t, t), 0.0);
        for (from, to) in [(TRAVEL_UNKNOWN, t), (start, TRAVEL_UNKNOWN), (t, start)] {
            assert_eq!(travelled(from, to), f64::INFINITY, "{from} {to}");
        }
        assert_eq!(travel_after(t, 1e5), TRAVEL_UNKNOWN, "16 km on");
        assert_eq!(travel_after(t, f64::NAN), TRAVEL_UNKNOWN);
        assert_eq!(travel_after(TRAVEL_UNKNOWN, 0.0), TRAVEL_UNKNOWN);
    }

    /// A large hull posed for contacts leaves its vertices out: each one computed when asked
    /// for must be the full pose's to the bit, and its box (by climbing) must hold the full
    /// pose's, by no more than its padding.
    #[test]
    fn a_large_hull_posed_for_contacts_gives_the_full_poses_numbers() {
        use crate::geometry::polygen::{generate, Params};
        let mesh = generate(&Params::default(), 3, 0).unwrap().mesh;
        let topo = mesh.topology(None).unwrap();
        let s = Shape::from_mesh(&crate::geometry::subdiv::subdivide(&mesh, &topo, 3)).unwrap();
        assert!(
            s.climb.is_some(),
            "not a large hull: {} vertices",
            s.vertices.len()
        );
        let pos = Vec3::new(0.3, -0.1, 0.25);
        let rot = UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0);
        let full = s.posed(&pos, &rot, 0.013);
        let (mut lazy, mut eager) = (Posed::default(), Posed::default());
        s.pose_for_contacts(&pos, &rot, 0.013, &mut lazy, true);
        s.pose_for_contacts(&pos, &rot, 0.013, &mut eager, false);
        assert_eq!(eager.vertices, full.vertices);
        assert_eq!((eager.lo, eager.hi), (full.lo, full.hi));
        assert!(
            eager.normals.is_empty(),
            "a large hull's planes are left out either way"
        );
        assert!(lazy.vertices.is_empty() && lazy.normals.is_empty());
        assert_eq!(lazy.vertex_count(&s), full.vertices.len());
        for (i, v) in full.vertices.iter().enumerate() {
            assert_eq!(lazy.vertex(&s, i), *v, "vertex {i}");
        }
        // The box by climbing holds the full pose's, padded by BOX_PAD_REL of the radius.
        let pad = BOX_PAD_REL * s.radius * 0.013;
        for k in 0..3 {
            assert!(
                lazy.lo[k] <= full.lo[k] && full.hi[k] <= lazy.hi[k],
                "axis {k}"
            );
            assert!(
                full.lo[k] - lazy.lo[k] <= 1.01 * pad,
                "axis {k}: low side too far"
            );
            assert!(
                lazy.hi[k] - full.hi[k] <= 1.01 * pad,
                "axis {k}: high side too far"
            );
        }
        for f in 0..s.face_count() {
            assert_eq!(lazy.plane(&s, f), full.plane(&s, f), "plane {f}");
        }
        // Posed again, turned a little or a lot, its climbs start where the last ended: the
        // box must be a fresh pose's, to the bit (and from tops of another shape's pose too).
        let mut warm = lazy.clone();
        for (k, angle) in [1e-4, 0.01, 0.3, 2.0, 3.1].into_iter().enumerate() {
            let turned = UnitQuaternion::from_euler_angles(angle, -0.5 * angle, 0.7) * rot;
            let moved = pos + Vec3::new(0.01, 0.0, -0.02) * k as f64;
            s.pose_for_contacts(&moved, &turned, 0.013, &mut warm, true);
            let mut fresh = Posed::default();
            s.pose_for_contacts(&moved, &turned, 0.013, &mut fresh, true);
            assert_eq!((warm.lo, warm.hi), (fresh.lo, fresh.hi), "angle {angle}");
        }
        warm.tops = Some([0, 1, 2, 3, 4, u32::MAX]);
        s.pose_for_contacts(&pos, &rot, 0.013, &mut warm, true);
        assert_eq!((warm.lo, warm.hi), (lazy.lo, lazy.hi));
    }

    /// [`Climb::clearances`] skips groups of planes by a bound: it must name the same near
    /// planes, with the same distances, as a scan over every plane, and a lower bound, no less
    /// than the limit, on the least distance of the others. Points inside near the surface
    /// (where a contact's vertices are), deep inside, and outside; limits from 0 to the whole
    /// body.
    #[test]
    fn grouped_plane_clearances_bound_a_full_scan() {
        use crate::geometry::polygen::{generate, Params};
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for faces in [6, 9, 14] {
            let params = Params {
                faces,
                ..Default::default()
            };
            let mesh = generate(&params, 5, 0).unwrap().mesh;
            let topo = mesh.topology(None).unwrap();
            let s = Shape::from_mesh(&crate::geometry::subdiv::subdivide(&mesh, &topo, 3)).unwrap();
            let climb = s.climb.as_ref().expect("a large hull");
            for _ in 0..400 {
                let v = s.vertices[rng.random_range(0..s.vertices.len())];
                let depth = [1e-6, 1e-3, 0.05, 0.5, -0.01][rng.random_range(0..5)];
                let p = v * (1.0 - depth);
                let scale = 0.02;
                let limit = scale * s.radius * [0.0, 1e-4, 5e-3, 0.1, 3.0][rng.random_range(0..5)];
                let (mut near, mut far) = (Vec::new(), f64::INFINITY);
                for (f, (n, d)) in s.normals.iter().zip(&s.offsets).enumerate() {
                    let inside = d * scale - (n.x * p.x + n.y * p.y + n.z * p.z);
                    if inside < limit {
                        near.push((f as u32, inside));
                    } else {
                        far = far.min(inside);
                    }
                }
                let mut got = Vec::new();
                let least = climb.clearances(&p, scale, limit, |f, inside| got.push((f, inside)));
                got.sort_by_key(|g| g.0);
                assert_eq!(got, near, "faces {faces}, depth {depth}, limit {limit}");
                // A lower bound on the least far distance, and no less than the limit (the
                // far planes' own floor): every plane it stands for is at least that far.
                assert!(
                    least <= far && least >= limit,
                    "faces {faces}, depth {depth}: {least:e} against {far:e}, limit {limit:e}"
                );
                assert_eq!(least == f64::INFINITY, far == f64::INFINITY);
            }
        }
    }

    /// Each face's sphere holds its polygon.
    #[test]
    fn face_spheres_hold_their_faces() {
        use crate::geometry::polygen::{generate, Params};
        let mesh = generate(&Params::default(), 3, 0).unwrap().mesh;
        let topo = mesh.topology(None).unwrap();
        let s = Shape::from_mesh(&crate::geometry::subdiv::subdivide(&mesh, &topo, 3)).unwrap();
        let climb = s.climb.as_ref().expect("a large hull");
        for f in 0..s.face_count() {
            let (c, r) = climb.face_spheres[f];
            for &v in s.face(f) {
                assert!(
                    (s.vertices[v as usize] - c).norm() <= r * (1.0 + 1e-15),
                    "face {f}"
                );
            }
            assert!(r < 0.5 * s.radius, "face {f}: radius {r}");
        }
    }

    #[test]
    fn cube_shape_in_principal_frame() {
        let mut c = cube(0.5);
        for v in &mut c.vertices {
            *v += Vec3::new(3.0, 4.0, 5.0);
        }
        let s = Shape::from_mesh(&c).unwrap();
        assert_relative_eq!(s.volume, 1.0, epsilon = 1e-12);
        assert_relative_eq!(s.moments, Vec3::repeat(1.0 / 6.0), epsilon = 1e-12);
        assert_relative_eq!(
            s.centroid_in_mesh,
            Vec3::new(3.0, 4.0, 5.0),
            epsilon = 1e-12
        );
        assert_relative_eq!(s.radius, 0.75f64.sqrt(), epsilon = 1e-12);
        assert_eq!(s.face_count(), 6);
    }

    #[test]
    fn every_cube_vertex_has_its_three_faces() {
        let s = Shape::from_mesh(&cube(0.5)).unwrap();
        for v in 0..s.vertices.len() {
            let around = s.faces_at(v);
            assert_eq!(around.len(), 3, "vertex {v}: {around:?}");
            for &f in around {
                assert!(s.face(f as usize).contains(&(v as u32)));
            }
        }
        let total: usize = (0..s.vertices.len()).map(|v| s.faces_at(v).len()).sum();
        assert_eq!(total, s.face_verts.len());
    }

    #[test]
    fn box_axes_are_sorted_and_proper() {
        // A 1 x 2 x 3 box rotated arbitrarily: moments ascending, a proper rotation back.
        let r = nalgebra::Rotation3::from_euler_angles(0.4, -0.7, 1.9);
        let mut m = cube(1.0);
        for v in &mut m.vertices {
            *v = r * Vec3::new(v.x * 0.5, v.y * 1.0, v.z * 1.5);
        }
        let s = Shape::from_mesh(&m).unwrap();
        let vol = 6.0;
        let (a, b, c) = (1.0f64, 2.0f64, 3.0f64);
        let expect = Vec3::new(b * b + c * c, a * a + c * c, a * a + b * b) * (vol / 12.0);
        let mut e: Vec<f64> = expect.iter().copied().collect();
        e.sort_by(f64::total_cmp);
        assert_relative_eq!(s.moments, Vec3::new(e[0], e[1], e[2]), epsilon = 1e-10);
        assert_relative_eq!(
            s.frame_in_mesh.to_rotation_matrix().matrix().determinant(),
            1.0,
            epsilon = 1e-12
        );
        // Back to the mesh frame, the vertices are the box's.
        for v in &s.vertices {
            let back = s.frame_in_mesh * v + s.centroid_in_mesh;
            assert!(m.vertices.iter().any(|w| (w - back).norm() < 1e-9));
        }
    }

    #[test]
    fn a_principal_frame_half_a_turn_from_the_mesh_is_exact() {
        // A 2 x 3 x 1 box along the axes: its principal frame is the mesh's y, x and -z axes,
        // half a turn about (1, 1, 0), where an iterative fit from the identity has no slope.
        let m = crate::geometry::mesh::cuboid(Vec3::new(1.0, 1.5, 0.5));
        let s = Shape::from_mesh(&m).unwrap();
        let turn = s.frame_in_mesh.to_rotation_matrix();
        let expect = Mat3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0);
        assert_relative_eq!(*turn.matrix(), expect, epsilon = 1e-15);
        for v in &s.vertices {
            let back = s.frame_in_mesh * v + s.centroid_in_mesh;
            assert!(m.vertices.iter().any(|w| (w - back).norm() < 1e-12));
        }
    }

    #[test]
    fn principal_axes_of_an_extreme_tensor_are_a_rotation() {
        // The inertia of a sliver 1.3e18 long and about 1 wide (found by fuzzing): the eigen
        // solver's vectors came with norms 1 + 7e-16, on which an iterative conversion to a
        // quaternion never converged.
        let inertia = Mat3::new(
            1.185185185185121e53,
            5.6909614583332305e22,
            -2.158333333333294e18,
            5.6909614583332305e22,
            0.0,
            2.1336947916666277e22,
            -2.158333333333294e18,
            2.1336947916666277e22,
            1.185185185185121e53,
        );
        let (rot, _) = principal_axes(&inertia);
        assert_relative_eq!(rot.transpose() * rot, Mat3::identity(), epsilon = 4e-16);
        assert_relative_eq!(rot.determinant(), 1.0, epsilon = 4e-16);
    }

    #[test]
    fn a_shape_too_slender_for_its_inertia_is_refused() {
        // A tetrahedron 1e18 long and 1 wide: its least moment is lost in the rounding of the
        // others. One 1e3 long is kept.
        let sliver = |length: f64| PolyMesh {
            name: "sliver".into(),
            vertices: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(0.3, 0.3, length),
            ],
            ..PolyMesh::default()
        };
        let e = Shape::from_mesh(&sliver(1e18)).unwrap_err();
        assert!(matches!(e, ShapeError::Slender(..)), "{e}");
        assert!(e.to_string().contains("too slender"), "{e}");
        assert!(Shape::from_mesh(&sliver(1e3)).is_ok());
    }

    #[test]
    fn rotation_rate_is_the_fastest_spring_at_a_vertex() {
        // Brute force: omega^2 per unit stiffness of a spring along n at vertex v is
        // (v x n) . M^-1 (v x n); its largest over many directions and all vertices.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let rod =
            Shape::from_mesh(&crate::geometry::mesh::cuboid(Vec3::new(0.6, 0.15, 0.1))).unwrap();
        let cube_shape = Shape::from_mesh(&cube(0.5)).unwrap();
        for s in [&rod, &cube_shape] {
            let mut best: f64 = 0.0;
            for _ in 0..20000 {
                let n = (Vec3::new(rng.random(), rng.random(), rng.random()) - Vec3::repeat(0.5))
                    .normalize();
                for v in &s.vertices {
                    let t = v.cross(&n);
                    best = best.max((t.component_div(&s.moments)).dot(&t));
                }
            }
            let rate = s.rotation_rate();
            assert!(rate >= best && rate < best * 1.01, "{rate} against {best}");
            assert!(rate <= s.radius * s.radius / s.moments.min() * (1.0 + 1e-12));
        }
        // Equal moments: r^2 / I exactly; an elongated rod: well below r^2 / I_min.
        let c = &cube_shape;
        assert!(
            (c.rotation_rate() - c.radius * c.radius / c.moments.min()).abs()
                < 1e-9 * c.rotation_rate()
        );
        assert!(rod.rotation_rate() < 0.2 * rod.radius * rod.radius / rod.moments.min());
    }
}
