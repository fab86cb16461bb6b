//! A capture's progress on the lab page: shots done, rate and time left (time waiting for the
//! operator left out), the last shot, the rig as the capture's own steps leave it, and the
//! shots' images to the preview: at most one every [`SHOT_PREVIEW_EVERY`] (or at the preview
//! rate when that is slower). The image is handed to the preview worker, never encoded on the
//! rig's thread, so the capture does not wait for it; and no extra frame is taken for the page
//! while shots are being taken (the page shows shots already made).
//!
//! Why one a second: every frame costs the server a JPEG and each watching browser a decode
//! and a repaint, and on a host whose cores the camera also needs (the simulated camera renders
//! on every core) that time comes out of the capture; a person watching an unattended run
//! reads the shots at that pace anyway. Live frames at the full preview rate are for when the
//! rig is idle and while the operator acts (`live`).

use std::cell::Cell;
use std::rc::Rc;
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::hub::Hub;
use super::preview::{Job, Source, Worker};
use super::state::{LastShot, eta_secs};
use crate::capture::{Progress, ShotRecord};
use crate::render::image::LinearImage;

/// At most one shot image a second goes to the preview during a run.
pub const SHOT_PREVIEW_EVERY: Duration = Duration::from_secs(1);

pub struct PageProgress {
    pub hub: Arc<Hub>,
    pub worker: Arc<Worker>,
    pub started: Instant,
    /// Time spent waiting for the operator (shared with the operator).
    pub waited: Rc<Cell<Duration>>,
    pub frame_interval: Duration,
    pub next_frame: Instant,
    pub total: usize,
    pub done: usize,
    pub taken_now: usize,
}

impl PageProgress {
    pub fn new(hub: Arc<Hub>, worker: Arc<Worker>, waited: Rc<Cell<Duration>>, fps: f64) -> Self {
        let now = Instant::now();
        Self {
            hub,
            worker,
            started: now,
            waited,
            frame_interval: Duration::from_secs_f64(1.0 / fps.max(0.01)).max(SHOT_PREVIEW_EVERY),
            next_frame: now,
            total: 0,
            done: 0,
            taken_now: 0,
        }
    }
}

impl Progress for PageProgress {
    fn start(&mut self, total: usize, already_done: usize) {
        self.started = Instant::now();
        self.total = total;
        self.done = already_done;
        self.hub.update(|s| {
            s.capture.total = total;
            s.capture.done = already_done;
            s.rig.polled = false;
        });
    }

    fn shot_done(&mut self, r: &ShotRecord) {
        self.taken_now += 1;
        self.done += 1;
        let busy = self
            .started
            .elapsed()
            .saturating_sub(self.waited.get())
            .as_secs_f64();
        let (rate, eta) = eta_secs(self.taken_now, busy, self.total.saturating_sub(self.done));
        let (done, taken_now) = (self.done, self.taken_now);
        let sim = self.hub.sim.as_ref().map(|h| h.snapshot());
        self.hub.update(|s| {
            let c = &mut s.capture;
            c.done = done;
            c.taken_now = taken_now;
            c.rate_per_sec = rate;
            c.eta_secs = eta;
            if r.retake.is_some() {
                c.retakes += 1;
            }
            c.last_shot = Some(LastShot {
                id: r.id.clone(),
                kind: format!("{:?}", r.kind),
                angle_deg: r.angle_deg,
                channel: r.channel,
                exposure_secs: r.exposure_secs,
            });
            // the rig as this shot found it (the host's view; `rig.sim` has the board's own)
            s.rig.angle_deg = r.measured_angle_deg;
            s.rig.homed = true;
            s.rig.moving = false;
            for l in &mut s.rig.lights {
                let on = r.channel == Some(l.channel);
                l.level = if on { r.level } else { 0.0 };
                l.stable = on;
            }
            if let Some(snap) = sim {
                s.rig.sim = Some(super::state::SimTruth::of(&snap));
            }
        });
    }

    fn shot_image(&mut self, r: &ShotRecord, image: &LinearImage) {
        let now = Instant::now();
        if now < self.next_frame || !self.hub.has_watchers() || self.worker.is_busy() {
            return;
        }
        self.next_frame = now + self.frame_interval;
        self.worker.offer(Job {
            image: image.clone(),
            saturation: r.saturation,
            source: Source::Shot { id: r.id.clone() },
            exposure_secs: r.exposure_secs,
            gain: r.gain,
        });
    }

    fn message(&mut self, text: &str) {
        self.hub.log("info", text);
    }
}
