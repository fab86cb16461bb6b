//! V4L2 devices through the v4l crate, with manual exposure (absolute, 100 us units) and gain.
//!
//! Frames are read as YUYV (the format every UVC camera offers), converted to RGB with BT.601
//! and linearised with the inverse sRGB curve: an approximation of the camera response (see
//! `camera_webcam`). The first frames after setting the exposure are dropped.

use std::path::{Path, PathBuf};

use v4l::buffer::Type;
use v4l::control::{Control, Value};
use v4l::io::mmap::Stream;
use v4l::io::traits::CaptureStream;
use v4l::video::Capture;
use v4l::{Device, FourCC};

use super::{Camera, DeviceError, ShotMetadata, ShotSettings};
use crate::imageio::srgb_decode;
use crate::render::image::LinearImage;

const CID_EXPOSURE_AUTO: u32 = 0x009a_0901;
const CID_EXPOSURE_ABSOLUTE: u32 = 0x009a_0902;
const CID_GAIN: u32 = 0x0098_0913;
const FLUSH_FRAMES: usize = 3;

pub struct V4l2Camera {
    path: PathBuf,
    width: u32,
    height: u32,
}

impl V4l2Camera {
    pub fn new(path: &Path, width: u32, height: u32) -> Self {
        Self {
            path: path.to_path_buf(),
            width,
            height,
        }
    }

    fn fail(&self, what: &str, e: impl std::fmt::Display) -> DeviceError {
        DeviceError::Other {
            device: format!("V4L2 {}", self.path.display()),
            reason: format!("{what}: {e}"),
        }
    }
}

/// YUYV (4:2:2) to linear RGB.
pub fn yuyv_to_linear(buf: &[u8], width: usize, height: usize) -> Option<LinearImage> {
    if buf.len() < width * height * 2 || !width.is_multiple_of(2) {
        return None;
    }
    let mut img = LinearImage::new(width, height);
    let clamp = |v: f32| v.round().clamp(0.0, 255.0) as u8;
    for y in 0..height {
        for x in (0..width).step_by(2) {
            let i = (y * width + x) * 2;
            let (y0, u, y1, v) = (
                buf[i] as f32,
                buf[i + 1] as f32 - 128.0,
                buf[i + 2] as f32,
                buf[i + 3] as f32 - 128.0,
            );
            for (dx, yy) in [(0, y0), (1, y1)] {
                let r = clamp(yy + 1.402 * v);
                let g = clamp(yy - 0.344_136 * u - 0.714_136 * v);
                let b = clamp(yy + 1.772 * u);
                img.set(
                    x + dx,
                    y,
                    [r, g, b].map(|c| srgb_decode(f32::from(c) / 255.0)),
                );
            }
        }
    }
    Some(img)
}

impl Camera for V4l2Camera {
    fn capture(
        &mut self,
        settings: ShotSettings,
    ) -> Result<(LinearImage, ShotMetadata), DeviceError> {
        let dev = Device::with_path(&self.path).map_err(|e| DeviceError::Disconnected {
            device: format!("V4L2 {}", self.path.display()),
            reason: e.to_string(),
        })?;
        let mut fmt = dev
            .format()
            .map_err(|e| self.fail("reading the format", e))?;
        fmt.width = self.width;
        fmt.height = self.height;
        fmt.fourcc = FourCC::new(b"YUYV");
        let fmt = dev
            .set_format(&fmt)
            .map_err(|e| self.fail("setting YUYV", e))?;
        if fmt.fourcc != FourCC::new(b"YUYV") {
            return Err(self.fail("setting the format", "the device does not offer YUYV"));
        }
        let _ = dev.set_control(Control {
            id: CID_EXPOSURE_AUTO,
            value: Value::Integer(1),
        });
        let units = (settings.exposure_secs * 10_000.0).round().max(1.0) as i64;
        dev.set_control(Control {
            id: CID_EXPOSURE_ABSOLUTE,
            value: Value::Integer(units),
        })
        .map_err(|e| self.fail("setting the exposure", e))?;
        let _ = dev.set_control(Control {
            id: CID_GAIN,
            value: Value::Integer((settings.gain * 100.0).round() as i64),
        });
        let mut stream = Stream::with_buffers(&dev, Type::VideoCapture, 4)
            .map_err(|e| self.fail("starting the stream", e))?;
        for _ in 0..FLUSH_FRAMES {
            stream.next().map_err(|e| self.fail("reading a frame", e))?;
        }
        let (buf, _) = stream.next().map_err(|e| self.fail("reading a frame", e))?;
        let image = yuyv_to_linear(buf, fmt.width as usize, fmt.height as usize)
            .ok_or_else(|| self.fail("decoding the frame", "short YUYV buffer"))?;
        Ok((
            image,
            ShotMetadata {
                exposure_secs: units as f64 / 10_000.0,
                gain: settings.gain,
                saturation: 1.0,
                device: format!("V4L2 {}", self.path.display()),
            },
        ))
    }
}

/// V4L2 capture nodes as `(path, name)`.
pub fn list() -> Vec<(String, String)> {
    v4l::context::enum_devices()
        .into_iter()
        .map(|n| {
            (
                n.path().display().to_string(),
                n.name().unwrap_or_else(|| "unnamed".into()),
            )
        })
        .collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn yuyv_grey_and_colour() {
        // mid grey: Y = 188, U = V = 128 -> linear about 0.5 in every channel
        let img = yuyv_to_linear(&[188, 128, 188, 128], 2, 1).unwrap();
        for c in img.get(1, 0) {
            assert!((c - 0.5).abs() < 0.01);
        }
        // saturated red in BT.601: Y 76, U 85, V 255
        let img = yuyv_to_linear(&[76, 85, 76, 255], 2, 1).unwrap();
        let [r, g, b] = img.get(0, 0);
        assert!(r > 0.95 && g < 0.01 && b < 0.01, "{r} {g} {b}");
        assert!(yuyv_to_linear(&[0; 3], 2, 1).is_none());
    }
}
