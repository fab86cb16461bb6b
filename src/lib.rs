//! brdf-rig: drive a turntable BRDF rig and recover an object's isotropic BRDF.
//!
//! The crate is split by concern (see `docs/architecture.md`):
//! pure computation (`protocol`, `geometry`, `brdf`, `render`) never touches files, ports or
//! the terminal; `devices`, `sim`, `capture`, `calib` and `report` live at the edges.

pub mod atomic;
pub mod brdf;
pub mod calib;
pub mod capture;
pub mod data;
pub mod devices;
pub mod eval;
pub mod format;
pub mod geometry;
pub mod imageio;
pub mod pipeline;
pub mod profile;
pub mod protocol;
pub mod ranges;
pub mod reconstruct;
pub mod render;
pub mod report;
pub mod rig_factory;
pub mod serve;
pub mod sim;
pub mod stats;
