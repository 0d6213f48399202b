//! Which bodies touch and how: the broad phase, the gap test, the overlap polyhedron and the
//! structures contacts keep from step to step.
//!
//! - [`broad`]: box-overlapping pairs by sweep and prune, with a kept list between sweeps.
//! - [`gaps`]: gap proofs kept between steps, checked against per-body odometers.
//! - [`gjk`]: a certified separation test for pairs whose boxes overlap.
//! - [`overlap`]: contact geometry from the overlap polyhedron (normal, depth, point).
//! - [`kept`]: the overlap polyhedron by its corners, kept from step to step.

pub mod broad;
pub mod gaps;
pub mod gjk;
pub mod kept;
pub mod overlap;
