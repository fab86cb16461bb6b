//! The light direction from one sphere image: the view direction mirrored about the sphere's
//! normal at the highlight, `l = 2 (n.v) n - v` (METHOD.md section 1.3).
//!
//! Conventions: as `calib::sphere`: `v` from the sphere towards the camera, `l` towards the
//! light, unit vectors in camera axes. Pure: no I/O.

use super::highlight::find_highlight;
use super::uncertainty;
use super::{Highlight, SphereError, SphereOptions, SphereOutline};
use crate::geometry::camera::Intrinsics;
use crate::geometry::reflect;
use crate::render::image::LinearImage;
use nalgebra::Vector3;

/// The light direction measured from one sphere image.
#[derive(Clone, Debug, PartialEq)]
pub struct SphereLight {
    /// Unit vector from the sphere towards the light, camera axes.
    pub dir_camera: Vector3<f64>,
    /// Sphere normal at the highlight, and the direction from that point to the camera.
    pub normal: Vector3<f64>,
    pub view: Vector3<f64>,
    pub outline: SphereOutline,
    pub highlight: Highlight,
    /// How far `dir_camera` may be off: the RMS angle (radians) to the truth from the outline,
    /// the highlight's sampling and noise, and its lobe's shape (`uncertainty`, which says what
    /// each part covers); exceeded twice over in about 2 % of cases.
    pub uncertainty_rad: f64,
    /// Wall time (seconds) of finding the outline (set by `calib::light`, which finds it; 0
    /// when the caller gave it) and the highlight: where a calibration's time goes.
    pub outline_secs: f64,
    pub highlight_secs: f64,
    /// What the caller should tell the user (e.g. a highlight that looks clipped while no clip
    /// level was given).
    pub warnings: Vec<String>,
}

/// Light direction from a light image and the sphere's outline.
pub fn light_from_sphere(
    light_image: &LinearImage,
    outline: &SphereOutline,
    intr: &Intrinsics,
    opts: &SphereOptions,
) -> Result<SphereLight, SphereError> {
    let started = std::time::Instant::now();
    let highlight = find_highlight(light_image, outline, intr, opts)?;
    let highlight_secs = started.elapsed().as_secs_f64();
    let n = highlight.normal;
    let p = outline.centre_in_radii() + n;
    let v = -p.normalize();
    let l = reflect(&n, &v).normalize();
    let uncertainty_rad = uncertainty::light_rms_rad(outline, &n, highlight.uncertainty_rad, intr);
    let mut warnings = Vec::new();
    if opts.saturation.is_none() && highlight.flat_top_pixels >= FLAT_TOP_WARN {
        warnings.push(format!(
            "{} pixels of the highlight share its largest value: if the camera clipped there, \
             give its clip level (--saturation); none is assumed for linear HDR input",
            highlight.flat_top_pixels
        ));
    }
    Ok(SphereLight {
        dir_camera: l,
        normal: n,
        view: v,
        outline: outline.clone(),
        highlight,
        uncertainty_rad,
        outline_secs: 0.0,
        highlight_secs,
        warnings,
    })
}

/// Pixels sharing the highlight's top value from which a plateau is worth a warning.
const FLAT_TOP_WARN: usize = 4;
