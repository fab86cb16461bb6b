//! Camera RAW files to linear images: decoding by rawloader, then black level, white level,
//! white balance and a bilinear demosaic here.
//!
//! Output: camera-native RGB (no colour matrix), white-balanced with the camera's as-shot
//! coefficients normalised to green, scaled so that the sensor's white level is 1.0 in the green
//! channel. Linear in radiance, as reconstruction needs; the colour space stays the camera's,
//! which is fine because the BRDF is recovered per channel and divided by the white reference
//! measured with the same camera.

use crate::render::image::LinearImage;
use rawloader::{RawImage, RawImageData};
use std::path::Path;

/// Why a RAW file could not be turned into an image.
#[derive(Debug, thiserror::Error)]
pub enum RawError {
    #[error("decoding RAW file {path}: {reason}")]
    Decode { path: String, reason: String },
    #[error("RAW file {path}: {reason}")]
    Unsupported { path: String, reason: String },
}

/// A linear image with the value at which a pixel counts as saturated.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearRaw {
    pub image: LinearImage,
    pub saturation: f32,
    pub make: String,
    pub model: String,
}

/// Decodes a RAW file (any format rawloader reads: DNG, CR2, NEF, ARW, ...).
pub fn decode_raw_file(path: &Path) -> Result<LinearRaw, RawError> {
    let raw = rawloader::decode_file(path).map_err(|e| RawError::Decode {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    linearise(&raw).map_err(|reason| RawError::Unsupported {
        path: path.display().to_string(),
        reason,
    })
}

/// Decodes RAW bytes held in memory; `name` is used in errors.
pub fn decode_raw_bytes(bytes: &[u8], name: &str) -> Result<LinearRaw, RawError> {
    let mut cursor = std::io::Cursor::new(bytes);
    let raw = rawloader::decode(&mut cursor).map_err(|e| RawError::Decode {
        path: name.to_string(),
        reason: e.to_string(),
    })?;
    linearise(&raw).map_err(|reason| RawError::Unsupported {
        path: name.to_string(),
        reason,
    })
}

/// White-balance multipliers normalised to green; NaN (unknown) becomes 1.
fn wb_normalised(raw: &RawImage) -> [f32; 4] {
    let wb = raw.wb_coeffs;
    let g = if wb[1].is_finite() && wb[1] > 0.0 {
        wb[1]
    } else {
        1.0
    };
    let mut out = [1.0f32; 4];
    for c in 0..4 {
        out[c] = if wb[c].is_finite() && wb[c] > 0.0 {
            wb[c] / g
        } else {
            1.0
        };
    }
    // A fourth colour (second green, "E") takes green's factor when it has none.
    if !(wb[3].is_finite() && wb[3] > 0.0) {
        out[3] = out[1];
    }
    out
}

/// Black/white level, white balance and bilinear demosaic of a Bayer (or any 2x2-periodic CFA)
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
    let expected = raw.width * raw.height * cpp;
    let sample = |i: usize| -> f32 {
        match &raw.data {
            RawImageData::Integer(v) => v.get(i).map(|&x| x as f32).unwrap_or(0.0),
            RawImageData::Float(v) => v.get(i).copied().unwrap_or(0.0),
        }
    };
    let len = match &raw.data {
        RawImageData::Integer(v) => v.len(),
        RawImageData::Float(v) => v.len(),
    };
    if len < expected {
        return Err(format!(
            "{len} samples for a {}x{}x{cpp} image",
            raw.width, raw.height
        ));
    }
    let wb = wb_normalised(raw);
    let level = |c: usize, v: f32| -> f32 {
        let black = raw.blacklevels[c] as f32;
        let white = raw.whitelevels[c] as f32;
        let range = (white - black).max(1.0);
        ((v - black) / range).clamp(0.0, 1.0) * wb[c]
    };
    let mut image = LinearImage::new(w, h);
    if cpp == 3 {
        for y in 0..h {
            for x in 0..w {
                let i = ((y + top) * raw.width + x + left) * 3;
                image.set(
                    x,
                    y,
                    [
                        level(0, sample(i)),
                        level(1, sample(i + 1)),
                        level(2, sample(i + 2)),
                    ],
                );
            }
        }
    } else {
        let cfa = raw.cropped_cfa();
        if !cfa.is_valid() {
            return Err("single-channel RAW without a colour filter pattern".into());
        }
        // Levelled mosaic, and the colour of each photosite (the 4th colour counts as green).
        let colour = |x: usize, y: usize| -> usize {
            match cfa.color_at(y, x) {
                3 => 1,
                c => c.min(2),
            }
        };
        let mut mosaic = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let c = cfa.color_at(y, x).min(3);
                mosaic[y * w + x] = level(c, sample((y + top) * raw.width + x + left));
            }
        }
        // Bilinear: each missing colour is the mean of the 3x3 neighbours that carry it.
        for y in 0..h {
            for x in 0..w {
                let mut sum = [0f32; 3];
                let mut n = [0u32; 3];
                let own = colour(x, y);
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                        if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                            continue;
                        }
                        let (xx, yy) = (xx as usize, yy as usize);
                        let c = colour(xx, yy);
                        sum[c] += mosaic[yy * w + xx];
                        n[c] += 1;
                    }
                }
                let mut rgb = [0f32; 3];
                for c in 0..3 {
                    rgb[c] = if c == own {
                        mosaic[y * w + x]
                    } else if n[c] > 0 {
                        sum[c] / n[c] as f32
                    } else {
                        0.0
                    };
                }
                image.set(x, y, rgb);
            }
        }
    }
    let saturation = wb[0].min(wb[1]).min(wb[2]);
    Ok(LinearRaw {
        image,
        saturation,
        make: raw.clean_make.clone(),
        model: raw.clean_model.clone(),
    })
}

/// Inverse of the sRGB transfer curve, 8-bit code to linear [0, 1] (webcam and V4L2 frames,
/// which arrive gamma-encoded).
pub fn srgb_to_linear(code: u8) -> f32 {
    let v = f32::from(code) / 255.0;
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Writes a minimal uncompressed Bayer DNG (RGGB, 16 bit): enough for rawloader and for tests
/// that need a real RAW file without a camera.
pub fn write_minimal_dng(
    width: usize,
    height: usize,
    samples: &[u16],
    black: u16,
    white: u16,
    as_shot_neutral: [f64; 3],
) -> Vec<u8> {
    // TIFF types: 1 BYTE, 2 ASCII, 3 SHORT, 4 LONG, 5 RATIONAL.
    struct Entry {
        tag: u16,
        typ: u16,
        count: u32,
        data: Vec<u8>,
    }
    let short = |tag, v: &[u16]| Entry {
        tag,
        typ: 3,
        count: v.len() as u32,
        data: v.iter().flat_map(|x| x.to_le_bytes()).collect(),
    };
    let long = |tag, v: &[u32]| Entry {
        tag,
        typ: 4,
        count: v.len() as u32,
        data: v.iter().flat_map(|x| x.to_le_bytes()).collect(),
    };
    let bytes = |tag, v: &[u8]| Entry {
        tag,
        typ: 1,
        count: v.len() as u32,
        data: v.to_vec(),
    };
    let ascii = |tag, s: &str| {
        let mut d = s.as_bytes().to_vec();
        d.push(0);
        Entry {
            tag,
            typ: 2,
            count: d.len() as u32,
            data: d,
        }
    };
    let rational = |tag, v: &[f64]| Entry {
        tag,
        typ: 5,
        count: v.len() as u32,
        data: v
            .iter()
            .flat_map(|x| {
                let den = 1_000_000u32;
                let num = (x * den as f64).round() as u32;
                num.to_le_bytes().into_iter().chain(den.to_le_bytes())
            })
            .collect(),
    };
    let pixel_bytes: Vec<u8> = samples.iter().flat_map(|x| x.to_le_bytes()).collect();
    let mut entries = vec![
        long(254, &[0]),
        long(256, &[width as u32]),
        long(257, &[height as u32]),
        short(258, &[16]),
        short(259, &[1]),
        short(262, &[32803]),
        ascii(271, "brdf-rig"),
        ascii(272, "test sensor"),
        long(273, &[0]), // strip offset, patched below
        short(277, &[1]),
        long(278, &[height as u32]),
        long(279, &[pixel_bytes.len() as u32]),
        short(33421, &[2, 2]),
        bytes(33422, &[0, 1, 1, 2]),
        bytes(50706, &[1, 4, 0, 0]),
        short(50714, &[black]),
        short(50717, &[white]),
        rational(50728, &as_shot_neutral),
    ];
    entries.sort_by_key(|e| e.tag);
    let ifd_offset = 8u32;
    let ifd_len = 2 + entries.len() as u32 * 12 + 4;
    let mut extra_offset = ifd_offset + ifd_len;
    let mut extra = Vec::new();
    let mut ifd = Vec::new();
    ifd.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    // Out-of-line values first, then the pixels; compute the pixel offset up front.
    let out_of_line: u32 = entries
        .iter()
        .filter(|e| e.data.len() > 4)
        .map(|e| e.data.len().next_multiple_of(2) as u32)
        .sum();
    let strip_offset = extra_offset + out_of_line;
    for e in &mut entries {
        if e.tag == 273 {
            e.data = strip_offset.to_le_bytes().to_vec();
        }
        ifd.extend_from_slice(&e.tag.to_le_bytes());
        ifd.extend_from_slice(&e.typ.to_le_bytes());
        ifd.extend_from_slice(&e.count.to_le_bytes());
        if e.data.len() <= 4 {
            let mut v = e.data.clone();
            v.resize(4, 0);
            ifd.extend_from_slice(&v);
        } else {
            ifd.extend_from_slice(&extra_offset.to_le_bytes());
            extra.extend_from_slice(&e.data);
            if e.data.len() % 2 == 1 {
                extra.push(0);
            }
            extra_offset += e.data.len().next_multiple_of(2) as u32;
        }
    }
    ifd.extend_from_slice(&0u32.to_le_bytes());
    let mut out = Vec::new();
    out.extend_from_slice(b"II");
    out.extend_from_slice(&42u16.to_le_bytes());
    out.extend_from_slice(&ifd_offset.to_le_bytes());
    out.extend_from_slice(&ifd);
    out.extend_from_slice(&extra);
    out.extend_from_slice(&pixel_bytes);
    out
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    /// A synthetic scene in linear RGB, mosaicked RGGB with levels and white balance undone,
    /// written as a DNG, decoded by rawloader and linearised: the scene must come back.
    #[test]
    fn dng_round_trip_recovers_a_linear_scene() {
        let (w, h) = (16usize, 12usize);
        let (black, white) = (512u16, 15_000u16);
        // Camera response to grey is (0.5, 1, 0.6) of green: AsShotNeutral = that, wb = 1/that.
        let neutral = [0.5, 1.0, 0.625];
        let scene = |x: usize, y: usize| -> [f64; 3] {
            // smooth, so bilinear interpolation is nearly exact in the interior
            let r = 0.2 + 0.02 * x as f64;
            let g = 0.3 + 0.01 * y as f64;
            let b = 0.1 + 0.005 * (x + y) as f64;
            [r, g, b]
        };
        let mut samples = vec![0u16; w * h];
        for y in 0..h {
            for x in 0..w {
                let c = match (y % 2, x % 2) {
                    (0, 0) => 0,
                    (1, 1) => 2,
                    _ => 1,
                };
                let sensor = scene(x, y)[c] * neutral[c];
                samples[y * w + x] =
                    (black as f64 + sensor * (white - black) as f64).round() as u16;
            }
        }
        let dng = write_minimal_dng(w, h, &samples, black, white, neutral);
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
                        (got[c] as f64 - want[c]).abs() < 2e-3,
                        "({x},{y}) channel {c}: {} vs {}",
                        got[c],
                        want[c]
                    );
                }
            }
        }
        // saturation: the smallest white-balanced clip level (green = 1 here, red 2, blue 1.6)
        assert!((lin.saturation - 1.0).abs() < 1e-6);
        // a truncated file is an error naming the file, not a panic
        let err = decode_raw_bytes(&dng[..100], "cut.dng")
            .unwrap_err()
            .to_string();
        assert!(err.contains("cut.dng"), "{err}");
    }

    #[test]
    fn srgb_curve_is_inverted() {
        assert_eq!(srgb_to_linear(0), 0.0);
        assert!((srgb_to_linear(255) - 1.0).abs() < 1e-6);
        // sRGB 188/255 is about 0.5 linear
        assert!((srgb_to_linear(188) - 0.5).abs() < 0.01);
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
