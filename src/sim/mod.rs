//! Simulated hardware, so every layer above the devices runs without a rig: the simulated
//! firmware (a pure state machine in `firmware`, served on a pseudo-terminal by `runner`) and,
//! beside it, the simulated camera. Simulated devices see each other through shared state
//! (`runner::SimHandle`): the camera renders the platter angle and lit channels the firmware
//! reports.

pub mod camera;
pub mod firmware;
pub mod imaging;
pub mod job_scene;
pub mod motion;
pub mod port_dir;
pub mod runner;
pub mod scene;
pub mod truth;
pub mod truth_labels;

pub use firmware::{FirmwareConfig, MoveKind, MoveRecord, SimSnapshot};
pub use runner::{FaultControl, LinkFaults, SimConfig, SimHandle, SimRig};
