//! Micro-mechanics: statistics of the contact network.
//!
//! - [`fabric`]: the fabric tensor of contact normals and its scalar anisotropy.

pub mod fabric;
