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
//! the white level times the white balance); a channel the demosaic interpolates from a clipped
//! photosite reads as clipped too (the largest clip level among them), because the mean of a
//! clipped and an unclipped neighbour is a wrong value that looks valid. So "any channel at or
//! above [`LinearRaw::saturation`]" finds every pixel a clipped photosite touched.
//!
//! Errors name the file; a corrupt or truncated file is an error, never a panic (rawloader
//! catches its decoders' panics). Depends on rawloader and `render::image` only; no devices.

use super::ImageIoError;
use crate::render::image::LinearImage;
use rawloader::{RawImage, RawImageData};
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
    let bytes = std::fs::read(path).map_err(|source| ImageIoError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    decode_raw(&bytes, path)
}

/// Decodes RAW bytes held in memory; `name` is used in errors.
pub fn decode_raw_bytes(bytes: &[u8], name: &str) -> Result<LinearRaw, ImageIoError> {
    decode_raw(bytes, Path::new(name))
}

/// A file cut short is refused before rawloader sees it ([`super::tiff_extent`]): some of its
/// decoders would fill the missing rows with zeros.
fn decode_raw(bytes: &[u8], path: &Path) -> Result<LinearRaw, ImageIoError> {
    let decode_error = |message: String| ImageIoError::Decode {
        path: path.to_path_buf(),
        message,
    };
    super::tiff_extent::check(bytes).map_err(decode_error)?;
    let raw = rawloader::decode(&mut std::io::Cursor::new(bytes))
        .map_err(|e| decode_error(format!("not a RAW file rawloader can decode: {e}")))?;
    linearise(&raw).map_err(|message| ImageIoError::Unsupported {
        path: path.to_path_buf(),
        message: format!("RAW file: {message}"),
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

/// Black/white level, white balance and bilinear demosaic of a Bayer (or any periodic CFA)
/// `RawImage`; 3-channel linear RAWs are only levelled and balanced.
pub fn linearise(raw: &RawImage) -> Result<LinearRaw, String> {
    let [top, right, bottom, left] = raw.crops;
    if left + right >= raw.width || top + bottom >= raw.height {
        return Err(format!(
            "crop {:?} leaves no pixels of {}x{}",
            raw.crops, raw.width, raw.height
        ));
    }
    let (w, h) = (raw.width - left - right, raw.height - top - bottom);
    let cpp = raw.cpp;
    if cpp != 1 && cpp != 3 {
        return Err(format!("{cpp} components per pixel are not supported"));
    }
    let len = match &raw.data {
        RawImageData::Integer(v) => v.len(),
        RawImageData::Float(v) => v.len(),
    };
    if len < raw.width * raw.height * cpp {
        return Err(format!(
            "{len} samples for a {}x{}x{cpp} image",
            raw.width, raw.height
        ));
    }
    let wb = wb_normalised(raw);
    // (value - black) / (white - black), clipped to [0, 1], times the white balance; a sample
    // at or above the white level reads exactly `wb[c]`, its clip level.
    let level = |c: usize, v: f32| -> f32 {
        let black = f32::from(raw.blacklevels[c]);
        let white = f32::from(raw.whitelevels[c]);
        let range = (white - black).max(1.0);
        ((v - black) / range).clamp(0.0, 1.0) * wb[c]
    };
    // Levelled samples of the active area, `cpp` per pixel, `colour(x, y, component)` giving
    // each one's CFA colour. In bounds: the data holds width x height x cpp samples (above).
    let levelled = |colour: &dyn Fn(usize, usize, usize) -> usize| -> Vec<f32> {
        let mut out = Vec::with_capacity(w * h * cpp);
        for y in 0..h {
            let row =
                ((y + top) * raw.width + left) * cpp..((y + top) * raw.width + left + w) * cpp;
            let mut push = |i: usize, v: f32| out.push(level(colour(i / cpp, y, i % cpp), v));
            match &raw.data {
                RawImageData::Integer(d) => {
                    for (i, &v) in d[row].iter().enumerate() {
                        push(i, f32::from(v));
                    }
                }
                RawImageData::Float(d) => {
                    for (i, &v) in d[row].iter().enumerate() {
                        push(i, v);
                    }
                }
            }
        }
        out
    };
    let image = if cpp == 3 {
        let data = levelled(&|_, _, component| component);
        LinearImage::from_rgb(w, h, data).ok_or("pixel count does not match the size")?
    } else {
        let cfa = raw.cropped_cfa();
        if !cfa.is_valid() {
            return Err("single-channel RAW without a colour filter pattern".into());
        }
        // The CFA colour of each cell of its period (0..=3; a 4th colour is a second green).
        let (pw, ph) = (cfa.width.max(1), cfa.height.max(1));
        let pattern: Vec<usize> = (0..ph * pw)
            .map(|i| cfa.color_at(i / pw, i % pw).min(3))
            .collect();
        let cfa_colour = |x: usize, y: usize| pattern[(y % ph) * pw + x % pw];
        let mosaic = levelled(&|x, y, _| cfa_colour(x, y));
        demosaic_bilinear(&mosaic, w, h, cfa_colour, &wb)
    };
    Ok(LinearRaw {
        image,
        saturation: wb[0].min(wb[1]).min(wb[2]),
        make: raw.clean_make.clone(),
        model: raw.clean_model.clone(),
    })
}

/// Bilinear demosaic: each missing colour is the mean of the 3x3 neighbours that carry it (the
/// 4th CFA colour counts as green). A channel whose neighbours include a clipped photosite
/// (value at its clip level `clip[colour]`) takes the largest such clip level instead.
fn demosaic_bilinear(
    mosaic: &[f32],
    w: usize,
    h: usize,
    cfa_colour: impl Fn(usize, usize) -> usize,
    clip: &[f32; 4],
) -> LinearImage {
    let channel = |c: usize| if c == 3 { 1 } else { c };
    let mut data = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0f32; 3];
            let mut n = [0u32; 3];
            let mut clipped = [f32::NAN; 3];
            for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    let colour = cfa_colour(xx, yy);
                    let c = channel(colour);
                    let v = mosaic[yy * w + xx];
                    if v >= clip[colour] {
                        // NaN-ignoring max: the first clipped neighbour replaces the NaN
                        clipped[c] = clipped[c].max(v);
                    }
                    sum[c] += v;
                    n[c] += 1;
                }
            }
            let own = channel(cfa_colour(x, y));
            for c in 0..3 {
                data.push(if !clipped[c].is_nan() {
                    clipped[c]
                } else if c == own {
                    mosaic[y * w + x]
                } else if n[c] > 0 {
                    sum[c] / n[c] as f32
                } else {
                    0.0
                });
            }
        }
    }
    LinearImage::from_rgb(w, h, data).unwrap_or_else(|| LinearImage::new(w, h))
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

    /// One clipped red photosite in a dim field: the pixels whose red is interpolated from it
    /// read red at its clip level (2, the red white balance), so a threshold at the saturation
    /// finds them; pixels further away keep their values.
    #[test]
    fn channels_interpolated_from_a_clipped_photosite_read_as_clipped() {
        let (w, h) = (8usize, 8usize);
        let (black, white) = (0u16, 1000u16);
        let mut samples = vec![300u16; w * h];
        samples[4 * w + 4] = 1000; // (4, 4) is red in RGGB
        let dng = write_minimal_dng(w, h, &samples, black, white, [0.5, 1.0, 1.0]);
        let lin = decode_raw_bytes(&dng, "hot.dng").unwrap();
        assert!((lin.saturation - 1.0).abs() < 1e-6);
        for y in 0..h {
            for x in 0..w {
                let [r, g, b] = lin.image.get(x, y);
                let near = x.abs_diff(4) <= 1 && y.abs_diff(4) <= 1;
                if near {
                    assert_eq!(r, 2.0, "({x},{y})");
                    assert!(r >= lin.saturation);
                } else {
                    assert!((r - 0.6).abs() < 1e-6, "({x},{y}) red {r}");
                }
                assert!(
                    (g - 0.3).abs() < 1e-6 && (b - 0.3).abs() < 1e-6,
                    "({x},{y})"
                );
            }
        }
    }
}
