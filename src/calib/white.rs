//! Irradiance of the light, per colour channel, from a white reference board (METHOD.md 1.4).
//!
//! A Lambertian board of albedo `a` under irradiance `E` (measured perpendicular to the light)
//! sends radiance `L = a E cos(theta) / pi` towards every direction, `theta` being the angle
//! between the board normal and the light, so `E = pi L / (a cos(theta))`.
//!
//! - `L` is the board's radiance at the centre of its pixels: a region of interest given by the
//!   user, or the largest bright region (Otsu threshold) eroded by a few pixels to stay off its
//!   edges; a detected region must stand out from the rest of the image by many times its own
//!   pixel noise, so an image with no board in it (noise) is refused. Pixels with a clipped
//!   channel are dropped (the clip level comes from the caller, `calib::clip`, never from the
//!   pixels), then per channel a quadratic surface is fitted robustly (values further than
//!   `reject_k` MAD-sigmas from it are dust, glints below the clip level or hot pixels) and read
//!   at the centre: for an evenly lit board that is the mean, and a light that falls off across
//!   the board does not pull it.
//! - Orientation: the caller gives the board normal (camera axes, the lit face's normal, e.g.
//!   from a fiducial pose or the photogrammetry); without it the board is **assumed to face the
//!   light** (`cos(theta) = 1`) and the result says so. Fitting the normal from the image would
//!   need the board's shape (e.g. its corners and size); that is not done here.
//! - Flat field: the board's bounding box is cut into a 3x3 grid; the spread
//!   `(max - min) / mean` of the cells' robust mean luminance reveals vignetting or an uneven
//!   light, and a warning is raised above `flat_field_warn`.
//!
//! Conventions: camera axes as `calib`; `light_dir` points from the board towards the light.
//! Units of `E` are those of the image times steradians (radiance in, irradiance out). Pure.

use super::regions::{self, Plane};
use super::robust::{RobustMean, robust_mean, robust_surface_centre};
use crate::render::image::LinearImage;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use thiserror::Error;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum WhiteError {
    #[error("albedo {albedo:?}: each channel must be in (0, 1.5]")]
    BadAlbedo { albedo: [f64; 3] },
    #[error("{what} {value:?} is not a usable direction (finite, non-zero)")]
    BadDirection { what: String, value: [f64; 3] },
    #[error(
        "the board normal {normal:?} points away from the camera (z > 0); give the normal of the \
         face the camera sees"
    )]
    NormalAway { normal: [f64; 3] },
    #[error(
        "the light grazes the board (cos(theta) = {cos_theta:.3}); the irradiance would be \
         unreliable: turn the board towards the light"
    )]
    Grazing { cos_theta: f64 },
    #[error(
        "region of interest {roi:?} (x, y, width, height) is not inside the {width}x{height} image"
    )]
    RoiOutside {
        roi: [usize; 4],
        width: usize,
        height: usize,
    },
    #[error("no white board found: {reason}")]
    NoBoard { reason: String },
    #[error("only {usable} usable board pixels ({saturated} clipped of {total}): {advice}")]
    TooFewPixels {
        usable: usize,
        saturated: usize,
        total: usize,
        advice: String,
    },
}

/// Where the board is in the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoardRegion {
    /// Pixels `x..x+width`, `y..y+height`.
    Roi {
        x: usize,
        y: usize,
        width: usize,
        height: usize,
    },
    /// The largest bright region, eroded.
    Detect,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WhiteOptions {
    /// Clip level (see `calib::clip`); `None`: nothing is clipped (linear HDR input). Never
    /// guessed from the pixels: a flat, noiseless board is not a clipped one.
    pub saturation: Option<f32>,
    /// Outlier rejection, in MAD-sigmas from the median.
    pub reject_k: f64,
    /// Erosion of a detected board, in pixels.
    pub erode_px: usize,
    /// Flat-field spread above which a warning is raised.
    pub flat_field_warn: f64,
    /// Fewest usable pixels.
    pub min_pixels: usize,
}

impl Default for WhiteOptions {
    fn default() -> Self {
        Self {
            saturation: None,
            reject_k: 3.5,
            erode_px: 3,
            flat_field_warn: 0.05,
            min_pixels: 50,
        }
    }
}

/// The 3x3 flat-field check.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FlatField {
    /// Robust mean luminance per cell, row-major from the top-left; `None` when a cell holds
    /// too few board pixels.
    pub cells: [Option<f64>; 9],
    /// `(max - min) / mean` over the cells.
    pub spread: f64,
}

/// Irradiance per channel with how it was obtained (serde: what a capture session stores).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IrradianceCalibration {
    /// `E` per channel (R, G, B).
    pub irradiance: [f64; 3],
    /// Standard error of `irradiance` from the pixel scatter (albedo and normal errors excluded).
    pub std_error: [f64; 3],
    /// Robust mean board radiance per channel.
    pub radiance: [f64; 3],
    pub cos_theta: f64,
    /// True when no normal was given and the board was assumed to face the light.
    pub normal_assumed: bool,
    /// Board pixels the fit kept (of those it read: every `sample_stride`-th pixel of every
    /// `sample_stride`-th row of the unclipped board), after rejecting outliers.
    pub pixels_used: usize,
    /// Unclipped board pixels, and the lattice step the fit read them at (1: every pixel).
    pub pixels_on_board: usize,
    pub sample_stride: usize,
    pub pixels_saturated: usize,
    /// Bounding box of the board pixels: x, y, width, height.
    pub region: [usize; 4],
    pub flat_field: FlatField,
    pub warnings: Vec<String>,
    /// Wall time (seconds) of finding the board's pixels and of the fits and checks after.
    #[serde(default)]
    pub detect_secs: f64,
    #[serde(default)]
    pub fit_secs: f64,
}

fn unit(what: &str, v: &Vector3<f64>) -> Result<Vector3<f64>, WhiteError> {
    let n = v.norm();
    if !(n.is_finite() && n > 1e-12) {
        return Err(WhiteError::BadDirection {
            what: what.into(),
            value: [v.x, v.y, v.z],
        });
    }
    Ok(v / n)
}

/// Irradiance per channel from an image of the white board.
pub fn calibrate_irradiance(
    img: &LinearImage,
    albedo: [f64; 3],
    light_dir: &Vector3<f64>,
    normal: Option<&Vector3<f64>>,
    region: &BoardRegion,
    opts: &WhiteOptions,
) -> Result<IrradianceCalibration, WhiteError> {
    if albedo
        .iter()
        .any(|a| !(a.is_finite() && *a > 0.0 && *a <= 1.5))
    {
        return Err(WhiteError::BadAlbedo { albedo });
    }
    let l = unit("light direction", light_dir)?;
    let mut warnings = Vec::new();
    let (cos_theta, normal_assumed) = match normal {
        Some(n) => {
            let n = unit("board normal", n)?;
            if n.z > 0.0 {
                return Err(WhiteError::NormalAway {
                    normal: [n.x, n.y, n.z],
                });
            }
            (n.dot(&l), false)
        }
        None => {
            warnings.push(
                "no board normal given: assumed the board faces the light (cos(theta) = 1)".into(),
            );
            (1.0, true)
        }
    };
    if cos_theta < 0.1 {
        return Err(WhiteError::Grazing { cos_theta });
    }
    let w = img.width();
    let started = std::time::Instant::now();
    let members = board_pixels(img, region, opts)?;
    let detect_secs = started.elapsed().as_secs_f64();
    let sat = opts.saturation;
    let data = img.data();
    let clipped = |i: usize| sat.is_some_and(|s| data[3 * i..3 * i + 3].iter().any(|&v| v >= s));
    // Every board pixel is counted (clipped or not, and the board's extent); the fit and the
    // flat field read a lattice of them when there are more than FIT_PIXELS.
    let saturated = members.iter().filter(|&&i| clipped(i)).count();
    let on_board = members.len() - saturated;
    let stride = sample_stride(members.len());
    let usable: Vec<usize> = members
        .iter()
        .copied()
        .filter(|&i| on_lattice(i, w, stride) && !clipped(i))
        .collect();
    if usable.len() < opts.min_pixels {
        return Err(WhiteError::TooFewPixels {
            usable: usable.len(),
            saturated,
            total: members.len(),
            advice: if saturated * 2 > members.len() {
                "the board is clipped: shorten the exposure or dim the light".into()
            } else {
                "enlarge the region of interest or move the board closer".into()
            },
        });
    }
    let mut means = [RobustMean {
        mean: 0.0,
        std_dev: 0.0,
        std_error: 0.0,
        kept: 0,
        rejected: 0,
    }; 3];
    for (k, m) in means.iter_mut().enumerate() {
        let v: Vec<(f64, f64, f64)> = usable
            .iter()
            .map(|&i| ((i % w) as f64, (i / w) as f64, data[3 * i + k] as f64))
            .collect();
        *m = robust_surface_centre(&v, opts.reject_k).ok_or_else(|| WhiteError::TooFewPixels {
            usable: 0,
            saturated,
            total: members.len(),
            advice: "no consistent board values".into(),
        })?;
    }
    let radiance = means.map(|m| m.mean);
    let irradiance = [0, 1, 2].map(|k| PI * radiance[k] / (albedo[k] * cos_theta));
    let std_error = [0, 1, 2].map(|k| PI * means[k].std_error / (albedo[k] * cos_theta));
    // flat field over the bounding box of the unclipped board pixels
    let unclipped = || members.iter().copied().filter(|&i| !clipped(i));
    let (x0, x1) = minmax(unclipped().map(|i| i % w));
    let (y0, y1) = minmax(unclipped().map(|i| i / w));
    let lum = |i: usize| f64::from(data[3 * i] + data[3 * i + 1] + data[3 * i + 2]) / 3.0;
    let mut cell_values: Vec<Vec<f64>> = vec![Vec::new(); 9];
    let (bw, bh) = ((x1 - x0 + 1) as f64, (y1 - y0 + 1) as f64);
    for &i in &usable {
        let (x, y) = (i % w, i / w);
        let cx = (((x - x0) as f64 / bw * 3.0) as usize).min(2);
        let cy = (((y - y0) as f64 / bh * 3.0) as usize).min(2);
        cell_values[cy * 3 + cx].push(lum(i));
    }
    let min_cell = (usable.len() / 40).max(5);
    let cells: [Option<f64>; 9] = std::array::from_fn(|c| {
        (cell_values[c].len() >= min_cell)
            .then(|| robust_mean(&cell_values[c], opts.reject_k).map(|m| m.mean))
            .flatten()
    });
    let present: Vec<f64> = cells.iter().flatten().copied().collect();
    let spread = if present.len() >= 2 {
        let mean = present.iter().sum::<f64>() / present.len() as f64;
        let (lo, hi) = present
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        (hi - lo) / mean
    } else {
        0.0
    };
    if spread > opts.flat_field_warn {
        warnings.push(format!(
            "the board is not evenly lit or the lens vignettes: the 3x3 cells differ by {:.1} % \
             (warning above {:.1} %); use a smaller board region near the object",
            100.0 * spread,
            100.0 * opts.flat_field_warn
        ));
    }
    if saturated > 0 {
        warnings.push(format!("{saturated} clipped board pixels ignored"));
    }
    Ok(IrradianceCalibration {
        irradiance,
        std_error,
        radiance,
        cos_theta,
        normal_assumed,
        pixels_used: means.iter().map(|m| m.kept).min().unwrap_or(0),
        pixels_on_board: on_board,
        sample_stride: stride,
        pixels_saturated: saturated,
        region: [x0, y0, x1 - x0 + 1, y1 - y0 + 1],
        flat_field: FlatField { cells, spread },
        warnings,
        detect_secs,
        fit_secs: started.elapsed().as_secs_f64() - detect_secs,
    })
}

/// Most board pixels the surface fit and the flat-field check read; a larger board is read on
/// a lattice (every `s`-th pixel of every `s`-th row). More add nothing a calibration can use:
/// the standard error of the radiance from 250 000 pixels of 1 % noise is 2e-5 of it, far
/// below an albedo's uncertainty, and a 24 MP board holds 4.5 million (the fit over all of them
/// took 4 s).
const FIT_PIXELS: usize = 250_000;

/// The lattice step for `n` board pixels: 1 up to [`FIT_PIXELS`].
fn sample_stride(n: usize) -> usize {
    if n <= FIT_PIXELS {
        1
    } else {
        (n as f64 / FIT_PIXELS as f64).sqrt().ceil() as usize
    }
}

/// True when pixel `i` of a `w`-wide image lies on the lattice of step `s`.
fn on_lattice(i: usize, w: usize, s: usize) -> bool {
    s == 1 || ((i % w).is_multiple_of(s) && (i / w).is_multiple_of(s))
}

fn minmax(it: impl Iterator<Item = usize>) -> (usize, usize) {
    it.fold((usize::MAX, 0), |(a, b), v| (a.min(v), b.max(v)))
}

/// Indices of the board pixels.
fn board_pixels(
    img: &LinearImage,
    region: &BoardRegion,
    opts: &WhiteOptions,
) -> Result<Vec<usize>, WhiteError> {
    let (w, h) = (img.width(), img.height());
    match *region {
        BoardRegion::Roi {
            x,
            y,
            width,
            height,
        } => {
            let inside = width > 0
                && height > 0
                && x.checked_add(width).is_some_and(|e| e <= w)
                && y.checked_add(height).is_some_and(|e| e <= h);
            if !inside {
                return Err(WhiteError::RoiOutside {
                    roi: [x, y, width, height],
                    width: w,
                    height: h,
                });
            }
            Ok((y..y + height)
                .flat_map(|yy| (x..x + width).map(move |xx| yy * w + xx))
                .collect())
        }
        BoardRegion::Detect => {
            // A large image: the board is found on its luminance box-downsampled to about
            // DETECT_WIDTH_PX, eroded by its blocks, and read back at full resolution.
            let f = regions::downsample_factor(w, h, DETECT_WIDTH_PX);
            let coarse = Plane::luminance_box_down(img, f);
            let (cw, ch) = (coarse.width, coarse.height);
            let lum = coarse.box3();
            let lo = regions::quantile(&lum.data, 0.0).unwrap_or(0.0);
            let hi = regions::quantile(&lum.data, 0.99).unwrap_or(0.0);
            let thr =
                regions::otsu_threshold(&lum.data, lo, hi).ok_or_else(|| WhiteError::NoBoard {
                    reason: "the image has no contrast".into(),
                })?;
            let mask: Vec<bool> = lum.data.iter().map(|&v| v >= thr).collect();
            let board = regions::components(&mask, cw, ch)
                .into_iter()
                .max_by_key(|c| c.pixels.len())
                .ok_or_else(|| WhiteError::NoBoard {
                    reason: "no bright region".into(),
                })?;
            let filled = regions::filled_mask(&board, cw, ch);
            // a block on the threshold's edge may hold the board's edge: one block more
            let erode = if f == 1 {
                opts.erode_px
            } else {
                opts.erode_px.div_ceil(f) + 1
            };
            let mut member = filled.clone();
            for _ in 0..erode {
                member = erode_mask(&member, cw, ch);
            }
            let coarse_of = |i: usize| {
                let (x, y) = (i % w / f, i / w / f);
                (x < cw && y < ch).then_some(y * cw + x)
            };
            let px: Vec<usize> = (0..w * h)
                .filter(|&i| coarse_of(i).is_some_and(|c| member[c]))
                .collect();
            if px.is_empty() {
                return Err(WhiteError::NoBoard {
                    reason: format!(
                        "the brightest region vanishes after eroding {} px: no solid bright \
                         region stands out (is there a board in the image?); give the board's \
                         region with --roi",
                        opts.erode_px
                    ),
                });
            }
            let in_region = |i: usize| coarse_of(i).is_some_and(|c| filled[c]);
            let board_coarse: Vec<usize> = (0..cw * ch).filter(|&c| member[c]).collect();
            stands_out(img, &coarse, &filled, &board_coarse, &px, in_region)?;
            Ok(px)
        }
    }
}

/// Width (pixels) above which the board is found on a downsampled image, and about the width
/// it is downsampled to: thresholding, labelling and eroding every pixel of a 24 MP image took
/// 2.3 s, and the board's outline needs no more than a pixel in a thousand.
const DETECT_WIDTH_PX: usize = 1000;

/// How far a board must stand out from the rest of the image, in its own pixel noise.
const MIN_BOARD_CONTRAST_SIGMAS: f64 = 8.0;

/// A detected board must stand out from everything outside it by many times the noise of its
/// pixels: the levels are medians over the (possibly downsampled) luminance `lum` of the board
/// (`board`, indices into `lum`) and of what lies outside `region` (before erosion); the noise
/// is from differences of horizontal neighbours at full resolution (a lattice of the board's
/// pixels, `board_px`, whose right neighbour is `in_region`), so a light falling off across
/// the board does not count as noise, and averaging blocks does not hide it. Thresholding pure
/// noise also finds a "largest bright region", whose level differs from the rest by about one
/// noise sigma.
fn stands_out(
    img: &LinearImage,
    lum: &Plane,
    region: &[bool],
    board: &[usize],
    board_px: &[usize],
    in_region: impl Fn(usize) -> bool,
) -> Result<(), WhiteError> {
    let w = img.width();
    let data = img.data();
    let full = |i: usize| (data[3 * i] + data[3 * i + 1] + data[3 * i + 2]) / 3.0;
    let mut inside: Vec<f64> = board.iter().map(|&i| lum.data[i] as f64).collect();
    let mut outside: Vec<f64> = (0..lum.data.len())
        .filter(|&i| !region[i])
        .map(|i| lum.data[i] as f64)
        .collect();
    let stride = sample_stride(board_px.len());
    let diffs: Vec<f64> = board_px
        .iter()
        .filter(|&&i| on_lattice(i, w, stride) && i % w + 1 < w && in_region(i + 1))
        .map(|&i| (full(i + 1) - full(i)) as f64)
        .collect();
    let (Some(level), Some(surround)) = (
        crate::stats::median(&mut inside),
        crate::stats::median(&mut outside),
    ) else {
        // the board fills the frame: nothing to compare with
        return Ok(());
    };
    let noise = super::robust::mad_sigma(&diffs, 0.0).unwrap_or(0.0) / std::f64::consts::SQRT_2;
    let contrast = level - surround;
    if contrast <= MIN_BOARD_CONTRAST_SIGMAS * noise {
        return Err(WhiteError::NoBoard {
            reason: format!(
                "the brightest region (level {level:.4}) stands out from the rest of the image \
                 ({surround:.4}) by {:.1} times its pixel noise ({noise:.4}), where a lit board \
                 stands out by more than {MIN_BOARD_CONTRAST_SIGMAS}: the image looks like noise \
                 or holds no board; check the file, or give the board's region with --roi",
                contrast / noise.max(f64::MIN_POSITIVE)
            ),
        });
    }
    Ok(())
}

/// One step of 4-neighbour erosion; the image border counts as outside.
fn erode_mask(m: &[bool], w: usize, h: usize) -> Vec<bool> {
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            m[i] && x > 0
                && y > 0
                && x + 1 < w
                && y + 1 < h
                && m[i - 1]
                && m[i + 1]
                && m[i - w]
                && m[i + w]
        })
        .collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn uniform_patch_gives_closed_form_irradiance() {
        // L = a E cos / pi with a = 0.5, E = 2, cos = 0.5  =>  L = 0.5 / pi
        let l_val = (0.5 * 2.0 * 0.5 / PI) as f32;
        let img = LinearImage::from_rgb(20, 20, vec![l_val; 20 * 20 * 3]).unwrap();
        let light = Vector3::new(0.0, -(0.75f64.sqrt()), -0.5);
        let normal = Vector3::new(0.0, 0.0, -1.0);
        let roi = BoardRegion::Roi {
            x: 2,
            y: 2,
            width: 16,
            height: 16,
        };
        let r = calibrate_irradiance(
            &img,
            [0.5; 3],
            &light,
            Some(&normal),
            &roi,
            &WhiteOptions::default(),
        )
        .unwrap();
        for e in r.irradiance {
            assert!((e - 2.0).abs() < 1e-5, "{e}");
        }
        assert!(r.flat_field.spread < 1e-6 && r.warnings.is_empty());
        assert!(matches!(
            calibrate_irradiance(
                &img,
                [0.0, 0.5, 0.5],
                &light,
                None,
                &roi,
                &Default::default()
            ),
            Err(WhiteError::BadAlbedo { .. })
        ));
    }

    /// The board detected, albedo 0.8, facing the camera and lit from the camera.
    fn detect_facing(
        img: &LinearImage,
        saturation: Option<f32>,
    ) -> Result<IrradianceCalibration, WhiteError> {
        let n = Vector3::new(0.0, 0.0, -1.0);
        calibrate_irradiance(
            img,
            [0.8; 3],
            &n,
            Some(&n),
            &BoardRegion::Detect,
            &WhiteOptions {
                saturation,
                ..WhiteOptions::default()
            },
        )
    }

    /// A noiseless board on a dark surround, found by detection with no clip level (linear HDR):
    /// its flat plateau is not taken for a clipped one (issue 13: "54595 clipped of 54595").
    #[test]
    fn a_flat_noiseless_board_is_not_clipped() {
        let (w, h) = (120, 90);
        let l_val = (0.8 * 1.5 / PI) as f32;
        let mut data = vec![0.01f32; w * h * 3];
        for y in 20..70 {
            for x in 25..95 {
                data[3 * (y * w + x)..3 * (y * w + x) + 3].fill(l_val);
            }
        }
        let img = LinearImage::from_rgb(w, h, data).unwrap();
        let r = detect_facing(&img, None).unwrap();
        assert_eq!(r.pixels_saturated, 0);
        for e in r.irradiance {
            assert!((e - 1.5).abs() < 1e-5, "{e}");
        }
        // told that the camera clipped at that very level, every board pixel is clipped
        let clipped = detect_facing(&img, Some(l_val)).unwrap_err();
        assert!(clipped.to_string().contains("clipped"), "{clipped}");
    }

    /// Pure noise has a "largest bright region" too; it is refused, saying why (issue 15).
    #[test]
    fn pure_noise_is_not_a_board() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let (w, h) = (160, 120);
        let data: Vec<f32> = (0..w * h * 3).map(|_| rng.gen_range(0.0..0.5)).collect();
        let img = LinearImage::from_rgb(w, h, data).unwrap();
        let e = detect_facing(&img, None).unwrap_err();
        assert!(matches!(e, WhiteError::NoBoard { .. }), "{e}");
        assert!(e.to_string().contains("--roi"), "{e}");
    }
}
