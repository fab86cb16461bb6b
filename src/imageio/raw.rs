//! Camera RAW files to linear images: decoding by rawloader, then black level, white level,
//! white balance and a bilinear demosaic here. The one owner of RAW decoding: `imageio` reads
//! RAW files named in jobs and calibration commands through it, and the DSLR backend
//! (`devices::camera_gphoto2`) decodes its downloads with it.
//!
//! Output: camera-native RGB (no colour matrix), white-balanced with the camera's as-shot
//! coefficients (rawloader's `wb_coeffs`, from the file's as-shot white balance) normalised to
//! green, scaled so that the sensor's white level is 1.0 in the green channel. Linear in
//! radiance, as reconstruction needs; the colour space stays the camera's, which is fine because
//! the BRDF is recovered per channel and divided by the white reference measured with the same
//! camera (and the same white balance: keep it fixed, not automatic, over a session).
//! The image is the sensor's active area (rawloader's crops), in sensor orientation (the file's
//! orientation flag is not applied): it must match the camera model the photogrammetry found.
//!
//! Clipping: a photosite at or above the white level reads as its channel's clip level (`wb[c]`,
//! the white level times the white balance), so "any channel at or above
//! [`LinearRaw::saturation`]" (the smallest of them) finds the clipped photosites' own pixels. A
//! channel the demosaic interpolates from a clipped and an unclipped neighbour is their mean,
//! below the clip level and low, and is not flagged, as in a 16-bit TIFF from a RAW converter.
//! Flagging those too (raising them to the clip level) was tried and measured: it moved the
//! sphere's highlight centroid, the light direction from a DNG went from 0.017 to 0.098 deg off
//! the same images' EXR (`tests/raw_input.rs`, calibrate), so it is not done.
//!
//! Errors name the file; a corrupt or truncated file is an error, never a panic: a TIFF-based
//! file cut short is refused before decoding (`tiff_extent`), and rawloader catches its
//! decoders' panics on other corrupt data (the default panic hook still prints them to stderr).
//! Depends on rawloader, rayon and `render::image` only; no devices.

use super::ImageIoError;
use crate::render::image::LinearImage;
use rawloader::{RawImage, RawImageData};
use rayon::prelude::*;
use std::path::Path;

/// File extensions (lower case) of the RAW formats rawloader 0.37 decodes.
pub const RAW_EXTENSIONS: [&str; 24] = [
    "dng", "cr2", "crw", "nef", "nrw", "arw", "srf", "sr2", "orf", "rw2", "rwl", "raf", "pef",
    "srw", "erf", "kdc", "dcs", "dcr", "mef", "mos", "mrw", "iiq", "3fr", "ari",
];

/// Whether a (lower-case) extension names a RAW format rawloader decodes.
pub fn is_raw_extension(ext: &str) -> bool {
    RAW_EXTENSIONS.contains(&ext)
}

/// A linear image with the value at which a pixel counts as saturated.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearRaw {
    pub image: LinearImage,
    /// The smallest channel clip level (see the module header): a pixel with any channel at or
    /// above it may be clipped.
    pub saturation: f32,
    pub make: String,
    pub model: String,
}

/// Decodes a RAW file (any format rawloader reads: DNG, CR2, NEF, ARW, ...).
pub fn decode_raw_file(path: &Path) -> Result<LinearRaw, ImageIoError> {
    // the file's bytes are dropped before the larger linear image is made
    let raw = {
        let bytes = std::fs::read(path).map_err(|source| ImageIoError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        decode_sensor_data(&bytes, path)?
    };
    linearise_named(&raw, path)
}

/// Decodes RAW bytes held in memory; `name` is used in errors.
pub fn decode_raw_bytes(bytes: &[u8], name: &str) -> Result<LinearRaw, ImageIoError> {
    linearise_named(
        &decode_sensor_data(bytes, Path::new(name))?,
        Path::new(name),
    )
}

/// rawloader's decoding. A file cut short is refused before rawloader sees it
/// ([`super::tiff_extent`]): some of its decoders would fill the missing rows with zeros.
fn decode_sensor_data(bytes: &[u8], path: &Path) -> Result<RawImage, ImageIoError> {
    let decode_error = |message: String| ImageIoError::Decode {
        path: path.to_path_buf(),
        message,
    };
    super::tiff_extent::check(bytes).map_err(|e| decode_error(e.to_string()))?;
    rawloader::decode(&mut std::io::Cursor::new(bytes))
        .map_err(|e| decode_error(format!("not a RAW file rawloader can decode: {e}")))
}

fn linearise_named(raw: &RawImage, path: &Path) -> Result<LinearRaw, ImageIoError> {
    linearise(raw).map_err(|e| ImageIoError::Unsupported {
        path: path.to_path_buf(),
        message: format!("RAW file: {e}"),
    })
}

/// White-balance multipliers normalised to green; NaN (unknown) becomes 1.
fn wb_normalised(raw: &RawImage) -> [f32; 4] {
    let wb = raw.wb_coeffs;
    let known = |v: f32| v.is_finite() && v > 0.0;
    let g = if known(wb[1]) { wb[1] } else { 1.0 };
    let mut out = wb.map(|v| if known(v) { v / g } else { 1.0 });
    // A fourth colour (second green, "E") takes green's factor when it has none.
    if !known(wb[3]) {
        out[3] = out[1];
    }
    out
}

/// What a decoded RAW image holds that [`linearise`] cannot use.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RawLayoutError {
    #[error("crop {crops:?} leaves no pixels of {width}x{height}")]
    Crop {
        crops: [usize; 4],
        width: usize,
        height: usize,
    },
    #[error("{0} components per pixel are not supported")]
    Components(usize),
    #[error("{len} samples for a {width}x{height}x{cpp} image")]
    Samples {
        len: usize,
        width: usize,
        height: usize,
        cpp: usize,
    },
    #[error("single-channel RAW without a colour filter pattern")]
    NoPattern,
    #[error("pixel count does not match the size")]
    PixelCount,
}

/// Black/white level, white balance and bilinear demosaic of a Bayer (or any periodic CFA)
/// `RawImage`; 3-channel linear RAWs are only levelled and balanced.
pub fn linearise(raw: &RawImage) -> Result<LinearRaw, RawLayoutError> {
    let [top, right, bottom, left] = raw.crops;
    if left + right >= raw.width || top + bottom >= raw.height {
        return Err(RawLayoutError::Crop {
            crops: raw.crops,
            width: raw.width,
            height: raw.height,
        });
    }
    let (w, h) = (raw.width - left - right, raw.height - top - bottom);
    let cpp = raw.cpp;
    if cpp != 1 && cpp != 3 {
        return Err(RawLayoutError::Components(cpp));
    }
    let len = match &raw.data {
        RawImageData::Integer(v) => v.len(),
        RawImageData::Float(v) => v.len(),
    };
    if len < raw.width * raw.height * cpp {
        return Err(RawLayoutError::Samples {
            len,
            width: raw.width,
            height: raw.height,
            cpp,
        });
    }
    let wb = wb_normalised(raw);
    // Per CFA colour: (value - black) / (white - black), clipped to [0, 1], times the white
    // balance; a sample at or above the white level reads exactly `wb[c]`, its clip level.
    let black = raw.blacklevels.map(f32::from);
    let range: [f32; 4] =
        std::array::from_fn(|c| (f32::from(raw.whitelevels[c]) - black[c]).max(1.0));
    // The colour (0..=3) of every sample of a row, one row per row of the CFA's period (for
    // 3-component data: the component), so the per-sample loops only index.
    let colours: Vec<Vec<u8>> = if cpp == 3 {
        vec![(0..w * 3).map(|i| (i % 3) as u8).collect()]
    } else {
        let cfa = raw.cropped_cfa();
        if !cfa.is_valid() {
            return Err(RawLayoutError::NoPattern);
        }
        (0..cfa.height.max(1))
            .map(|y| (0..w).map(|x| cfa.color_at(y, x).min(3) as u8).collect())
            .collect()
    };
    // Levelled samples of the active area, rows in parallel. In bounds: the data holds
    // width x height x cpp samples (checked above).
    let mut levelled = vec![0f32; w * h * cpp];
    levelled
        .par_chunks_mut(w * cpp)
        .enumerate()
        .for_each(|(y, row)| {
            let from = ((y + top) * raw.width + left) * cpp;
            let samples = from..from + w * cpp;
            let row_colours = &colours[y % colours.len()];
            let mut put = |i: usize, v: f32| {
                let c = usize::from(row_colours[i]);
                row[i] = ((v - black[c]) / range[c]).clamp(0.0, 1.0) * wb[c];
            };
            match &raw.data {
                RawImageData::Integer(d) => d[samples]
                    .iter()
                    .enumerate()
                    .for_each(|(i, &v)| put(i, f32::from(v))),
                RawImageData::Float(d) => {
                    d[samples].iter().enumerate().for_each(|(i, &v)| put(i, v))
                }
            }
        });
    let image = if cpp == 3 {
        LinearImage::from_rgb(w, h, levelled).ok_or(RawLayoutError::PixelCount)?
    } else {
        // the 4th colour counts as green
        let channels: Vec<Vec<u8>> = colours
            .iter()
            .map(|r| r.iter().map(|&c| if c == 3 { 1 } else { c }).collect())
            .collect();
        demosaic_bilinear(&levelled, w, h, &channels).ok_or(RawLayoutError::PixelCount)?
    };
    Ok(LinearRaw {
        image,
        saturation: wb[0].min(wb[1]).min(wb[2]),
        make: raw.clean_make.clone(),
        model: raw.clean_model.clone(),
    })
}

/// Bilinear demosaic, rows in parallel: each missing colour is the mean of the 3x3 neighbours
/// that carry it. `channels[y % channels.len()][x]` is the colour (0, 1, 2) of photosite (x, y).
fn demosaic_bilinear(
    mosaic: &[f32],
    w: usize,
    h: usize,
    channels: &[Vec<u8>],
) -> Option<LinearImage> {
    let period = channels.len().max(1);
    let mut data = vec![0f32; w * h * 3];
    data.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
        let rows = y.saturating_sub(1)..(y + 2).min(h);
        let own_row = &channels[y % period];
        for x in 0..w {
            let mut sum = [0f32; 3];
            let mut n = [0u32; 3];
            let cols = x.saturating_sub(1)..(x + 2).min(w);
            for yy in rows.clone() {
                let colours = &channels[yy % period][cols.clone()];
                let values = &mosaic[yy * w + cols.start..yy * w + cols.end];
                for (&c, &v) in colours.iter().zip(values) {
                    sum[usize::from(c)] += v;
                    n[usize::from(c)] += 1;
                }
            }
            let own = usize::from(own_row[x]);
            for c in 0..3 {
                row[x * 3 + c] = if c == own {
                    mosaic[y * w + x]
                } else if n[c] > 0 {
                    sum[c] / n[c] as f32
                } else {
                    0.0
                };
            }
        }
    });
    LinearImage::from_rgb(w, h, data)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use crate::imageio::dng::{BayerEncoding, dng_from_image, write_minimal_dng};

    /// A synthetic scene in linear RGB, mosaicked RGGB with levels and white balance undone,
    /// written as a DNG, decoded by rawloader and linearised: the scene must come back.
    #[test]
    fn dng_round_trip_recovers_a_linear_scene() {
        let (w, h) = (16usize, 12usize);
        // smooth, so bilinear interpolation is nearly exact in the interior
        let scene = |x: usize, y: usize| -> [f32; 3] {
            let r = 0.2 + 0.02 * x as f32;
            let g = 0.3 + 0.01 * y as f32;
            let b = 0.1 + 0.005 * (x + y) as f32;
            [r, g, b]
        };
        let mut img = LinearImage::new(w, h);
        for y in 0..h {
            for x in 0..w {
                img.set(x, y, scene(x, y));
            }
        }
        // Camera response to grey is (0.5, 1, 0.625) of green: AsShotNeutral = that, wb = 1/that.
        let enc = BayerEncoding {
            black: 512,
            white: 15_000,
            as_shot_neutral: [0.5, 1.0, 0.625],
            full_scale: 1.0,
        };
        let dng = dng_from_image(&img, &enc);
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("shot.dng");
        std::fs::write(&path, &dng).unwrap();
        let lin = decode_raw_file(&path).unwrap();
        assert_eq!((lin.image.width(), lin.image.height()), (w, h));
        assert_eq!(lin.model, "test sensor");
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let got = lin.image.get(x, y);
                let want = scene(x, y);
                for c in 0..3 {
                    assert!(
                        (got[c] - want[c]).abs() < 2e-3,
                        "({x},{y}) channel {c}: {} vs {}",
                        got[c],
                        want[c]
                    );
                }
            }
        }
        // saturation: the smallest white-balanced clip level (green = 1 here, red 2, blue 1.6)
        assert!((lin.saturation - 1.0).abs() < 1e-6);
        // a file cut in its header or in its pixels is an error naming the file, not a panic
        for cut in [100, dng.len() / 2] {
            let err = decode_raw_bytes(&dng[..cut], "cut.dng")
                .unwrap_err()
                .to_string();
            assert!(err.contains("cut.dng"), "{err}");
        }
        let err = decode_raw_file(&tmp.path().join("none.dng")).unwrap_err();
        assert!(matches!(err, ImageIoError::Read { .. }), "{err}");
        assert!(err.to_string().contains("none.dng"), "{err}");
    }

    #[test]
    fn black_and_white_levels_clip() {
        let dng = write_minimal_dng(4, 4, &[100; 16], 200, 1000, [1.0, 1.0, 1.0]);
        let lin = decode_raw_bytes(&dng, "dark.dng").unwrap();
        assert!(lin.image.data().iter().all(|&v| v == 0.0));
        let dng = write_minimal_dng(4, 4, &[4000; 16], 200, 1000, [1.0, 1.0, 1.0]);
        let lin = decode_raw_bytes(&dng, "bright.dng").unwrap();
        assert!(lin.image.data().iter().all(|&v| (v - 1.0).abs() < 1e-6));
    }
}
