//! The engine's files: scenes and restartable states ([`state`], JSON lines), snapshots for
//! ParaView ([`vtk`]) and the Yade comparison's scene format ([`yade`]).

pub mod state;
pub mod vtk;
pub mod yade;
