//! How a report is made (`brdf-rig report` options): what is re-checked, how much is shown.

use super::inplane::InPlaneSettings;
use std::path::PathBuf;

/// How the report is made.
#[derive(Clone, Debug, PartialEq)]
pub struct ReportOptions {
    pub inplane: InPlaneSettings,
    /// In-plane plots on a logarithmic f_r axis (specular peaks span decades).
    pub log_y: bool,
    /// Further BRDF files to compare in the in-plane plot: (label, path to `.binary` or `.f32`).
    pub compare: Vec<(String, PathBuf)>,
    /// Re-read every session image and check its SHA-256 against the manifest.
    pub verify_checksums: bool,
    /// At most this many single-light thumbnails from a session.
    pub max_thumbnails: usize,
    /// Width and height of each sphere render, pixels.
    pub sphere_pixels: usize,
}

impl Default for ReportOptions {
    fn default() -> Self {
        Self {
            inplane: InPlaneSettings::default(),
            log_y: true,
            compare: Vec::new(),
            verify_checksums: true,
            max_thumbnails: 6,
            sphere_pixels: 160,
        }
    }
}
