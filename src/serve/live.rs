//! Live preview frames: when the rig's thread may take a picture for the page, and with which
//! camera. Live frames are taken only on the rig's thread, only while pages are connected, only
//! when the preview worker is free, at most at the preview rate, and never while a capture is
//! taking shots (then the page sees the shots themselves): when idle, and while the operator
//! acts in guided mode (so the person placing the sphere sees it on the page).
//!
//! The capture's camera and the live feed share one camera object ([`SharedCamera`]) on one
//! thread, so a real camera is never opened twice and never used by two callers at once.

use std::cell::RefCell;
use std::rc::Rc;
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::hub::Hub;
use super::preview::{Job, Source, Worker};
use crate::devices::{Camera, DeviceError, ShotMetadata, ShotSettings};
use crate::render::image::LinearImage;

/// One camera used by the capture run and by the live feed, on the rig's thread.
#[derive(Clone)]
pub struct SharedCamera(Rc<RefCell<Box<dyn Camera>>>);

impl SharedCamera {
    pub fn new(camera: Box<dyn Camera>) -> Self {
        Self(Rc::new(RefCell::new(camera)))
    }
}

impl Camera for SharedCamera {
    fn capture(
        &mut self,
        settings: ShotSettings,
    ) -> Result<(LinearImage, ShotMetadata), DeviceError> {
        let mut camera = self.0.try_borrow_mut().map_err(|_| DeviceError::Other {
            device: "camera".into(),
            reason: "already taking a picture".into(),
        })?;
        camera.capture(settings)
    }
}

/// Takes live frames for the preview when they are due.
pub struct LiveFeed {
    hub: Arc<Hub>,
    worker: Arc<Worker>,
    camera: Option<SharedCamera>,
    interval: Duration,
    next: Instant,
    /// The last camera error, logged once until a frame succeeds again.
    failing: bool,
}

impl LiveFeed {
    pub fn new(hub: Arc<Hub>, worker: Arc<Worker>, fps: f64) -> LiveFeed {
        LiveFeed {
            hub,
            worker,
            camera: None,
            interval: Duration::from_secs_f64(1.0 / fps.max(0.01)),
            next: Instant::now(),
            failing: false,
        }
    }

    /// The camera live frames come from (`None`: no live view).
    pub fn set_camera(&mut self, camera: Option<SharedCamera>) {
        self.camera = camera;
    }

    /// How long until the next frame is due.
    pub fn due_in(&self) -> Duration {
        self.next.saturating_duration_since(Instant::now())
    }

    /// Takes and hands over a frame if one is due and worth making.
    pub fn tick(&mut self) {
        let now = Instant::now();
        if now < self.next {
            return;
        }
        let Some(camera) = self.camera.as_mut() else {
            return;
        };
        if !self.hub.has_watchers() || self.worker.is_busy() {
            return;
        }
        self.next = now + self.interval;
        let p = self.hub.preview_settings();
        let settings = ShotSettings {
            exposure_secs: p.exposure_secs,
            gain: p.gain,
        };
        match camera.capture(settings) {
            Ok((image, meta)) => {
                self.failing = false;
                self.worker.offer(Job {
                    image,
                    saturation: meta.saturation,
                    source: Source::Live,
                    exposure_secs: meta.exposure_secs,
                    gain: meta.gain,
                });
            }
            Err(e) => {
                if !self.failing {
                    self.hub.log("warn", format!("live preview: {e}"));
                }
                self.failing = true;
            }
        }
    }
}
