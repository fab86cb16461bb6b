//! Linear radiance from exposure brackets (METHOD.md 1.5: specular peaks clip, so the honest way
//! to keep the brightest pixel is to bracket and merge).
//!
//! - Linear cameras (RAW, or the simulated camera): each value divided by its exposure time is
//!   an estimate of the radiance; a value counts only when it is above `noise_floor` and below
//!   `clip_fraction * saturation`. The estimates are merged as `sum(v) / sum(t)` over the usable
//!   exposures, which is the maximum-likelihood radiance under photon (Poisson) noise and gives
//!   long exposures the weight their better signal-to-noise ratio deserves.
//! - Non-linear cameras (8-bit JPEG/PNG): the response is recovered with Debevec & Malik (1997,
//!   "Recovering high dynamic range radiance maps from photographs"): per channel, unknowns
//!   `g(z) = ln(E t)` for the 256 codes and `ln E_i` for sampled pixels, least squares on
//!   `w(z_ij) (g(z_ij) - ln E_i - ln t_j) = 0`, smoothness `lambda w(z) g''(z) = 0`, `g(128) = 0`,
//!   hat weights `w(z) = min(z, 255 - z)`. Solved by normal equations (Cholesky, nalgebra). The
//!   radiance it gives is relative: one unknown scale per channel, which the white board's
//!   irradiance calibration absorbs when the same curve linearises both.
//!
//! Conventions: exposure in seconds (any consistent unit works), radiance out in image units per
//! second. Pure: no I/O.

use super::clip::ClipLevel;
use crate::render::image::LinearImage;
use nalgebra::{DMatrix, DVector};
use thiserror::Error;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum HdrError {
    #[error("no exposures given")]
    NoImages,
    #[error("exposure {index} is {got_w}x{got_h} but exposure 0 is {want_w}x{want_h}")]
    SizeMismatch {
        index: usize,
        got_w: usize,
        got_h: usize,
        want_w: usize,
        want_h: usize,
    },
    #[error("exposure {index}: exposure time {value} s must be finite and positive")]
    BadExposure { index: usize, value: f64 },
    #[error("need at least {need} exposures with different times, got {got}")]
    TooFewExposures { need: usize, got: usize },
    #[error("the response curve cannot be solved: {reason}")]
    Solve { reason: String },
    #[error("{what}: {reason}")]
    BadOption { what: String, reason: String },
}

/// One linear exposure of a bracket.
#[derive(Clone, Copy, Debug)]
pub struct Exposure<'a> {
    pub image: &'a LinearImage,
    pub exposure_secs: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MergeOptions {
    /// Clip level of the camera (`ShotMetadata::saturation`).
    pub saturation: f32,
    /// Values at or above `clip_fraction * saturation` are treated as clipped.
    pub clip_fraction: f32,
    /// Values at or below this are too close to the noise floor to use.
    pub noise_floor: f32,
}

impl MergeOptions {
    pub fn new(saturation: f32, noise_floor: f32) -> Self {
        Self {
            saturation,
            clip_fraction: 0.98,
            noise_floor,
        }
    }
}

/// A merged radiance image and how many samples had no usable exposure.
#[derive(Clone, Debug, PartialEq)]
pub struct MergedHdr {
    pub image: LinearImage,
    /// Channel samples clipped in every exposure: lower bounds from the shortest exposure.
    pub clipped_everywhere: usize,
    /// Channel samples in the noise in every exposure: `sum(v) / sum(t)` over all exposures.
    pub dark_everywhere: usize,
    /// Where the merged image clips: a value at or above it was clipped in every exposure (a
    /// lower bound); every other value is below it.
    pub clip: ClipLevel,
}

fn check_exposures<T>(
    items: &[T],
    size: impl Fn(&T) -> (usize, usize),
    secs: impl Fn(&T) -> f64,
) -> Result<(), HdrError> {
    let first = items.first().ok_or(HdrError::NoImages)?;
    let (w0, h0) = size(first);
    for (index, it) in items.iter().enumerate() {
        let (w, h) = size(it);
        if (w, h) != (w0, h0) {
            return Err(HdrError::SizeMismatch {
                index,
                got_w: w,
                got_h: h,
                want_w: w0,
                want_h: h0,
            });
        }
        let t = secs(it);
        if !(t.is_finite() && t > 0.0) {
            return Err(HdrError::BadExposure { index, value: t });
        }
    }
    Ok(())
}

/// Merges linear exposures into radiance (`value / exposure`).
pub fn merge_linear(brackets: &[Exposure<'_>], opts: &MergeOptions) -> Result<MergedHdr, HdrError> {
    check_exposures(
        brackets,
        |e| (e.image.width(), e.image.height()),
        |e| e.exposure_secs,
    )?;
    if opts.saturation.partial_cmp(&opts.noise_floor) != Some(std::cmp::Ordering::Greater) {
        return Err(HdrError::BadOption {
            what: "saturation".into(),
            reason: format!(
                "the clip level {} must exceed the noise floor {}",
                opts.saturation, opts.noise_floor
            ),
        });
    }
    let (w, h) = (brackets[0].image.width(), brackets[0].image.height());
    let clip = opts.clip_fraction * opts.saturation;
    let shortest = brackets
        .iter()
        .min_by(|a, b| a.exposure_secs.total_cmp(&b.exposure_secs))
        .ok_or(HdrError::NoImages)?;
    let mut out = LinearImage::new(w, h);
    let (mut clipped_everywhere, mut dark_everywhere) = (0, 0);
    for (i, o) in out.data_mut().iter_mut().enumerate() {
        let (mut sv, mut st) = (0.0f64, 0.0f64);
        let (mut all_sv, mut all_st) = (0.0f64, 0.0f64);
        let mut any_clipped = false;
        for e in brackets {
            let v = e.image.data()[i];
            if v >= clip {
                any_clipped = true;
                continue;
            }
            all_sv += v as f64;
            all_st += e.exposure_secs;
            if v > opts.noise_floor {
                sv += v as f64;
                st += e.exposure_secs;
            }
        }
        *o = if st > 0.0 {
            (sv / st) as f32
        } else if all_st > 0.0 {
            dark_everywhere += 1;
            (all_sv / all_st) as f32
        } else {
            debug_assert!(any_clipped);
            clipped_everywhere += 1;
            (shortest.image.data()[i] as f64 / shortest.exposure_secs) as f32
        };
    }
    Ok(MergedHdr {
        image: out,
        clipped_everywhere,
        dark_everywhere,
        clip: ClipLevel::merged_bracket(
            opts.saturation,
            opts.clip_fraction,
            shortest.exposure_secs,
        ),
    })
}

/// An 8-bit RGB image straight from a non-linear camera (codes, not radiance).
#[derive(Clone, Debug, PartialEq)]
pub struct Rgb8Image {
    pub width: usize,
    pub height: usize,
    /// `width * height * 3` codes, RGB interleaved, row-major.
    pub data: Vec<u8>,
}

/// One 8-bit exposure of a bracket.
#[derive(Clone, Copy, Debug)]
pub struct Exposure8<'a> {
    pub image: &'a Rgb8Image,
    pub exposure_secs: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResponseOptions {
    /// Weight of the smoothness term (Debevec & Malik use tens to hundreds).
    pub lambda: f64,
    /// Pixels sampled per channel (stratified by their value in the middle exposure).
    pub samples: usize,
}

impl Default for ResponseOptions {
    fn default() -> Self {
        Self {
            lambda: 10.0,
            samples: 200,
        }
    }
}

/// Debevec & Malik's hat weight.
pub fn hat(z: u8) -> f64 {
    let z = z as f64;
    if z <= 127.5 { z } else { 255.0 - z }
}

/// A camera response: `g(z) = ln(E t)` per channel, up to one additive constant per channel
/// (`g(128) = 0`).
#[derive(Clone, Debug, PartialEq)]
pub struct ResponseCurve {
    pub log_exposure: [[f64; 256]; 3],
}

impl ResponseCurve {
    /// Relative radiance `exp(g(z)) / t` of one 8-bit image.
    pub fn linearise(&self, img: &Rgb8Image, exposure_secs: f64) -> LinearImage {
        let data = img
            .data
            .iter()
            .enumerate()
            .map(|(i, &z)| (self.log_exposure[i % 3][z as usize].exp() / exposure_secs) as f32)
            .collect();
        LinearImage::from_rgb(img.width, img.height, data)
            .unwrap_or_else(|| LinearImage::new(img.width, img.height))
    }

    /// Merges an 8-bit bracket to relative radiance (Debevec & Malik, eq. 6): a hat-weighted
    /// mean of `g(z) - ln t` in the log domain; a sample clipped or black in every exposure
    /// takes the exposure closest to usable.
    pub fn merge(&self, brackets: &[Exposure8<'_>]) -> Result<LinearImage, HdrError> {
        check_exposures(
            brackets,
            |e| (e.image.width, e.image.height),
            |e| e.exposure_secs,
        )?;
        let (w, h) = (brackets[0].image.width, brackets[0].image.height);
        let mut out = LinearImage::new(w, h);
        for (i, o) in out.data_mut().iter_mut().enumerate() {
            let c = i % 3;
            let (mut num, mut den) = (0.0, 0.0);
            let mut fallback = (f64::MAX, 0.0);
            for e in brackets {
                let z = e.image.data[i];
                let g = self.log_exposure[c][z as usize] - e.exposure_secs.ln();
                let wgt = hat(z);
                num += wgt * g;
                den += wgt;
                // nearest to mid-grey when nothing is usable
                let dist = (z as f64 - 127.5).abs();
                if dist < fallback.0 {
                    fallback = (dist, g);
                }
            }
            *o = (if den > 0.0 { num / den } else { fallback.1 }).exp() as f32;
        }
        Ok(out)
    }

    /// True when `g` increases over the codes `lo..=hi`.
    pub fn is_monotonic(&self, lo: u8, hi: u8) -> bool {
        self.log_exposure
            .iter()
            .all(|g| (lo as usize..hi as usize).all(|z| g[z + 1] > g[z]))
    }
}

/// Recovers the camera response from a bracket of 8-bit images of a static scene.
pub fn recover_response(
    brackets: &[Exposure8<'_>],
    opts: &ResponseOptions,
) -> Result<ResponseCurve, HdrError> {
    check_exposures(
        brackets,
        |e| (e.image.width, e.image.height),
        |e| e.exposure_secs,
    )?;
    let mut times: Vec<f64> = brackets.iter().map(|e| e.exposure_secs).collect();
    times.sort_by(f64::total_cmp);
    times.dedup_by(|a, b| (*a / *b - 1.0).abs() < 1e-9);
    if times.len() < 2 {
        return Err(HdrError::TooFewExposures {
            need: 2,
            got: times.len(),
        });
    }
    if !(opts.lambda.is_finite() && opts.lambda >= 0.0) || opts.samples < 2 {
        return Err(HdrError::BadOption {
            what: "response options".into(),
            reason: format!(
                "lambda {} must be finite and >= 0, samples {} at least 2",
                opts.lambda, opts.samples
            ),
        });
    }
    let npix = brackets[0].image.width * brackets[0].image.height;
    let mut middle: Vec<&Exposure8> = brackets.iter().collect();
    middle.sort_by(|a, b| a.exposure_secs.total_cmp(&b.exposure_secs));
    let mid = middle[middle.len() / 2];
    let mut curve = ResponseCurve {
        log_exposure: [[0.0; 256]; 3],
    };
    for c in 0..3 {
        // stratified samples: evenly spaced in the middle exposure's sorted values
        let mut order: Vec<usize> = (0..npix).collect();
        order.sort_by_key(|&p| mid.image.data[3 * p + c]);
        let n = opts.samples.min(npix);
        let mut picks: Vec<usize> = (0..n)
            .map(|k| order[(k * (npix - 1)) / (n - 1).max(1)])
            .collect();
        picks.dedup();
        // drop samples with no usable code at all (they would leave ln E_i undetermined)
        picks.retain(|&p| brackets.iter().any(|e| hat(e.image.data[3 * p + c]) > 0.0));
        curve.log_exposure[c] = solve_channel(brackets, &picks, c, opts.lambda)?;
    }
    Ok(curve)
}

/// The least-squares system of one channel, by normal equations.
fn solve_channel(
    brackets: &[Exposure8<'_>],
    picks: &[usize],
    c: usize,
    lambda: f64,
) -> Result<[f64; 256], HdrError> {
    let n = 256 + picks.len();
    let mut ata = DMatrix::<f64>::zeros(n, n);
    let mut atb = DVector::<f64>::zeros(n);
    // adds the row `sum coef_k x_k = rhs`
    let mut add = |terms: &[(usize, f64)], rhs: f64| {
        for &(i, a) in terms {
            atb[i] += a * rhs;
            for &(j, b) in terms {
                ata[(i, j)] += a * b;
            }
        }
    };
    for (s, &p) in picks.iter().enumerate() {
        for e in brackets {
            let z = e.image.data[3 * p + c];
            let wgt = hat(z);
            if wgt > 0.0 {
                add(
                    &[(z as usize, wgt), (256 + s, -wgt)],
                    wgt * e.exposure_secs.ln(),
                );
            }
        }
    }
    add(&[(128, 1.0)], 0.0);
    for z in 1..255usize {
        let k = lambda * hat(z as u8);
        add(&[(z - 1, k), (z, -2.0 * k), (z + 1, k)], 0.0);
    }
    // a whisper of ridge keeps codes that no sample reached determined by the smoothness ends
    let ridge = 1e-10 * (0..n).map(|i| ata[(i, i)]).sum::<f64>() / n as f64;
    for i in 0..n {
        ata[(i, i)] += ridge;
    }
    let x = ata
        .cholesky()
        .ok_or_else(|| HdrError::Solve {
            reason: format!("channel {c}: the normal equations are singular (too few samples?)"),
        })?
        .solve(&atb);
    let mut g = [0.0; 256];
    for (z, v) in g.iter_mut().enumerate() {
        *v = x[z];
    }
    if g.iter().any(|v| !v.is_finite()) {
        return Err(HdrError::Solve {
            reason: format!("channel {c}: non-finite solution"),
        });
    }
    Ok(g)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn hat_weights_vanish_at_the_ends() {
        assert_eq!(hat(0), 0.0);
        assert_eq!(hat(255), 0.0);
        assert_eq!(hat(127), 127.0);
        assert_eq!(hat(128), 127.0);
    }

    #[test]
    fn bad_brackets_are_refused() {
        let a = LinearImage::new(4, 4);
        let b = LinearImage::new(4, 5);
        let opts = MergeOptions::new(1.0, 0.01);
        assert!(matches!(merge_linear(&[], &opts), Err(HdrError::NoImages)));
        let e = merge_linear(
            &[
                Exposure {
                    image: &a,
                    exposure_secs: 1.0,
                },
                Exposure {
                    image: &b,
                    exposure_secs: 2.0,
                },
            ],
            &opts,
        );
        assert!(matches!(e, Err(HdrError::SizeMismatch { index: 1, .. })));
        let e = merge_linear(
            &[Exposure {
                image: &a,
                exposure_secs: -1.0,
            }],
            &opts,
        );
        assert!(matches!(e, Err(HdrError::BadExposure { index: 0, .. })));
    }
}
