//! Capture: plans (what to shoot), the session folder's format (`session_format`: file names,
//! version, records) and its writer (`session`: manifest, journal, images), the session
//! runner (guided or unattended, resumable) and verification.
//!
//! Depends on the device traits only (`crate::devices`), never on a concrete driver, so the
//! simulated rig and a real one run the same code. The CLI chooses the devices.

pub mod camera_config;
pub mod error;
pub mod plan;
pub mod runner;
pub mod session;
pub mod session_format;
pub mod verify;

pub use error::CaptureError;
pub use plan::{CapturePlan, PlannedShot, ShotKind, Stage, Target};
pub use runner::{Operator, Progress, RunOptions, RunSummary, Unattended, run_session};
pub use session::{Session, SessionHeader, ShotRecord};
pub use verify::{VerifyReport, verify_session};

/// Bytes one image of `width x height` takes on disk, with a margin (32-bit float RGB OpenEXR
/// compresses little).
pub fn estimated_image_bytes(width: usize, height: usize) -> u64 {
    (width as u64) * (height as u64) * 12 + 4096
}

/// Refuses to start when the folder's file system has less free space than the remaining shots
/// need (plus 10 % and 16 MiB of margin).
pub fn check_disk_space(
    dir: &std::path::Path,
    shots: usize,
    width: usize,
    height: usize,
) -> Result<(), CaptureError> {
    // The folder may not exist yet: measure the nearest existing ancestor.
    let mut probe = dir.to_path_buf();
    while !probe.exists() {
        match probe.parent() {
            Some(p) if !p.as_os_str().is_empty() => probe = p.to_path_buf(),
            _ => {
                probe = std::path::PathBuf::from(".");
                break;
            }
        }
    }
    let available = fs4::available_space(&probe)
        .map_err(|e| CaptureError::io("measuring free disk space", &probe, e))?;
    let needed = (shots as u64 * estimated_image_bytes(width, height)) * 11 / 10 + (16 << 20);
    if available < needed {
        return Err(CaptureError::DiskSpace {
            path: probe,
            needed_mib: needed >> 20,
            available_mib: available >> 20,
        });
    }
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn disk_space_is_checked_against_the_remaining_shots() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("not/yet/there");
        check_disk_space(&dir, 10, 64, 48).unwrap();
        let err = check_disk_space(&dir, 1_000_000_000, 4000, 3000).unwrap_err();
        assert!(matches!(err, CaptureError::DiskSpace { .. }), "{err}");
        assert!(err.to_string().contains("MiB are free"), "{err}");
    }
}
