//! Shared test harness: paths to the shared data and the built binary.

#![allow(dead_code)]

use std::path::PathBuf;

/// `../shared/data` next to the repository, or `$BRDF_RIG_SHARED_DATA`.
pub fn shared_data() -> PathBuf {
    if let Ok(p) = std::env::var("BRDF_RIG_SHARED_DATA") {
        return PathBuf::from(p);
    }
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data")
}

/// The `brdf-rig` binary cargo built for these tests.
pub fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_brdf-rig"))
}
