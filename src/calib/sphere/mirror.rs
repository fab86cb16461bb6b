//! The light direction from one sphere image: the view direction mirrored about the sphere's
//! normal at the highlight, `l = 2 (n.v) n - v` (METHOD.md section 1.3).
//!
//! Conventions: as `calib::sphere`: `v` from the sphere towards the camera, `l` towards the
//! light, unit vectors in camera axes. Pure: no I/O.

use super::highlight::find_highlight;
use super::{Highlight, SphereError, SphereOptions, SphereOutline};
use crate::geometry::camera::Intrinsics;
use crate::render::image::LinearImage;
use nalgebra::Vector3;

/// Mirror `v` about `n`: `2 (n.v) n - v`.
pub fn reflect(n: &Vector3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
    n * (2.0 * n.dot(v)) - v
}

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
    /// First-order standard uncertainty of `dir_camera` (radians): twice the normal's, since
    /// mirroring doubles a normal error.
    pub uncertainty_rad: f64,
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
    let highlight = find_highlight(light_image, outline, intr, opts)?;
    let n = highlight.normal;
    let p = outline.centre_in_radii() + n;
    let v = -p.normalize();
    let l = reflect(&n, &v).normalize();
    // the highlight centroid is trusted to a tenth of a pixel
    let sigma_h = 0.1 / outline.radius_px.max(1.0);
    let sigma_n = (outline.normal_uncertainty_rad(intr).powi(2) + sigma_h.powi(2)).sqrt();
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
        uncertainty_rad: 2.0 * sigma_n,
        warnings,
    })
}

/// Pixels sharing the highlight's top value from which a plateau is worth a warning.
const FLAT_TOP_WARN: usize = 4;

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    #[test]
    fn reflection_is_the_mirror_direction() {
        let n = Vector3::new(0.0, 0.0, -1.0);
        let v = Vector3::new(0.6, 0.0, -0.8);
        let l = reflect(&n, &v);
        assert!((l - Vector3::new(-0.6, 0.0, -0.8)).norm() < 1e-12);
        // half vector of l and v is n
        assert!(((l + v).normalize() - n).norm() < 1e-12);
    }
}
