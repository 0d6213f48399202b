//! Micro-mechanics: statistics of the contact network.
//!
//! - [`fabric`]: the fabric tensor of contact normals and its scalar anisotropy.
//! - [`stress`]: the average stress from the contacts, and coordination numbers.

pub mod fabric;
pub mod stress;
