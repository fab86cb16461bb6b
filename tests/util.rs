//! Shared test harness: paths to the shared data and the built binary, the tests' small basis.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

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

/// Runs `brdf-rig report DIR` (asserting it succeeds, with its stderr if not) and returns the
/// page it wrote, `DIR/report.html`.
pub fn html_report(dir: &Path) -> String {
    let o = std::process::Command::new(bin())
        .arg("report")
        .arg(dir)
        .output()
        .expect("brdf-rig runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read_to_string(dir.join("report.html")).expect("report.html written")
}

/// The tests' reduced basis: stride 1,4,6 and 40 components (its cache is shared by the tests,
/// `brdf-rig-test-basis` in the temporary folder), leaving out `exclude`.
pub fn small_basis(exclude: Vec<String>) -> brdf_rig::brdf::basis::BasisSettings {
    brdf_rig::brdf::basis::BasisSettings {
        stride: brdf_rig::brdf::basis::GridStride {
            theta_h: 1,
            theta_d: 4,
            phi_d: 6,
        },
        basis_components: 40,
        exclude,
    }
}
