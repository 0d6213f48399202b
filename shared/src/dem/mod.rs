//! The DEM engine for rigid convex polyhedra (work in progress; see issue "DEM engine").
//!
//! - [`shape`]: convex templates in their principal frame.
//! - [`gjk`]: a certified separation test for pairs whose boxes overlap.
//! - [`overlap`]: contact geometry from the overlap polyhedron (normal, depth, point).
//! - [`spread`]: a step's loops over the pool's threads.
//! - [`structure`]: the overlap polyhedron by its corners, kept from step to step.
//! - [`world`]: bodies, walls, the contact law, the integrator and the energy audit.
//! - [`state`]: scenes and restartable states as JSON lines.
//! - [`peer`]: the Yade peer benchmark's scene format.
//! - [`vtk`]: snapshots for ParaView.
//! - [`wall`]: planes, facets with moving nodes, cylinders.

pub mod broad;
pub mod contacts;
pub mod gjk;
pub mod overlap;
pub mod peer;
pub mod scenes;
pub mod shape;
pub mod spread;
pub mod state;
pub mod structure;
pub mod vtk;
pub mod wall;
pub mod world;
