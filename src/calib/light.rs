//! Light direction from one or more sphere images, combined with an uncertainty. This is the
//! entry point a capture session calls ([`calibrate_light`]).
//!
//! Conventions: as `calib` (camera axes, unit vectors towards the light). Uncertainties are
//! RMS angles to the truth (`calib::sphere::uncertainty`), like the spread of several images.
//! Several images (the sphere moved, or re-shot) are combined by an inverse-variance weighted
//! mean of their unit vectors; the reported uncertainty is the larger of the standard error from
//! their scatter and the images' own (model-based) uncertainty, so one image still gets an
//! honest figure and several images cannot claim less than they scatter. Pure: no I/O.

use super::sphere::{self, SphereError, SphereLight, SphereOptions, SphereOutline};
use crate::geometry::camera::Intrinsics;
use crate::render::image::LinearImage;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use thiserror::Error;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum LightError {
    #[error("no sphere image given")]
    NoImages,
    #[error("sphere image {index}: {source}")]
    Image {
        index: usize,
        #[source]
        source: SphereError,
    },
}

impl LightError {
    /// The index of the image at fault, for callers that name files.
    pub fn image_index(&self) -> Option<usize> {
        match self {
            Self::Image { index, .. } => Some(*index),
            Self::NoImages => None,
        }
    }
}

/// Where the sphere's outline comes from for one light image.
#[derive(Clone, Copy, Debug)]
pub enum OutlineInput<'a> {
    /// Detected in the light image itself (its backdrop must be lit).
    FromLightImage,
    /// Detected in a second image from the same camera (ambient light).
    Image(&'a LinearImage),
    /// Given by the user: centre and radius in pixels.
    Circle { cx: f64, cy: f64, radius_px: f64 },
}

/// One sphere shot: the single-light image and its outline source.
#[derive(Clone, Copy, Debug)]
pub struct SphereShot<'a> {
    pub light: &'a LinearImage,
    pub outline: OutlineInput<'a>,
}

/// The light direction in camera axes with its uncertainty.
#[derive(Clone, Debug, PartialEq)]
pub struct LightCalibration {
    /// Unit vector towards the light, camera axes (x right, y down, z forward).
    pub dir_camera: Vector3<f64>,
    /// Reported standard uncertainty: max(std_error_deg, fit_uncertainty_deg).
    pub uncertainty_deg: f64,
    /// Sample standard deviation of the per-image directions about the mean (0 for one image).
    pub spread_deg: f64,
    /// `spread_deg / sqrt(n)`.
    pub std_error_deg: f64,
    /// The images' own uncertainties (outline, highlight, lobe shape), combined.
    pub fit_uncertainty_deg: f64,
    pub per_image: Vec<SphereLight>,
}

/// What a capture session stores of a [`LightCalibration`] (plain numbers, serde).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LightSummary {
    /// Unit vector towards the light, camera axes (x right, y down, z forward).
    pub dir_camera: [f64; 3],
    pub uncertainty_deg: f64,
    pub spread_deg: f64,
    pub std_error_deg: f64,
    pub fit_uncertainty_deg: f64,
    pub images: usize,
}

impl LightCalibration {
    pub fn summary(&self) -> LightSummary {
        let d = self.dir_camera;
        LightSummary {
            dir_camera: [d.x, d.y, d.z],
            uncertainty_deg: self.uncertainty_deg,
            spread_deg: self.spread_deg,
            std_error_deg: self.std_error_deg,
            fit_uncertainty_deg: self.fit_uncertainty_deg,
            images: self.per_image.len(),
        }
    }
}

/// Measures the light direction from each shot and combines them.
pub fn calibrate_light(
    shots: &[SphereShot<'_>],
    intr: &Intrinsics,
    opts: &SphereOptions,
) -> Result<LightCalibration, LightError> {
    if shots.is_empty() {
        return Err(LightError::NoImages);
    }
    let mut per_image = Vec::with_capacity(shots.len());
    for (index, shot) in shots.iter().enumerate() {
        let at = |source| LightError::Image { index, source };
        let started = std::time::Instant::now();
        let outline = match shot.outline {
            OutlineInput::FromLightImage => sphere::detect_outline(shot.light, intr, opts),
            OutlineInput::Image(img) => sphere::detect_outline(img, intr, opts),
            OutlineInput::Circle { cx, cy, radius_px } => {
                SphereOutline::from_circle(cx, cy, radius_px, intr)
            }
        }
        .map_err(at)?;
        let outline_secs = started.elapsed().as_secs_f64();
        let mut one = sphere::light_from_sphere(shot.light, &outline, intr, opts).map_err(at)?;
        one.outline_secs = outline_secs;
        per_image.push(one);
    }
    Ok(combine(per_image))
}

/// Inverse-variance weighted mean direction and its uncertainty.
pub fn combine(per_image: Vec<SphereLight>) -> LightCalibration {
    let weight = |s: &SphereLight| 1.0 / s.uncertainty_rad.max(1e-6).powi(2);
    let sum = per_image
        .iter()
        .fold(Vector3::zeros(), |a, s| a + s.dir_camera * weight(s));
    let dir = sum.normalize();
    let n = per_image.len() as f64;
    let angles: Vec<f64> = per_image
        .iter()
        .map(|s| s.dir_camera.dot(&dir).clamp(-1.0, 1.0).acos())
        .collect();
    let spread = if per_image.len() > 1 {
        (angles.iter().map(|a| a * a).sum::<f64>() / (n - 1.0)).sqrt()
    } else {
        0.0
    };
    let total_weight: f64 = per_image.iter().map(weight).sum();
    let fit = (1.0 / total_weight).sqrt();
    let se = spread / n.sqrt();
    LightCalibration {
        dir_camera: dir,
        uncertainty_deg: se.max(fit).to_degrees(),
        spread_deg: spread.to_degrees(),
        std_error_deg: se.to_degrees(),
        fit_uncertainty_deg: fit.to_degrees(),
        per_image,
    }
}
