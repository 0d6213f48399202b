//! # granular-shared
//!
//! The library behind the `granular` command-line tools: random convex polyhedra from tangent
//! planes, Catmull-Clark abrasion, roundness, and the pictures of them. The tools in `tools/`
//! only parse arguments and move bytes; every computation lives here.
//!
//! ```
//! use shared::{polygen, subdiv, mass};
//! // One random 8-faced polyhedron, abraded once, and its roundness S3D.
//! let params = polygen::Params { faces: 8, ..Default::default() };
//! let poly = polygen::generate(&params, 7, 0).unwrap();
//! let topo = poly.mesh.topology(None).unwrap();
//! let abraded = subdiv::catmull_clark(&poly.mesh, &topo);
//! let s3d = mass::MassProps::of(&abraded).s3d();
//! assert!(s3d > 0.8 && s3d < 1.0);
//! ```
//!
//! Modules, one per concept:
//! - [`math`]: type aliases and numeric helpers.
//! - [`mesh`]: polygon meshes, half-edge topology, closed-manifold validation.
//! - [`obj`]: the streaming OBJ reader and writer (the format between the tools).
//! - [`hull`]: a robust 3D convex hull with coplanar facets merged.
//! - [`polygen`]: random convex polyhedra from tangent planes of a sphere.
//! - [`subdiv`]: Catmull-Clark subdivision, the paper's abrasion.
//! - [`mass`]: volume, area, centroid, inertia and roundness S3D.
//! - [`render`]: OBJ meshes to shaded PNG pictures.
//! - [`plot`]: line charts from tables.
//! - [`cli`]: what every tool shares: exit codes, broken pipes, stream helpers.
//! - [`dem`]: the discrete element engine for rigid convex polyhedra.
//! - [`pack`]: dense, isotropically consolidated specimens (the `pack` tool).

pub mod cli;
pub mod dem;
pub mod hull;
pub mod mass;
pub mod math;
pub mod mesh;
pub mod obj;
pub mod pack;
pub mod plot;
pub mod polygen;
pub mod render;
pub mod subdiv;
