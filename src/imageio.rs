//! Reading and writing linear images.
//!
//! Formats:
//! - EXR (exr crate): RGB, written as f32 or f16, read from any sample type (alpha ignored); to
//!   and from bytes in memory too ([`encode_exr`], [`decode_exr`]: the capture checksums the
//!   bytes it writes). The one EXR codec of the tool.
//! - 16-bit PNG and 16-bit TIFF (image crate), declared **linear**: a stored value `q` means
//!   radiance `q / 65535 * scale`. 8-bit files are refused on a linear read: they are almost
//!   always gamma-encoded, and guessing would corrupt the reflectance; read as [`Transfer::Srgb`]
//!   (the caller says so) a code `q` of `n` bits means `srgb_decode(q / (2^n - 1)) * scale`.
//!   32-bit float TIFF is read as is.
//! - Camera RAW ([`raw`], rawloader: DNG, CR2, CRW, NEF, NRW, ARW, ORF, RW2, RAF, PEF, ...; see
//!   [`raw::RAW_EXTENSIONS`]; not CR3, which rawloader 0.37 does not read): black level
//!   subtracted, white-balanced as shot, demosaiced, linear, the white level at 1.0 in green,
//!   times `scale` as for integer files. A RAW file is linear by definition: asking for the sRGB
//!   transfer is an error, as for EXR.
//!
//! [`read_image`] also says what the file held ([`Samples`]): integer codes (whose largest code
//! is a clip level), RAW codes (whose white level is one), or floats (which have none). The
//! format is chosen by the extension, case-insensitively.
//! - 8-bit PNG previews for humans: multiplied by `2^exposure_stops`, clipped, sRGB-encoded.
//!   Never read these back as data.
//!
//! Every writer is atomic (`crate::atomic`): bytes go to a temp file in the destination's
//! directory, which is fsynced and renamed over the target, so a crash leaves the old file or
//! the new one, never half of one. Every error names the file. Depends on
//! `render::image::LinearImage` and `atomic` only.

pub mod dng;
pub mod raw;
mod tiff_extent;

use crate::atomic::{write_atomic, write_atomic_with};
use crate::render::image::LinearImage;
use std::io::{BufWriter, Seek, Write};
use std::path::{Path, PathBuf};
use thiserror::Error;

#[derive(Debug, Error)]
pub enum ImageIoError {
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: cannot decode: {message}")]
    Decode { path: PathBuf, message: String },
    #[error("{path}: {message}")]
    Unsupported { path: PathBuf, message: String },
}

/// EXR sample type on write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExrPrecision {
    F32,
    F16,
}

fn ext_of(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
}

/// Reads a linear image by extension: `.exr`, `.png`/`.tif`/`.tiff` as 16-bit linear with
/// `scale`, or a camera RAW times `scale` (see the module header).
pub fn read_linear(path: &Path, scale: f32) -> Result<LinearImage, ImageIoError> {
    read_image(path, scale, Transfer::Linear).map(|d| d.image)
}

/// How a file's stored values map to radiance, before `scale`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Transfer {
    /// Linear in radiance: EXR, RAW files and RAW-derived 16-bit files.
    #[default]
    Linear,
    /// The sRGB curve (IEC 61966-2-1), as most 8-bit camera output is encoded.
    Srgb,
}

/// What a file stored: floats, integer codes (whose largest code is where the file clips), or
/// RAW sensor codes (which clip at the sensor's white level).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Samples {
    Float,
    Integer {
        bits: u8,
    },
    /// `clip`: [`raw::LinearRaw::saturation`], the smallest white-balanced channel clip level,
    /// before `scale`.
    Raw {
        clip: f32,
    },
}

impl Samples {
    /// Where a file of these samples read with `scale` clips, in image units: the largest code
    /// of an integer file (`scale`), the white level of a RAW file (`clip * scale`); none for
    /// floats.
    pub fn clip_level(&self, scale: f32) -> Option<f32> {
        match *self {
            Samples::Float => None,
            Samples::Integer { .. } => Some(scale),
            Samples::Raw { clip } => Some(clip * scale),
        }
    }
}

/// An image read as radiance, with the kind of samples its file held.
#[derive(Clone, Debug, PartialEq)]
pub struct DecodedImage {
    pub image: LinearImage,
    pub samples: Samples,
}

/// Reads an image by extension (`.exr`, `.png`, `.tif`, `.tiff` or a RAW extension, any case)
/// as radiance: EXR and float TIFF as stored, integer codes through `transfer` to `[0, 1]` and
/// times `scale`, RAW files decoded by [`raw`] and times `scale`. EXR and RAW are linear by
/// definition: asking for sRGB there is an error rather than a silent no-op.
pub fn read_image(
    path: &Path,
    scale: f32,
    transfer: Transfer,
) -> Result<DecodedImage, ImageIoError> {
    let unsupported = |message: String| ImageIoError::Unsupported {
        path: path.to_path_buf(),
        message,
    };
    let linear_only = |what: &str| {
        unsupported(format!(
            "{what} holds linear values; the sRGB transfer applies to 8/16-bit PNG or TIFF only"
        ))
    };
    match ext_of(path).as_deref() {
        Some("exr") if transfer == Transfer::Srgb => Err(linear_only("an EXR file")),
        Some("exr") => Ok(DecodedImage {
            image: read_exr(path)?,
            samples: Samples::Float,
        }),
        Some("png" | "tif" | "tiff") => read_coded(path, scale, transfer),
        Some(ext) if raw::is_raw_extension(ext) => {
            if transfer == Transfer::Srgb {
                return Err(linear_only("a camera RAW file"));
            }
            let raw::LinearRaw {
                mut image,
                saturation,
                ..
            } = raw::decode_raw_file(path)?;
            image.data_mut().iter_mut().for_each(|v| *v *= scale);
            Ok(DecodedImage {
                image,
                samples: Samples::Raw { clip: saturation },
            })
        }
        Some("cr3") => Err(unsupported(
            "Canon CR3 is not read by rawloader, which decodes the RAW files here; convert it \
             to DNG (Adobe DNG Converter) or to 16-bit linear TIFF"
                .into(),
        )),
        _ => Err(unsupported(format!(
            "unsupported image format (by its extension); supported: .exr, 16-bit linear .png, \
             .tif, .tiff, and camera RAW .{}",
            raw::RAW_EXTENSIONS.join(", .")
        ))),
    }
}

/// The inverse of [`srgb_encode`]: the linear value of an sRGB-encoded value in [0, 1].
pub fn srgb_decode(c: f32) -> f32 {
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Decodes the first RGB(A) layer of an EXR stream as f32 (alpha ignored).
fn decode_exr_from(
    reader: impl std::io::Read + Seek + Send,
) -> Result<LinearImage, exr::error::Error> {
    use exr::prelude::*;
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |res, _| {
                (
                    res.width(),
                    res.height(),
                    vec![0.0f32; res.width() * res.height() * 3],
                )
            },
            |(w, _, data): &mut (usize, usize, Vec<f32>),
             pos,
             (r, g, b, _a): (f32, f32, f32, f32)| {
                let i = (pos.y() * *w + pos.x()) * 3;
                data[i] = r;
                data[i + 1] = g;
                data[i + 2] = b;
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(reader)?;
    let (w, h, data) = img.layer_data.channel_data.pixels;
    LinearImage::from_rgb(w, h, data).ok_or(exr::error::Error::Invalid(
        "pixel count does not match the size".into(),
    ))
}

/// Decodes EXR bytes held in memory (the first RGB(A) layer, as [`read_exr`] reads a file).
pub fn decode_exr(bytes: &[u8]) -> Result<LinearImage, exr::error::Error> {
    decode_exr_from(std::io::Cursor::new(bytes))
}

/// Reads the first RGB(A) layer of an EXR file as f32.
pub fn read_exr(path: &Path) -> Result<LinearImage, ImageIoError> {
    let file = std::fs::File::open(path).map_err(|source| ImageIoError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    decode_exr_from(std::io::BufReader::new(file)).map_err(|e| ImageIoError::Decode {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Encodes an RGB EXR (no alpha) in memory, with the exr crate's default lossless compression
/// (RLE). The session encodes in memory so that it can checksum exactly the bytes it writes.
/// `F16` halves the size but holds 11 significant bits and overflows to infinity above 65504:
/// scale radiance first if it can be that large.
pub fn encode_exr(
    img: &LinearImage,
    precision: ExrPrecision,
) -> Result<Vec<u8>, exr::error::Error> {
    use exr::prelude::*;
    let (w, h) = (img.width(), img.height());
    let mut cursor = std::io::Cursor::new(Vec::new());
    match precision {
        ExrPrecision::F32 => {
            let ch = SpecificChannels::rgb(|Vec2(x, y)| {
                let [r, g, b] = img.get(x, y);
                (r, g, b)
            });
            Image::from_channels((w, h), ch)
                .write()
                .to_buffered(&mut cursor)?
        }
        ExrPrecision::F16 => {
            let ch = SpecificChannels::rgb(|Vec2(x, y)| {
                let [r, g, b] = img.get(x, y);
                (f16::from_f32(r), f16::from_f32(g), f16::from_f32(b))
            });
            Image::from_channels((w, h), ch)
                .write()
                .to_buffered(&mut cursor)?
        }
    }
    Ok(cursor.into_inner())
}

/// Writes an RGB EXR (no alpha), atomically ([`encode_exr`], then `atomic::write_atomic`).
pub fn write_exr(
    path: &Path,
    img: &LinearImage,
    precision: ExrPrecision,
) -> Result<(), ImageIoError> {
    let encoded = encode_exr(img, precision).map_err(|e| ImageIoError::Write {
        path: path.to_path_buf(),
        source: std::io::Error::other(e.to_string()),
    })?;
    write_atomic(path, &encoded).map_err(|source| ImageIoError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads a 16-bit PNG or TIFF (RGB, RGBA or grey) as linear: `q / 65535 * scale`; 32-bit float
/// TIFF as stored times `scale`. 8-bit files are refused (see the module header).
pub fn read_linear16(path: &Path, scale: f32) -> Result<LinearImage, ImageIoError> {
    read_coded(path, scale, Transfer::Linear).map(|d| d.image)
}

/// A PNG or TIFF: integer codes through `transfer`, floats as stored, times `scale`.
fn read_coded(path: &Path, scale: f32, transfer: Transfer) -> Result<DecodedImage, ImageIoError> {
    let reader = image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|source| ImageIoError::Read {
            path: path.to_path_buf(),
            source,
        })?;
    let dynimg = reader.decode().map_err(|e| ImageIoError::Decode {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let (w, h) = (dynimg.width() as usize, dynimg.height() as usize);
    let color = dynimg.color();
    let bytes_per_sample = color.bytes_per_pixel() / color.channel_count().max(1);
    let float = matches!(color, image::ColorType::Rgb32F | image::ColorType::Rgba32F);
    let unsupported = |why: &str| ImageIoError::Unsupported {
        path: path.to_path_buf(),
        message: format!("pixel type {color:?} {why}"),
    };
    let (data, samples): (Vec<f32>, Samples) = if float {
        if transfer != Transfer::Linear {
            return Err(unsupported(
                "holds floats, which are linear: read it as linear",
            ));
        }
        let data = dynimg.to_rgb32f().into_raw();
        (
            data.into_iter().map(|v| v * scale).collect(),
            Samples::Float,
        )
    } else {
        let (codes, bits): (Vec<f32>, u8) = match bytes_per_sample {
            2 => (
                dynimg
                    .to_rgb16()
                    .into_raw()
                    .into_iter()
                    .map(f32::from)
                    .collect(),
                16,
            ),
            1 if transfer == Transfer::Linear => {
                return Err(unsupported(
                    "is 8-bit, which cameras gamma-encode: read it as sRGB (--transfer srgb) \
                     if it is, or give 16-bit linear PNG/TIFF or EXR",
                ));
            }
            1 => (
                dynimg
                    .to_rgb8()
                    .into_raw()
                    .into_iter()
                    .map(f32::from)
                    .collect(),
                8,
            ),
            _ => return Err(unsupported("is not supported: use 16-bit PNG/TIFF or EXR")),
        };
        let max = ((1u32 << bits) - 1) as f32;
        let data = codes
            .into_iter()
            .map(|q| match transfer {
                Transfer::Linear => q / max * scale,
                Transfer::Srgb => srgb_decode(q / max) * scale,
            })
            .collect();
        (data, Samples::Integer { bits })
    };
    let image = LinearImage::from_rgb(w, h, data).ok_or_else(|| ImageIoError::Decode {
        path: path.to_path_buf(),
        message: "pixel count does not match the size".into(),
    })?;
    Ok(DecodedImage { image, samples })
}

/// Quantises to 16 bits: `q = round(v / scale * 65535)`, clipped to [0, 65535]. Returns the
/// samples and how many were clipped (above `scale`, below zero or NaN).
pub fn quantise16(img: &LinearImage, scale: f32) -> (Vec<u16>, usize) {
    let mut clipped = 0;
    let q = img
        .data()
        .iter()
        .map(|&v| {
            let x = v / scale * 65535.0;
            if x.is_nan() || !(0.0..=65535.0).contains(&x) {
                clipped += 1;
            }
            if x.is_nan() {
                0
            } else {
                x.round().clamp(0.0, 65535.0) as u16
            }
        })
        .collect();
    (q, clipped)
}

fn write_with_image_crate(
    path: &Path,
    img: &LinearImage,
    scale: f32,
    format: image::ImageFormat,
) -> Result<usize, ImageIoError> {
    let (q, clipped) = quantise16(img, scale);
    let buf = image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(
        img.width() as u32,
        img.height() as u32,
        q,
    )
    .ok_or_else(|| ImageIoError::Write {
        path: path.to_path_buf(),
        source: std::io::Error::other("image size overflows"),
    })?;
    write_atomic_with(path, |f| {
        let mut w = BufWriter::new(f);
        buf.write_to(&mut w, format)
            .map_err(std::io::Error::other)?;
        w.flush()
    })
    .map_err(|source| ImageIoError::Write {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(clipped)
}

/// Writes a 16-bit linear RGB PNG (`q = v / scale * 65535`); returns the clipped sample count.
pub fn write_png16(path: &Path, img: &LinearImage, scale: f32) -> Result<usize, ImageIoError> {
    write_with_image_crate(path, img, scale, image::ImageFormat::Png)
}

/// Writes a 16-bit linear RGB TIFF (`q = v / scale * 65535`); returns the clipped sample count.
pub fn write_tiff16(path: &Path, img: &LinearImage, scale: f32) -> Result<usize, ImageIoError> {
    write_with_image_crate(path, img, scale, image::ImageFormat::Tiff)
}

/// The sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
pub fn srgb_encode(v: f32) -> f32 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// 8-bit sRGB bytes of `img * 2^exposure_stops` (RGB interleaved), for previews.
pub fn preview_srgb8(img: &LinearImage, exposure_stops: f32) -> Vec<u8> {
    let gain = exposure_stops.exp2();
    img.data()
        .iter()
        .map(|&v| (srgb_encode(v * gain) * 255.0).round() as u8)
        .collect()
}

/// Writes an 8-bit sRGB PNG preview (for humans; not data).
pub fn write_preview_png(
    path: &Path,
    img: &LinearImage,
    exposure_stops: f32,
) -> Result<(), ImageIoError> {
    let bytes = preview_srgb8(img, exposure_stops);
    let buf = image::RgbImage::from_raw(img.width() as u32, img.height() as u32, bytes)
        .ok_or_else(|| ImageIoError::Write {
            path: path.to_path_buf(),
            source: std::io::Error::other("image size overflows"),
        })?;
    write_atomic_with(path, |f| {
        let mut w = BufWriter::new(f);
        buf.write_to(&mut w, image::ImageFormat::Png)
            .map_err(std::io::Error::other)?;
        w.flush()
    })
    .map_err(|source| ImageIoError::Write {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize, max: f32) -> LinearImage {
        let data = (0..w * h * 3)
            .map(|i| max * i as f32 / (w * h * 3) as f32)
            .collect();
        LinearImage::from_rgb(w, h, data).unwrap()
    }

    #[test]
    fn exr_bytes_round_trip_exactly_and_junk_is_refused() {
        let mut img = LinearImage::new(7, 5);
        for y in 0..5 {
            for x in 0..7 {
                img.set(
                    x,
                    y,
                    [x as f32 * 0.1, y as f32 * 3.5, 1e-6 + (x * y) as f32],
                );
            }
        }
        let bytes = encode_exr(&img, ExrPrecision::F32).unwrap();
        assert_eq!(decode_exr(&bytes).unwrap(), img);
        assert!(decode_exr(b"not an exr").is_err());
    }

    #[test]
    fn exr_round_trips_f32_exactly_and_f16_to_half_precision() {
        let dir = tempfile::tempdir().unwrap();
        let img = ramp(7, 5, 40.0);
        let p = dir.path().join("a.exr");
        write_exr(&p, &img, ExrPrecision::F32).unwrap();
        assert_eq!(read_linear(&p, 1.0).unwrap(), img);
        write_exr(&p, &img, ExrPrecision::F16).unwrap();
        let back = read_exr(&p).unwrap();
        for (a, b) in back.data().iter().zip(img.data()) {
            assert!((a - b).abs() <= b.abs() * 1e-3 + 1e-6, "{a} {b}");
        }
        // the overwrite left no temp file behind
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn sixteen_bit_png_and_tiff_round_trip_within_half_a_step() {
        let dir = tempfile::tempdir().unwrap();
        let scale = 8.0;
        let img = ramp(9, 4, scale);
        for name in ["a.png", "a.tif"] {
            let p = dir.path().join(name);
            let clipped = if name.ends_with("png") {
                write_png16(&p, &img, scale).unwrap()
            } else {
                write_tiff16(&p, &img, scale).unwrap()
            };
            assert_eq!(clipped, 0);
            let back = read_linear(&p, scale).unwrap();
            assert_eq!((back.width(), back.height()), (9, 4));
            for (a, b) in back.data().iter().zip(img.data()) {
                assert!((a - b).abs() <= 0.5 * scale / 65535.0 + 1e-6);
            }
        }
        // values above the scale clip and are counted
        let mut hot = img.clone();
        hot.set(0, 0, [9.0, -1.0, 1.0]);
        assert_eq!(
            write_png16(&dir.path().join("h.png"), &hot, scale).unwrap(),
            2
        );
    }

    #[test]
    fn eight_bit_files_are_refused_as_data_and_errors_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("preview.png");
        let img = ramp(4, 4, 1.0);
        write_preview_png(&p, &img, 0.0).unwrap();
        let e = read_linear(&p, 1.0).unwrap_err();
        assert!(matches!(e, ImageIoError::Unsupported { .. }));
        assert!(e.to_string().contains("preview.png"));
        let e = read_linear(&dir.path().join("none.exr"), 1.0).unwrap_err();
        assert!(matches!(e, ImageIoError::Read { .. }) && e.to_string().contains("none.exr"));
        let junk = dir.path().join("junk.exr");
        std::fs::write(&junk, b"not an exr").unwrap();
        assert!(matches!(
            read_linear(&junk, 1.0).unwrap_err(),
            ImageIoError::Decode { .. }
        ));
        let e =
            write_exr(&dir.path().join("no/such/dir.exr"), &img, ExrPrecision::F32).unwrap_err();
        assert!(matches!(e, ImageIoError::Write { .. }));
    }

    /// An 8-bit sRGB file read as sRGB gives back the linear values to within a code, and says
    /// it held 8-bit codes; 16-bit linear files say 16 bits; EXR says floats.
    #[test]
    fn srgb_files_decode_and_reads_say_what_the_file_held() {
        let dir = tempfile::tempdir().unwrap();
        let img = ramp(16, 4, 1.0);
        let p8 = dir.path().join("srgb.png");
        write_preview_png(&p8, &img, 0.0).unwrap();
        let d = read_image(&p8, 2.0, Transfer::Srgb).unwrap();
        assert_eq!(d.samples, Samples::Integer { bits: 8 });
        for (got, want) in d.image.data().iter().zip(img.data()) {
            // half a code: at most 0.5 / 255 * 2.4 / 1.055 in linear terms (steepest at 1)
            assert!((got / 2.0 - want).abs() < 0.005, "{got} vs {want}");
        }
        assert!((srgb_decode(srgb_encode(0.18)) - 0.18).abs() < 1e-6);
        assert!((srgb_decode(srgb_encode(0.001)) - 0.001).abs() < 1e-7);
        let p16 = dir.path().join("lin.png");
        write_png16(&p16, &img, 1.0).unwrap();
        let d = read_image(&p16, 1.0, Transfer::Linear).unwrap();
        assert_eq!(d.samples, Samples::Integer { bits: 16 });
        let pe = dir.path().join("lin.exr");
        write_exr(&pe, &img, ExrPrecision::F32).unwrap();
        assert_eq!(
            read_image(&pe, 1.0, Transfer::Linear).unwrap().samples,
            Samples::Float
        );
        let e = read_image(&pe, 1.0, Transfer::Srgb).unwrap_err();
        assert!(e.to_string().contains("linear values"), "{e}");
    }

    /// A DNG (any case of extension) reads as the linear image it encodes, times the scale, and
    /// says where it clips; the sRGB transfer, unknown extensions, CR3 and a truncated DNG are
    /// errors naming the file.
    #[test]
    fn raw_files_read_as_linear_radiance_and_errors_name_the_file() {
        use dng::{BayerEncoding, dng_from_image};
        let dir = tempfile::tempdir().unwrap();
        let img = LinearImage::from_rgb(6, 4, vec![0.25; 6 * 4 * 3]).unwrap();
        let enc = BayerEncoding {
            black: 100,
            white: 16_000,
            as_shot_neutral: [0.5, 1.0, 0.8],
            full_scale: 1.0,
        };
        let bytes = dng_from_image(&img, &enc);
        let p = dir.path().join("shot.DNG");
        std::fs::write(&p, &bytes).unwrap();
        let d = read_image(&p, 4.0, Transfer::Linear).unwrap();
        // wb (2, 1, 1.25): the clip level is green's white level, 1, times the scale
        assert_eq!(d.samples, Samples::Raw { clip: 1.0 });
        assert_eq!(d.samples.clip_level(4.0), Some(4.0));
        for v in d.image.data() {
            // half a code of 15900 in the worst channel (red, wb 2), times the scale
            assert!((v - 1.0).abs() < 4.0 * 2.0 * 0.5 / 15_900.0 + 1e-6, "{v}");
        }
        assert_eq!(read_linear(&p, 1.0).unwrap().width(), 6);
        let e = read_image(&p, 1.0, Transfer::Srgb).unwrap_err();
        assert!(e.to_string().contains("shot.DNG") && e.to_string().contains("linear"));
        for (name, needle) in [("a.jpg", ".nef"), ("a.cr3", "DNG"), ("noext", ".exr")] {
            let q = dir.path().join(name);
            std::fs::write(&q, &bytes).unwrap();
            let e = read_linear(&q, 1.0).unwrap_err();
            assert!(matches!(e, ImageIoError::Unsupported { .. }), "{e}");
            let e = e.to_string();
            assert!(e.contains(name) && e.contains(needle), "{e}");
        }
        let cut = dir.path().join("cut.dng");
        std::fs::write(&cut, &bytes[..bytes.len() - 20]).unwrap();
        let e = read_linear(&cut, 1.0).unwrap_err();
        assert!(matches!(e, ImageIoError::Decode { .. }), "{e}");
        assert!(e.to_string().contains("cut.dng"), "{e}");
    }

    #[test]
    fn srgb_preview_matches_the_standard_curve() {
        // IEC 61966-2-1 reference points: 0.18 linear -> 0.4614 encoded; linear toe below 0.0031308
        assert!((srgb_encode(0.18) - 0.4614).abs() < 1e-3);
        assert!((srgb_encode(0.002) - 0.02584).abs() < 1e-6);
        assert!((srgb_encode(2.0) - 1.0).abs() < 1e-6);
        let img = LinearImage::from_rgb(1, 1, vec![0.045, 0.09, 0.0]).unwrap();
        // one stop up doubles the linear value before encoding
        let b = preview_srgb8(&img, 1.0);
        assert_eq!(b[0], (srgb_encode(0.09) * 255.0).round() as u8);
        assert_eq!(b[1], (srgb_encode(0.18) * 255.0).round() as u8);
    }
}
