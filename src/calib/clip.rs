//! Where a calibration image clips, and how that is known. A clip level is never guessed from
//! the pixels: a flat region (a noiseless board, a uniform backdrop, a sharp highlight's core)
//! is not a clipped one, and a linear HDR image (EXR, float TIFF, a merged bracket) holds
//! radiance with no ceiling. So the clip level comes from the user (`--saturation`), from the
//! file format (the largest integer code, or a RAW file's white level, times the scale the file
//! is read with), or from the
//! session (a merged bracket clips where its shortest exposure did); otherwise there is none.
//!
//! Conventions: levels are in image units (the values the detectors see); a channel value at or
//! above the level is clipped. Pure: no I/O.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Why a clip level is what it is.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "source")]
pub enum ClipSource {
    /// Given by the user (`--saturation`).
    Given,
    /// The largest code of an integer file of `bits` bits, read with `scale`.
    IntegerFile { bits: u8, scale: f32 },
    /// A float file (EXR, float TIFF): linear radiance without a ceiling.
    FloatFile,
    /// Camera RAW files: the sensor's white level, white-balanced (the smallest channel's,
    /// `clip`, over the files), read with `scale`.
    RawFile { clip: f32, scale: f32 },
    /// A bracket merged to HDR: a value is a lower bound where even the shortest exposure
    /// clipped, `clip_fraction * saturation / shortest`.
    MergedBracket {
        saturation: f32,
        clip_fraction: f32,
        shortest_exposure_secs: f64,
    },
}

/// A clip level (or none) and its source.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClipLevel {
    /// Channel values at or above this are clipped; `None`: nothing is.
    pub value: Option<f32>,
    #[serde(flatten)]
    pub source: ClipSource,
}

impl ClipLevel {
    pub fn given(value: f32) -> Self {
        Self {
            value: Some(value),
            source: ClipSource::Given,
        }
    }

    /// An integer file read as `code / (2^bits - 1)` (through its transfer curve) times `scale`:
    /// the largest code reads as `scale`.
    pub fn integer_file(bits: u8, scale: f32) -> Self {
        Self {
            value: Some(scale),
            source: ClipSource::IntegerFile { bits, scale },
        }
    }

    /// RAW files read with `scale`, whose smallest white-balanced white level is `clip`
    /// (`imageio::raw`): clipped at `clip * scale`.
    pub fn raw_file(clip: f32, scale: f32) -> Self {
        Self {
            value: Some(clip * scale),
            source: ClipSource::RawFile { clip, scale },
        }
    }

    pub fn float_file() -> Self {
        Self {
            value: None,
            source: ClipSource::FloatFile,
        }
    }

    /// A merged bracket (radiance = value / exposure): clipped where even the shortest exposure
    /// reached `clip_fraction * saturation`.
    pub fn merged_bracket(
        saturation: f32,
        clip_fraction: f32,
        shortest_exposure_secs: f64,
    ) -> Self {
        let value = (f64::from(clip_fraction * saturation) / shortest_exposure_secs) as f32;
        Self {
            value: (value.is_finite() && value > 0.0).then_some(value),
            source: ClipSource::MergedBracket {
                saturation,
                clip_fraction,
                shortest_exposure_secs,
            },
        }
    }
}

impl fmt::Display for ClipLevel {
    /// "1 (the largest code of the 16-bit file, times --scale 1)", "none (...)".
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.value {
            Some(v) => write!(f, "{v}")?,
            None => write!(f, "none")?,
        }
        match self.source {
            ClipSource::Given => write!(f, " (given with --saturation)"),
            ClipSource::IntegerFile { bits, scale } => write!(
                f,
                " (the largest code of the {bits}-bit file, times the scale {scale})"
            ),
            ClipSource::RawFile { clip, scale } => write!(
                f,
                " (the RAW files' white level, white-balanced: {clip}, times the scale {scale})"
            ),
            ClipSource::FloatFile => write!(
                f,
                " (a float image holds linear radiance without a ceiling; give --saturation if \
                 the camera clipped)"
            ),
            ClipSource::MergedBracket {
                saturation,
                clip_fraction,
                shortest_exposure_secs,
            } => write!(
                f,
                " (merged bracket: {clip_fraction} x the camera's clip level {saturation} over \
                 the shortest exposure, {shortest_exposure_secs} s)"
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_say_where_they_come_from() {
        let g = ClipLevel::given(0.9);
        assert_eq!(g.value, Some(0.9));
        assert!(g.to_string().contains("--saturation"));
        let i = ClipLevel::integer_file(16, 2.0);
        assert_eq!(i.value, Some(2.0));
        assert!(i.to_string().contains("16-bit"));
        let r = ClipLevel::raw_file(0.8, 2.0);
        assert_eq!(r.value, Some(1.6));
        assert!(r.to_string().contains("RAW files' white level"));
        let f = ClipLevel::float_file();
        assert_eq!(f.value, None);
        assert!(f.to_string().starts_with("none"));
        let m = ClipLevel::merged_bracket(1.0, 0.98, 1e-4);
        assert!((m.value.unwrap_or(0.0) - 9800.0).abs() < 0.01);
        assert!(m.to_string().contains("shortest exposure"));
        assert_eq!(ClipLevel::merged_bracket(1.0, 0.98, 0.0).value, None);
    }
}
