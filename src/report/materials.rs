//! The materials part of a report (issue #17, `reconstruct --materials auto`): what
//! `report.json` says of the materials found and, per material, its own sphere renders (from
//! its `materials/material-N.binary`, through [`super::images::sphere_renders`]) and its pixels
//! and error in each light image (`comparisons[].materials`).
//!
//! Gathering reads the per-material tables, tolerantly: a missing or unreadable one becomes
//! [`Avail::No`] with a reason naming the file, never an error. The page is rendered by
//! `super::html`. Must not touch `report.json` itself (read once by `gather`) nor write anything.

use super::avail::{Avail, error_chain};
use super::brdf_file::load_brdf;
use super::images::{EmbeddedImage, sphere_renders};
use super::options::ReportOptions;
use crate::reconstruct::materials::MaterialsFile;
use crate::reconstruct::report_file::Report;
use std::path::Path;

/// The materials found, and what the page shows of each.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialsSection {
    /// `report.json`'s `materials` (the content of `materials.json`).
    pub file: MaterialsFile,
    /// One per entry of `file.materials`, in its order (label `i` is entry `i`).
    pub details: Vec<MaterialDetail>,
}

/// What the page shows of one material besides its `materials.json` entry.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialDetail {
    /// Its BRDF on spheres, or why not (naming the file).
    pub spheres: Avail<Vec<EmbeddedImage>>,
    /// Per light image with a comparison: its pixels there and their error.
    pub comparisons: Vec<MaterialImageRow>,
}

/// One material's pixels in one light image.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialImageRow {
    /// Index of the light image in the job.
    pub image: usize,
    pub observed_pixels: usize,
    /// Relative error of the re-render over them.
    pub fit_error: Option<f64>,
}

/// The materials section of the reconstruction in `recon_dir` whose report is `r`; `None` when
/// the segmentation did not run. Per-material files are read relative to `recon_dir`.
pub fn gather_materials(
    r: &Report,
    recon_dir: &Path,
    opts: &ReportOptions,
) -> Option<MaterialsSection> {
    let file = r.materials.clone()?;
    let details = file
        .materials
        .iter()
        .enumerate()
        .map(|(i, e)| MaterialDetail {
            spheres: material_spheres(&recon_dir.join(&e.file), opts),
            comparisons: r
                .comparisons
                .iter()
                .filter_map(|c| {
                    let m = c.materials.get(i)?;
                    Some(MaterialImageRow {
                        image: c.image,
                        observed_pixels: m.observed_pixels,
                        fit_error: m.fit_error,
                    })
                })
                .collect(),
        })
        .collect();
    Some(MaterialsSection { file, details })
}

/// Sphere renders of the BRDF in `path`, or why not (naming the file).
fn material_spheres(path: &Path, opts: &ReportOptions) -> Avail<Vec<EmbeddedImage>> {
    if !path.is_file() {
        return Avail::No(format!("{} does not exist", path.display()));
    }
    match load_brdf(path) {
        Ok(brdf) => sphere_renders(brdf.as_ref(), opts.sphere_pixels),
        // the MERL reader's errors name the file
        Err(e) => Avail::No(error_chain(&e)),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn a_missing_or_unreadable_table_is_a_hole_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let opts = ReportOptions {
            sphere_pixels: 16,
            ..ReportOptions::default()
        };
        let missing = dir.path().join("materials/material-1.binary");
        let Avail::No(why) = material_spheres(&missing, &opts) else {
            panic!("a missing file gave spheres")
        };
        assert!(
            why.contains("material-1.binary") && why.contains("does not exist"),
            "{why}"
        );
        let bad = dir.path().join("material-2.binary");
        std::fs::write(&bad, b"not a table").unwrap();
        let Avail::No(why) = material_spheres(&bad, &opts) else {
            panic!("a bad file gave spheres")
        };
        assert!(why.contains("material-2.binary"), "{why}");
    }
}
