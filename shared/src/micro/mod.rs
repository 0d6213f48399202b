//! Micro-mechanics: statistics of the contact network.
//!
//! - [`fabric`]: the fabric tensors of normals, branches and forces, their anisotropies and
//!   the stress-force-fabric relation (Eqs. 11-19).
//! - [`stress`]: the average stress from the contacts, coordination numbers and the sliding
//!   ratio.
//! - [`rotation`]: particle rotations through a sequence of states.
//! - [`rose`]: the mean normal force per direction on equal-area bins.

pub mod fabric;
pub mod rose;
pub mod rotation;
pub mod stress;
