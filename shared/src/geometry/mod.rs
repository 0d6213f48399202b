//! Polyhedra as meshes: reading and writing them, measuring them, making and abrading them.
//!
//! - [`mesh`]: polygon meshes, half-edge topology, closed-manifold validation.
//! - [`obj`]: the streaming OBJ reader and writer (the format between the tools).
//! - [`hull`]: a robust 3D convex hull with coplanar facets merged, and its simplification to
//!   a vertex budget.
//! - [`mass`]: volume, area, centroid, inertia and roundness S3D.
//! - [`polygen`]: random convex polyhedra from tangent planes of a sphere.
//! - [`subdiv`]: Catmull-Clark subdivision, the paper's abrasion.

pub mod hull;
pub mod mass;
pub mod mesh;
pub mod obj;
pub mod polygen;
pub mod subdiv;
