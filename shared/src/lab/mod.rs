//! The laboratory: procedures that drive the engine as an experimenter drives a rig.
//!
//! - [`boundary`]: the container (platens and a cylinder or box sides), what its walls measure
//!   (stresses, porosity) and where its inside is.
//! - [`inertia`]: density scaling for quasi-static procedures.
//! - [`servo`]: wall speeds that hold a stress (PFC's servo law with integral action).
//! - [`pack`]: dense, isotropically consolidated specimens (the `pack` tool).
//! - [`triax`]: the drained triaxial test with a flexible membrane (the `triax` tool).

pub mod boundary;
pub mod inertia;
pub mod pack;
pub mod servo;
pub mod triax;
