//! The discrete element engine for rigid convex polyhedra.
//!
//! A [`world::World`] holds shapes, bodies, walls and contacts; [`world::World::step`] advances
//! it by one time step:
//! 1. walls move ([`wall`]);
//! 2. bodies are posed and paired by their boxes ([`collision::broad`]), pairs proven apart are
//!    skipped ([`collision::gaps`], [`collision::gjk`]);
//! 3. touching pairs get their overlap polyhedron ([`collision::overlap`], its structure kept
//!    from step to step by [`collision::kept`]) and the contact law's forces ([`law`]);
//! 4. each body sums its forces and moves ([`integrate`]); the contact list ([`contacts`]) and
//!    the energy audit ([`energy`]) are made beside it.
//!
//! Loops run on rayon's pool in an order that does not depend on the thread count
//! ([`parallel`]). Scenes and states are read and written by [`io`].
//!
//! Conventions: SI units; a contact's normal points from its partner (body A, the lower id, or
//! the wall) to its body B; forces stored on a contact act on B.

pub mod collision;
pub mod contacts;
pub mod energy;
pub mod integrate;
pub mod io;
pub mod law;
pub mod membrane;
pub mod parallel;
pub mod scenes;
pub mod shape;
pub mod wall;
pub mod world;
