//! Integration tests compile to one binary (one link on a 2-core machine). Each module drives
//! the library or the real binary the way a user would.

// Tests: a panic on unexpected input is the failure report, so unwrap is the clearest form.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod brdf;
mod calib_cli;
mod calib_fixtures;
mod calib_hdr;
mod calib_large;
mod calib_session;
mod calib_sphere;
mod calib_synth;
mod calib_white;
mod capture_kill;
mod capture_sim;
mod capture_util;
mod cli_output;
mod eval;
mod firmware;
mod firmware_flash;
mod firmware_qemu;
mod formats;
mod geometry;
mod imports;
mod independent;
mod label_masks;
mod materials;
mod observe_sweep;
mod raw_input;
mod reconstruct;
mod regression;
mod render;
mod report;
mod rig_cli;
mod rig_sim;
mod rig_vectors;
mod util;
mod web;
mod web_util;
