//! The DEM engine for rigid convex polyhedra (work in progress; see issue "DEM engine").
//!
//! - [`shape`]: convex templates in their principal frame.
//! - [`overlap`]: contact geometry from the overlap polyhedron (normal, depth, point).

pub mod overlap;
pub mod shape;
