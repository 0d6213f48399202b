//! # granular-shared
//!
//! The library behind the `granular` command-line tools: random convex polyhedra from tangent
//! planes, Catmull-Clark abrasion and roundness; a discrete element engine for rigid convex
//! polyhedra; the laboratory procedures that drive it (a consolidated specimen); the
//! micro-mechanics of its contact network; and the pictures of all of them. The tools in
//! `tools/` only parse arguments and move bytes; every computation lives here.
//!
//! ```
//! use shared::geometry::{mass, polygen, subdiv};
//! // One random 8-faced polyhedron, abraded once, and its roundness S3D.
//! let params = polygen::Params { faces: 8, ..Default::default() };
//! let poly = polygen::generate(&params, 7, 0).unwrap();
//! let topo = poly.mesh.topology(None).unwrap();
//! let abraded = subdiv::catmull_clark(&poly.mesh, &topo);
//! let s3d = mass::MassProps::of(&abraded).s3d();
//! assert!(s3d > 0.8 && s3d < 1.0);
//! ```
//!
//! The crate's folders are its concerns:
//! - [`geometry`]: meshes, the OBJ stream, convex hulls, mass properties, random polyhedra and
//!   their abrasion.
//! - [`dem`]: the discrete element engine: shapes, collision, the contact law, walls, the
//!   integrator and the world, parallel loops, and its file formats.
//! - [`lab`]: procedures that drive the engine as a laboratory would: servo-controlled walls,
//!   boundary measurements, the consolidated specimen (`pack`).
//! - [`micro`]: statistics of the contact network (fabric tensors and anisotropy, the
//!   stress-force-fabric relation, rotations, roses).
//! - [`draw`]: shaded pictures of meshes and line charts of tables.
//! - [`math`]: type aliases and numeric helpers; [`cli`]: what every tool shares (exit codes,
//!   broken pipes, stream helpers); [`text`]: excerpts of input in messages; [`fuzz`]: what
//!   the fuzzers feed each reader.

pub mod cli;
pub mod dem;
pub mod draw;
pub mod fuzz;
pub mod geometry;
pub mod lab;
pub mod math;
pub mod micro;
pub mod text;
