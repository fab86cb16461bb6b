//! Observations: one per usable pixel of a single-light image, carrying what the rest of the
//! reconstruction needs (directions, reflectance, MERL bin, curvature).
//!
//! Conventions: every direction is a unit vector in the world (photogrammetry) frame, pointing
//! away from the surface: `light` towards the light, `view` towards the camera centre; `normal`
//! is the rasterised (interpolated) mesh normal, flipped to face the camera. The light direction
//! of a job is given in camera axes and carried to the world by the inverse camera rotation
//! (`Pose::dir_to_world`), which is how a turntable capture is seen from the object.
//! Reflectance `r = I / (E cos theta_i)` per channel (1/sr when I is radiance and E irradiance).
//! Rusinkiewicz angles use a local frame with the normal as +z and any tangent (the BRDF is
//! isotropic; `render::frame`), then `brdf::coords`.
//!
//! Pure: the surface samples come from the rasteriser, the image and mask from the loader.

pub use super::observation::{NO_FACE, Observation, Seen, to_local};
use super::reduce::Reduction;

use crate::render::image::LinearImage;
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// What the rasteriser knows about the surface seen through one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePixel {
    pub x: u32,
    pub y: u32,
    pub position: Point3<f64>,
    /// Unit normal, world frame (any orientation; it is flipped to face the camera).
    pub normal: Vector3<f64>,
    /// Mean curvature H = (k1 + k2) / 2, in 1 / (mesh unit).
    pub mean_curvature: f64,
    /// The mesh face seen ([`NO_FACE`] when not from a mesh).
    pub face: u32,
    /// Whether the light reaches this point (shadow ray not blocked).
    pub lit: bool,
}

/// Thresholds for keeping a pixel.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObserveSettings {
    /// Drop pixels with cos(theta_i) or cos(theta_o) below this (grazing: normal errors and
    /// foreshortening dominate there). Default cos(80 deg).
    pub min_cos: f64,
    /// Drop a pixel when any channel reaches this value (clipped); `None` = never (HDR input).
    pub saturation: Option<f64>,
    /// Drop a pixel whose mean value is at or below this fraction of the image's maximum mean
    /// (black: no signal, and the log mapping of the basis needs positive values).
    pub black_fraction: f64,
    /// Thin out redundant pixels per light image (`reduce`); `None` = keep every pixel.
    pub reduce: Option<Reduction>,
}

impl Default for ObserveSettings {
    fn default() -> Self {
        Self {
            min_cos: 80f64.to_radians().cos(),
            saturation: None,
            black_fraction: 1e-4,
            reduce: Some(Reduction::default()),
        }
    }
}

/// Pixels dropped, by reason. Each pixel is counted once, under the first reason that applies,
/// tested in this order: masked out, invalid, turned away from the light (shadowed), grazing,
/// saturated, black, redundant, cast shadow (shadowed: the shadow ray, the costly test, is cast
/// only for a pixel that would otherwise be kept).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct DropCounts {
    pub masked_out: usize,
    pub shadowed: usize,
    pub grazing: usize,
    pub saturated: usize,
    pub black: usize,
    /// NaN or infinite pixel values or geometry.
    pub invalid: usize,
    /// Left out by the reduction (`reduce`): their (MERL bin, image region) cell was full.
    pub redundant: usize,
}

/// One light image's pixel counts.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageCounts {
    pub file: PathBuf,
    /// Pixels where the mesh is seen.
    pub covered: usize,
    pub observed: usize,
    pub dropped: DropCounts,
}

/// Why a pixel was dropped before its shadow ray (see [`DropCounts`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dropped {
    MaskedOut,
    /// Turned away from the light (cast shadows need the shadow ray).
    Shadowed,
    Invalid,
    Grazing,
    Saturated,
    Black,
}

impl DropCounts {
    pub fn add(&mut self, o: &DropCounts) {
        self.masked_out += o.masked_out;
        self.shadowed += o.shadowed;
        self.grazing += o.grazing;
        self.saturated += o.saturated;
        self.black += o.black;
        self.invalid += o.invalid;
        self.redundant += o.redundant;
    }

    /// Counts one pixel under `reason`.
    pub fn count(&mut self, reason: Dropped) {
        match reason {
            Dropped::MaskedOut => self.masked_out += 1,
            Dropped::Shadowed => self.shadowed += 1,
            Dropped::Invalid => self.invalid += 1,
            Dropped::Grazing => self.grazing += 1,
            Dropped::Saturated => self.saturated += 1,
            Dropped::Black => self.black += 1,
        }
    }

    pub fn total(&self) -> usize {
        self.masked_out
            + self.shadowed
            + self.grazing
            + self.saturated
            + self.black
            + self.invalid
            + self.redundant
    }
}

/// Everything known about one light image before observations are made.
pub struct ViewInput<'a> {
    pub image_index: usize,
    pub image: &'a LinearImage,
    /// Per pixel, row-major; `true` = material. `None` = everything is material.
    pub mask: Option<&'a [bool]>,
    pub camera_centre: Point3<f64>,
    /// Unit direction towards the light, world frame.
    pub light_world: Vector3<f64>,
    pub irradiance: [f64; 3],
}

/// The black level of a view: `black_fraction` of the largest mean pixel value over the
/// pixels where the mesh is seen (`values`: their mean values).
pub fn black_level(values: impl Iterator<Item = f32>, settings: &ObserveSettings) -> f64 {
    let max_mean = values
        .map(f64::from)
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    max_mean * settings.black_fraction
}

/// Every test of one pixel but the shadow ray: its observation, or why it is dropped.
/// `black`: the view's [`black_level`].
pub fn check_pixel(
    input: &ViewInput<'_>,
    s: &SurfacePixel,
    settings: &ObserveSettings,
    black: f64,
) -> Result<Observation, Dropped> {
    let img = input.image;
    let (px, py) = (s.x as usize, s.y as usize);
    if let Some(mask) = input.mask
        && !mask.get(py * img.width() + px).copied().unwrap_or(false)
    {
        return Err(Dropped::MaskedOut);
    }
    let rgb = img.get(px, py).map(f64::from);
    let view = input.camera_centre - s.position;
    let finite = rgb.iter().all(|v| v.is_finite())
        && s.normal.iter().all(|v| v.is_finite())
        && view.iter().all(|v| v.is_finite());
    if !finite {
        return Err(Dropped::Invalid);
    }
    let view = view.normalize();
    let mut normal = s.normal;
    if normal.dot(&view) < 0.0 {
        normal = -normal;
    }
    let cos_i = normal.dot(&input.light_world);
    let cos_o = normal.dot(&view);
    if cos_i <= 0.0 {
        // turned away from the light: in its own shadow, no ray needed
        return Err(Dropped::Shadowed);
    }
    if cos_i < settings.min_cos || cos_o < settings.min_cos {
        return Err(Dropped::Grazing);
    }
    if let Some(sat) = settings.saturation
        && rgb.iter().any(|&v| v >= sat)
    {
        return Err(Dropped::Saturated);
    }
    let mean = (rgb[0] + rgb[1] + rgb[2]) / 3.0;
    if mean <= black || rgb.iter().any(|&v| v <= 0.0) {
        return Err(Dropped::Black);
    }
    Observation::new(
        Seen {
            image: input.image_index,
            x: s.x,
            y: s.y,
            position: s.position,
            normal,
            mean_curvature: s.mean_curvature,
            face: s.face,
        },
        input.light_world,
        view,
        rgb,
        input.irradiance,
    )
    .ok_or(Dropped::Grazing)
}

/// Which of `surface` lie at least `margin` pixels inside the lit surface: every pixel of the
/// (2 margin + 1)^2 square around them is a lit surface pixel of this view. Where the mesh's
/// positions are off by a little, the pixels at its silhouette and at its cast shadows' edges
/// see background or shadow in the image (the refinement leaves them out). `margin` 0: all.
pub fn inside_lit_surface(surface: &[SurfacePixel], margin: usize) -> Vec<bool> {
    if margin == 0 {
        return vec![true; surface.len()];
    }
    let width = surface.iter().map(|s| s.x as usize + 1).max().unwrap_or(0);
    let height = surface.iter().map(|s| s.y as usize + 1).max().unwrap_or(0);
    let mut lit = vec![false; width * height];
    for s in surface.iter().filter(|s| s.lit) {
        lit[s.y as usize * width + s.x as usize] = true;
    }
    let m = margin as i64;
    let is_lit = |x: i64, y: i64| {
        x >= 0
            && y >= 0
            && (x as usize) < width
            && (y as usize) < height
            && lit[y as usize * width + x as usize]
    };
    surface
        .iter()
        .map(|s| {
            let (x, y) = (i64::from(s.x), i64::from(s.y));
            (-m..=m).all(|dy| (-m..=m).all(|dx| is_lit(x + dx, y + dy)))
        })
        .collect()
}

/// Turns the surface pixels of one view into observations, counting what was dropped and why
/// (every pixel; no reduction).
pub fn observe_view(
    input: &ViewInput<'_>,
    surface: &[SurfacePixel],
    settings: &ObserveSettings,
) -> (Vec<Observation>, DropCounts) {
    let img = input.image;
    let black = black_level(
        surface
            .iter()
            .map(|s| img.luminance(s.x as usize, s.y as usize)),
        settings,
    );
    let mut drops = DropCounts::default();
    let mut out = Vec::with_capacity(surface.len());
    for s in surface {
        match check_pixel(input, s, settings, black) {
            Err(reason) => drops.count(reason),
            Ok(_) if !s.lit => drops.shadowed += 1,
            Ok(o) => out.push(o),
        }
    }
    (out, drops)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_pixels_inside_the_lit_surface_are_inside() {
        // a 5x3 surface, the pixel (4, 1) in shadow: with a margin of 1 only (1, 1) and (2, 1)
        // have a lit square around them ((3, 1) touches the shadow)
        let mut surface = Vec::new();
        for y in 0..3u32 {
            for x in 0..5u32 {
                surface.push(SurfacePixel {
                    x,
                    y,
                    position: Point3::origin(),
                    normal: Vector3::z(),
                    mean_curvature: 0.0,
                    face: 0,
                    lit: !(x == 4 && y == 1),
                });
            }
        }
        let inside = inside_lit_surface(&surface, 1);
        let kept: Vec<(u32, u32)> = surface
            .iter()
            .zip(&inside)
            .filter(|(_, k)| **k)
            .map(|(s, _)| (s.x, s.y))
            .collect();
        assert_eq!(kept, vec![(1, 1), (2, 1)]);
        assert!(inside_lit_surface(&surface, 0).iter().all(|k| *k));
        assert!(inside_lit_surface(&[], 2).is_empty());
    }

    #[test]
    fn drops_are_counted_by_reason() {
        let mut img = LinearImage::new(6, 1);
        for x in 0..6 {
            img.set(x, 0, [0.5; 3]);
        }
        img.set(3, 0, [2.0, 0.5, 0.5]); // saturated at 1.0
        img.set(4, 0, [0.0; 3]); // black
        let mask = [false, true, true, true, true, true];
        let input = ViewInput {
            image_index: 0,
            image: &img,
            mask: Some(&mask),
            camera_centre: Point3::new(0.0, 0.0, 10.0),
            light_world: Vector3::z(),
            irradiance: [1.0; 3],
        };
        let px = |x: u32, normal: Vector3<f64>, lit: bool| SurfacePixel {
            x,
            y: 0,
            position: Point3::origin(),
            normal,
            mean_curvature: 0.0,
            face: NO_FACE,
            lit,
        };
        let surface = [
            px(0, Vector3::z(), true),                             // masked out
            px(1, Vector3::z(), false),                            // shadowed
            px(2, Vector3::new(1.0, 0.0, 0.05).normalize(), true), // grazing
            px(3, Vector3::z(), true),                             // saturated
            px(4, Vector3::z(), true),                             // black
            px(5, -Vector3::z(), true), // kept (flipped to face the camera)
        ];
        let settings = ObserveSettings {
            saturation: Some(1.0),
            ..Default::default()
        };
        let (obs, drops) = observe_view(&input, &surface, &settings);
        assert_eq!(obs.len(), 1);
        assert_eq!(obs[0].x, 5);
        assert!((obs[0].normal - Vector3::z()).norm() < 1e-12);
        assert_eq!(
            drops,
            DropCounts {
                masked_out: 1,
                shadowed: 1,
                grazing: 1,
                saturated: 1,
                black: 1,
                invalid: 0,
                redundant: 0
            }
        );
    }
}
