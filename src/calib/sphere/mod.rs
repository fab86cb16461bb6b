//! The light probe: a glossy black sphere photographed under the single light. Its outline gives
//! the sphere's position, its specular highlight the mirror normal, and the light direction is
//! the view direction mirrored about that normal, `l = 2 (n.v) n - v` (METHOD.md section 1.3).
//!
//! Conventions: camera axes x right, y down, z forward (COLMAP); every direction is a unit vector
//! in camera axes; `v` points from the sphere towards the camera, `l` from the sphere towards the
//! light. Pixel centres at half-integers. Angles in radians.
//!
//! Approach, perspective-exact: under perspective a sphere projects to an ellipse, not a circle,
//! so instead of fitting a conic in the image, every sub-pixel edge point is back-projected to a
//! ray with the intrinsics (distortion included). The rays tangent to a sphere form a circular
//! cone around the direction `d` of the sphere's centre with half-angle `alpha`, so
//! `d . r_i = cos(alpha)` for every edge ray: the ray tips lie on a plane, fitted by total least
//! squares (smallest eigenvector of their covariance). With the sphere radius as unit the centre
//! is `C = d / sin(alpha)`; the scale of the scene never matters for directions. The normal at a
//! pixel is found by intersecting its ray with that sphere. The highlight is located in *normal
//! space* (weighted mean of the sphere normals of its pixels), where the iso-brightness contours
//! of an isotropic lobe are circles around the mirror normal, so foreshortening near the rim and
//! a clipped (saturated) core do not bias it.
//!
//! Edge points: candidate circles from the image's edges (a Hough transform, `seed`), then
//! radial intensity profiles across each, fitted with the rim model of a glossy sphere (`rim`):
//! near its silhouette the sphere mirrors the backdrop beside it with a Fresnel reflectance that
//! rises to 1 at grazing, so its rim fades into the backdrop, brighter or darker than the
//! sphere's middle. The model's fitted position is the outline itself, not the visible fade,
//! which lies 0.5 to 1 px inside it; the blur of the lens and the pixel is fitted too. Profiles
//! that do not fit (a holder, a highlight at the rim, clipped pixels) are left out (`edges`).
//!
//! Highlight position: the half-peak region chooses the highlight; its lobe is then followed down
//! to a few percent of the peak above the sphere's own radiance (estimated per ring around the
//! centre, so the brightening rim does not count), every pixel weighted by that excess. Its
//! tails carry the sub-pixel position a half-peak cut would throw away.
//! Depends on `geometry::camera` and `render::image` only; pure, no I/O.

mod edges;
mod highlight;
mod mirror;
mod outline;
mod rim;
mod scale;
mod seed;
mod uncertainty;

pub use crate::geometry::reflect;
pub use edges::detect_outline;
pub use highlight::{Highlight, find_highlight};
pub use mirror::{SphereLight, light_from_sphere};
pub use outline::{OutlineSource, SphereOutline};

use crate::geometry::camera::Intrinsics;
use crate::render::image::LinearImage;
use thiserror::Error;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum SphereError {
    #[error("no sphere found: {reason}")]
    NoSphere { reason: String },
    #[error(
        "the sphere is cut by the frame edge (outline centre ({cx:.1}, {cy:.1}) px, radius \
         {radius_px:.1} px, image {width}x{height}): frame the whole sphere"
    )]
    SphereCut {
        cx: f64,
        cy: f64,
        radius_px: f64,
        width: usize,
        height: usize,
    },
    #[error("no highlight on the sphere: {reason}")]
    NoHighlight { reason: String },
    #[error(
        "the highlight at ({x:.1}, {y:.1}) px lies on the sphere's rim (its normal {normal_from_view_deg:.0} \
         deg from the view), where a pixel spans degrees of normal: the light is nearly behind \
         the sphere; move the light or the camera so that the highlight falls inside the outline"
    )]
    HighlightAtRim {
        x: f64,
        y: f64,
        normal_from_view_deg: f64,
    },
    #[error(
        "the brightest region (centroid ({x:.1}, {y:.1}) px) lies outside the sphere (outline \
         centre ({cx:.1}, {cy:.1}) px, radius {radius_px:.1} px): mask or remove the other \
         bright object, or check that the outline image matches the light image"
    )]
    HighlightOutsideSphere {
        x: f64,
        y: f64,
        cx: f64,
        cy: f64,
        radius_px: f64,
    },
    #[error("{what} is {got_w}x{got_h} pixels but the intrinsics are for {want_w}x{want_h}")]
    SizeMismatch {
        what: String,
        got_w: usize,
        got_h: usize,
        want_w: usize,
        want_h: usize,
    },
    #[error("invalid outline circle: {reason}")]
    InvalidCircle { reason: String },
}

/// Tuning of the sphere detection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereOptions {
    /// Value at or above which a channel is clipped (see `calib::clip` for where it comes
    /// from). `None`: nothing is clipped (linear HDR input); never guessed from the pixels.
    pub saturation: Option<f32>,
    /// Smallest sphere radius, in pixels, worth considering.
    pub min_radius_px: f64,
    /// Normal-incidence Fresnel reflectance of the sphere's surface: below 0.5 (0.04 for black
    /// glossy plastic or glass) its rim fades into the backdrop and the outline is fitted with
    /// that fade (`rim`); `None` (or a metal's, 0.5 and above): the outline is a plain step, as
    /// for a matte outline image or a chrome sphere. The fade's shape depends only weakly on the
    /// value below 0.5.
    pub rim_fresnel_f0: Option<f64>,
}

impl Default for SphereOptions {
    fn default() -> Self {
        Self {
            saturation: None,
            min_radius_px: 8.0,
            rim_fresnel_f0: Some(0.04),
        }
    }
}

fn check_size(img: &LinearImage, intr: &Intrinsics, what: &str) -> Result<(), SphereError> {
    if img.width() != intr.width || img.height() != intr.height {
        return Err(SphereError::SizeMismatch {
            what: what.into(),
            got_w: img.width(),
            got_h: img.height(),
            want_w: intr.width,
            want_h: intr.height,
        });
    }
    Ok(())
}
