//! Orchestration across steps: starting a capture on a rig (shared by the command line and the
//! lab page), calibrating a capture session into a reconstruction job, and the whole simulated
//! story (capture, calibrate, reconstruct, report) behind the README's main command. An edge:
//! reads and writes session folders; the steps themselves live in their own modules and know
//! nothing of each other.

pub mod calibration_file;
pub mod capture_run;
pub mod capture_start;
pub mod session_calib;
pub mod sim_session;
