//! UVC webcams through nokhwa (V4L2 input on Linux), with manual exposure and gain.
//!
//! Webcams deliver gamma-encoded 8-bit frames; they are linearised with the inverse sRGB curve,
//! which is an approximation of the camera's response (measure it for serious work, or prefer a
//! RAW-capable camera). Exposure goes to the UVC absolute exposure control (100 us units);
//! the first frames after a change are dropped because the sensor applies it a few frames late.
//! The device is opened for each shot and dropped afterwards, so nothing holds the stream open
//! between shots.

use nokhwa::pixel_format::RgbFormat;
use nokhwa::utils::{
    ApiBackend, CameraIndex, ControlValueSetter, KnownCameraControl, RequestedFormat,
    RequestedFormatType,
};

use super::{Camera, DeviceError, ShotMetadata, ShotSettings};
use crate::imageio::srgb_decode;
use crate::render::image::LinearImage;

/// V4L2's "exposure auto" control id (value 1 = manual).
const V4L2_CID_EXPOSURE_AUTO: u128 = 0x009a_0901;
/// Frames dropped after setting the exposure.
const FLUSH_FRAMES: usize = 3;

pub struct WebcamCamera {
    index: u32,
}

impl WebcamCamera {
    pub fn new(index: u32) -> Self {
        Self { index }
    }

    fn fail(&self, what: &str, e: impl std::fmt::Display) -> DeviceError {
        DeviceError::Other {
            device: format!("webcam {}", self.index),
            reason: format!("{what}: {e}"),
        }
    }
}

impl Camera for WebcamCamera {
    fn capture(
        &mut self,
        settings: ShotSettings,
    ) -> Result<(LinearImage, ShotMetadata), DeviceError> {
        let format =
            RequestedFormat::new::<RgbFormat>(RequestedFormatType::AbsoluteHighestResolution);
        let mut cam = nokhwa::Camera::new(CameraIndex::Index(self.index), format).map_err(|e| {
            DeviceError::Disconnected {
                device: format!("webcam {}", self.index),
                reason: e.to_string(),
            }
        })?;
        // Manual exposure first; some drivers refuse the auto control, which then stays as is.
        let _ = cam.set_camera_control(
            KnownCameraControl::Other(V4L2_CID_EXPOSURE_AUTO),
            ControlValueSetter::Integer(1),
        );
        let units = (settings.exposure_secs * 10_000.0).round().max(1.0) as i64;
        cam.set_camera_control(
            KnownCameraControl::Exposure,
            ControlValueSetter::Integer(units),
        )
        .map_err(|e| self.fail("setting the exposure", e))?;
        let _ = cam.set_camera_control(
            KnownCameraControl::Gain,
            ControlValueSetter::Integer((settings.gain * 100.0).round() as i64),
        );
        cam.open_stream()
            .map_err(|e| self.fail("opening the stream", e))?;
        let mut frame = cam.frame().map_err(|e| self.fail("reading a frame", e))?;
        for _ in 0..FLUSH_FRAMES {
            frame = cam.frame().map_err(|e| self.fail("reading a frame", e))?;
        }
        let res = frame.resolution();
        let (w, h) = (res.width() as usize, res.height() as usize);
        let mut rgb = vec![0u8; w * h * 3];
        frame
            .decode_image_to_buffer::<RgbFormat>(&mut rgb)
            .map_err(|e| self.fail("decoding the frame", e))?;
        let _ = cam.stop_stream();
        let data = rgb
            .iter()
            .map(|&c| srgb_decode(f32::from(c) / 255.0))
            .collect();
        let image = LinearImage::from_rgb(w, h, data)
            .ok_or_else(|| self.fail("decoding the frame", "size mismatch"))?;
        Ok((
            image,
            ShotMetadata {
                exposure_secs: units as f64 / 10_000.0,
                gain: settings.gain,
                saturation: 1.0,
                device: format!("webcam {} (nokhwa, V4L2)", self.index),
            },
        ))
    }
}

/// Attached webcams as `(index, name)`; the error is nokhwa's (V4L2 query).
pub fn list() -> Result<Vec<(String, String)>, nokhwa::NokhwaError> {
    nokhwa::query(ApiBackend::Video4Linux).map(|cams| {
        cams.into_iter()
            .map(|c| (c.index().to_string(), c.human_name()))
            .collect()
    })
}
