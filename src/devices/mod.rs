//! Device traits (turntable, light, camera) and their drivers. Everything above this module
//! (capture sessions, the CLI) talks to these traits only, so a simulated device and a real one
//! go through the same code.
//!
//! Units: angles in degrees at this boundary (operators and profiles think in degrees; the wire
//! protocol uses millidegrees), light levels in [0, 1], exposure in seconds.

pub mod camera_gphoto2;
#[cfg(feature = "v4l2")]
pub mod camera_v4l2;
#[cfg(feature = "webcam")]
pub mod camera_webcam;
pub mod cameras;
pub mod error;
pub mod link;
pub mod motion;
pub mod rig;

pub use error::DeviceError;

use crate::render::image::LinearImage;

/// What the turntable reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TurntableStatus {
    pub angle_deg: f64,
    pub target_deg: f64,
    pub moving: bool,
    pub homed: bool,
}

/// A motorised turntable. Methods block until the motion has finished (or failed).
pub trait Turntable {
    /// Finds the home switch; the angle is 0 afterwards.
    fn home(&mut self) -> Result<(), DeviceError>;
    /// Moves to an absolute angle in degrees and waits until at rest.
    fn move_to(&mut self, angle_deg: f64) -> Result<(), DeviceError>;
    /// Moves by a relative angle in degrees and waits until at rest.
    fn move_by(&mut self, delta_deg: f64) -> Result<(), DeviceError>;
    /// Decelerates to rest.
    fn stop(&mut self) -> Result<(), DeviceError>;
    fn status(&mut self) -> Result<TurntableStatus, DeviceError>;
}

/// State of one light channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelStatus {
    /// 0 = off, 1 = full.
    pub level: f64,
    /// Warmed up and steady.
    pub stable: bool,
}

/// A light source with one or more channels (e.g. LEDs at different positions).
pub trait Light {
    fn channel_count(&self) -> usize;
    /// Switches `channel` on at `level` in (0, 1]; every other channel off when `exclusive`.
    /// Waits until the channel reports stable (warm-up) or the driver's timeout.
    fn on(&mut self, channel: usize, level: f64, exclusive: bool) -> Result<(), DeviceError>;
    /// Switches one channel off, or all with `None`.
    fn off(&mut self, channel: Option<usize>) -> Result<(), DeviceError>;
    fn status(&mut self) -> Result<Vec<ChannelStatus>, DeviceError>;
}

/// Capture settings for one shot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShotSettings {
    pub exposure_secs: f64,
    pub gain: f64,
}

/// What a camera says about a shot it took.
#[derive(Clone, Debug, PartialEq)]
pub struct ShotMetadata {
    pub exposure_secs: f64,
    pub gain: f64,
    /// Value at or above which a pixel is saturated, in the image's units.
    pub saturation: f32,
    /// Free-form description of the device (model, serial, backend).
    pub device: String,
}

/// A camera giving linear images.
pub trait Camera {
    fn capture(
        &mut self,
        settings: ShotSettings,
    ) -> Result<(LinearImage, ShotMetadata), DeviceError>;
}
