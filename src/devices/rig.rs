//! The rig over its serial link: handshake, turntable and light drivers (implementing
//! [`Turntable`] and [`Light`]), limits from the profile checked before anything is sent,
//! heartbeat, and recovery (a firmware reset seen through the boot counter leads to a new
//! handshake, homing again, and the lights switched back on, then the interrupted command
//! carries on).
//!
//! Both drivers share one [`Controller`] (one port, one request at a time) behind a mutex; a
//! heartbeat thread holds only a weak reference and sends HEARTBEAT when the link has been idle
//! for a third of the watchdog timeout, so the light stays on while the host waits on a camera.
//!
//! Moves are always sent as MOVE_ABS (a relative move is turned into an absolute target here):
//! re-sending an absolute move after a reset or a lost reply cannot add up to a double move.
//!
//! Units: degrees and levels in [0, 1] at the trait boundary, wire units (millidegrees, u16)
//! inside. Must not parse bytes (that is `protocol`) or touch the port directly (that is
//! `link`). Knows nothing of the simulated firmware: a board on a serial port and the simulated
//! one on a pseudo-terminal are the same to it (`rig_factory` chooses which to open).

use std::path::Path;
use std::sync::{Arc, Mutex, MutexGuard, Weak};
use std::time::{Duration, Instant};

use super::link::{LinkConfig, LinkStats, SerialLink};
use super::{ChannelStatus, DeviceError, Light, Turntable, TurntableStatus};
use crate::profile::Profile;
use crate::protocol::messages::{PROTOCOL_MAJOR, caps, faults};
use crate::protocol::{HelloInfo, NakCode, Reply, Request, StatusInfo};

/// Everything the driver needs, in wire units, derived from a profile.
#[derive(Clone, Debug, PartialEq)]
pub struct RigSettings {
    pub link: LinkConfig,
    pub watchdog_ms: u16,
    /// millidegrees per second (squared)
    pub max_speed: u32,
    pub max_accel: u32,
    /// millidegrees
    pub min_angle: i32,
    pub max_angle: i32,
    /// Highest level per channel, in [0, 1]; the length is the channel count the profile has.
    pub max_levels: Vec<f64>,
    pub poll: Duration,
    pub warmup_timeout: Duration,
    /// Run the heartbeat thread (off only in tests that play a silent host).
    pub heartbeat: bool,
}

impl RigSettings {
    pub fn from_profile(p: &Profile, port: &Path) -> RigSettings {
        let t = &p.turntable;
        RigSettings {
            link: LinkConfig {
                path: port.to_owned(),
                baud: p.serial.baud,
                timeout: Duration::from_millis(p.serial.timeout_ms),
                retries: p.serial.retries,
                reconnect_timeout: Duration::from_millis(p.serial.reconnect_ms),
                boot_window: Duration::from_millis(p.boot_window_ms()),
            },
            watchdog_ms: p.serial.watchdog_ms,
            max_speed: (t.max_speed_deg_s * 1000.0).round() as u32,
            max_accel: (t.max_accel_deg_s2 * 1000.0).round() as u32,
            min_angle: (t.min_angle_deg * 1000.0).round() as i32,
            max_angle: (t.max_angle_deg * 1000.0).round() as i32,
            max_levels: p.light.channels.iter().map(|c| c.max_level).collect(),
            poll: Duration::from_millis(p.turntable.poll_ms),
            warmup_timeout: Duration::from_millis(p.light.warmup_timeout_ms),
            heartbeat: true,
        }
    }
}

/// Things that happened on the link that the operator (or a test) may want to know.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RigEvent {
    /// The boot counter changed: the firmware reset.
    Reset { old_boot: u32, new_boot: u32 },
    /// Homing again after a reset or a lost position.
    Rehomed,
    /// Lights switched back on after a reset or a watchdog trip.
    LightsRestored,
    /// The firmware reported that the host went silent.
    WatchdogTripped,
    /// The firmware lost its position (stall) or forgot it was homed.
    PositionLost,
    /// Moved back to where the turntable was before a reset (millidegrees).
    Resumed { angle_mdeg: i32 },
}

/// How many times one command may be interrupted (reset, watchdog, busy) before giving up.
const MAX_INTERRUPTIONS: usize = 6;

/// One rig on one link. Shared by the turntable and light drivers.
pub struct Controller {
    link: SerialLink,
    settings: RigSettings,
    hello: HelloInfo,
    boot: u32,
    /// The host homed the turntable once and wants it kept homed (re-homed after a reset).
    want_homed: bool,
    /// Homed as far as the host knows now.
    homed: bool,
    needs_recovery: bool,
    needs_lights: bool,
    /// What the host wants lit (u16 levels), restored after a reset or watchdog trip.
    lights: Vec<u16>,
    /// The absolute target of the last move, millidegrees.
    target: Option<i32>,
    events: Vec<RigEvent>,
    /// Whatever serves the port and must live as long as the drivers (the simulated firmware
    /// on its pseudo-terminal); `None` for a board.
    _port_server: Option<PortServer>,
}

/// What serves a rig's port from inside this process, kept alive with the drivers.
pub type PortServer = Box<dyn Send>;

fn tt(reason: impl Into<String>, what: impl Into<String>) -> DeviceError {
    DeviceError::Refused {
        device: "turntable".into(),
        what: what.into(),
        reason: reason.into(),
    }
}

fn nak_reason(code: u8, detail: u8) -> String {
    match NakCode::from_u8(code) {
        Some(c) => format!("{} (detail {detail})", c.name()),
        None => format!("error code {code} (detail {detail})"),
    }
}

impl Controller {
    /// Opens the link and shakes hands.
    pub fn connect(settings: RigSettings) -> Result<Controller, DeviceError> {
        let link = SerialLink::open(settings.link.clone())?;
        let n = settings.max_levels.len();
        let mut c = Controller {
            link,
            hello: HelloInfo {
                major: 0,
                minor: 0,
                caps: 0,
                boot: 0,
                channels: 0,
                min_angle: 0,
                max_angle: 0,
                max_speed: 0,
                max_accel: 0,
                watchdog_ms: 0,
                name: String::new(),
            },
            boot: 0,
            want_homed: false,
            homed: false,
            needs_recovery: false,
            needs_lights: false,
            lights: vec![0; n],
            target: None,
            events: Vec::new(),
            settings,
            _port_server: None,
        };
        c.handshake()?;
        Ok(c)
    }

    fn device(&self) -> String {
        format!("rig on {}", self.settings.link.path.display())
    }

    pub fn hello(&self) -> &HelloInfo {
        &self.hello
    }

    pub fn settings(&self) -> &RigSettings {
        &self.settings
    }

    pub fn events(&self) -> &[RigEvent] {
        &self.events
    }

    pub fn link_stats(&self) -> LinkStats {
        self.link.stats()
    }

    /// HELLO, then the profile's watchdog and motion limits. Refuses a firmware of another
    /// major version, with fewer channels than the profile, or with hard limits below it.
    fn handshake(&mut self) -> Result<(), DeviceError> {
        let h = match self.link.request(Request::Hello)? {
            Reply::Hello(h) => h,
            r => {
                return Err(DeviceError::Protocol {
                    device: self.device(),
                    reason: format!("HELLO answered with {}", r.name()),
                });
            }
        };
        let bad = |reason: String| DeviceError::Protocol {
            device: format!("rig on {}", self.settings.link.path.display()),
            reason,
        };
        if h.major != PROTOCOL_MAJOR {
            return Err(bad(format!(
                "firmware {} speaks protocol {}.{}, this host {PROTOCOL_MAJOR}.x",
                h.name, h.major, h.minor
            )));
        }
        let limit = |what: &str, reason: String| DeviceError::Limit {
            device: format!("rig on {}", self.settings.link.path.display()),
            what: what.into(),
            reason,
        };
        if (h.channels as usize) < self.settings.max_levels.len() {
            return Err(limit(
                "light channels",
                format!(
                    "the profile has {} channels, firmware {} has {}",
                    self.settings.max_levels.len(),
                    h.name,
                    h.channels
                ),
            ));
        }
        if self.settings.max_speed > h.max_speed || self.settings.max_accel > h.max_accel {
            return Err(limit(
                "turntable speed/acceleration",
                format!(
                    "the profile asks {} deg/s, {} deg/s^2; firmware {} allows {} deg/s, {} deg/s^2",
                    self.settings.max_speed as f64 / 1000.0,
                    self.settings.max_accel as f64 / 1000.0,
                    h.name,
                    h.max_speed as f64 / 1000.0,
                    h.max_accel as f64 / 1000.0
                ),
            ));
        }
        self.boot = h.boot;
        self.hello = h;
        self.expect_ack(
            Request::SetWatchdog {
                timeout_ms: self.settings.watchdog_ms,
            },
            "set the watchdog",
        )?;
        self.hello.watchdog_ms = self.settings.watchdog_ms;
        self.expect_ack(
            Request::SetLimits {
                max_speed: self.settings.max_speed,
                max_accel: self.settings.max_accel,
            },
            "set the motion limits",
        )?;
        Ok(())
    }

    fn expect_ack(&mut self, req: Request, what: &str) -> Result<(), DeviceError> {
        match self.link.request(req)? {
            Reply::Ack => Ok(()),
            Reply::Nak { code, detail } => Err(DeviceError::Refused {
                device: self.device(),
                what: what.into(),
                reason: nak_reason(code, detail),
            }),
            r => Err(DeviceError::Protocol {
                device: self.device(),
                reason: format!("{what}: unexpected {}", r.name()),
            }),
        }
    }

    /// STATUS without interpretation (faults are latched by the firmware until read here, so
    /// every caller passes the result through [`Controller::observe`]).
    fn status_raw(&mut self) -> Result<StatusInfo, DeviceError> {
        match self.link.request(Request::Status)? {
            Reply::Status(s) => Ok(s),
            r => Err(DeviceError::Protocol {
                device: self.device(),
                reason: format!("STATUS answered with {}", r.name()),
            }),
        }
    }

    /// Reads what a STATUS reply tells about resets and faults. True when the firmware reset.
    fn observe(&mut self, s: &StatusInfo) -> bool {
        if s.faults & faults::WATCHDOG != 0 {
            self.events.push(RigEvent::WatchdogTripped);
            if self.lights.iter().any(|&l| l != 0) {
                self.needs_lights = true;
            }
        }
        if s.boot != self.boot {
            self.events.push(RigEvent::Reset {
                old_boot: self.boot,
                new_boot: s.boot,
            });
            self.homed = false;
            self.needs_recovery = true;
            return true;
        }
        if self.homed && (s.faults & faults::STALL != 0 || !s.homed) {
            self.events.push(RigEvent::PositionLost);
            self.homed = false;
            self.needs_recovery = true;
        }
        false
    }

    /// After a reset: shake hands again, home again if we had homed, light what was lit, and
    /// with `resume`, move back to the last target (a command that moves anyway, such as the
    /// next step of a scan, passes `false`: going back first would be wasted motion).
    fn recover(&mut self, resume: bool) -> Result<(), DeviceError> {
        let back_to = self.target;
        for _ in 0..MAX_INTERRUPTIONS {
            self.needs_recovery = false;
            self.handshake()?;
            if self.want_homed && !self.homed {
                self.events.push(RigEvent::Rehomed);
                if !self.run_motion(Request::Home, 0)? {
                    continue;
                }
                if let Some(t) = back_to.filter(|&t| resume && t != 0) {
                    if !self.run_motion(Request::MoveAbs { angle: t }, t)? {
                        continue;
                    }
                    self.target = Some(t);
                    self.events.push(RigEvent::Resumed { angle_mdeg: t });
                }
            }
            self.restore_lights()?;
            if !self.needs_recovery {
                return Ok(());
            }
        }
        Err(DeviceError::Fault {
            device: self.device(),
            reason: "the firmware kept resetting during recovery".into(),
        })
    }

    fn restore_lights(&mut self) -> Result<(), DeviceError> {
        self.needs_lights = false;
        let lit: Vec<(usize, u16)> = self
            .lights
            .iter()
            .enumerate()
            .filter(|(_, l)| **l != 0)
            .map(|(c, l)| (c, *l))
            .collect();
        if lit.is_empty() {
            return Ok(());
        }
        for (i, &(c, level)) in lit.iter().enumerate() {
            self.expect_ack(
                Request::LightOn {
                    channel: c as u8,
                    level,
                    exclusive: i == 0,
                },
                "switch the light back on",
            )?;
        }
        self.events.push(RigEvent::LightsRestored);
        Ok(())
    }

    fn ensure_ready(&mut self, resume: bool) -> Result<(), DeviceError> {
        if self.needs_recovery {
            self.recover(resume)?;
        }
        if self.needs_lights {
            self.restore_lights()?;
        }
        Ok(())
    }

    /// Sends one motion command and waits until at rest. `Ok(true)` when it arrived, `Ok(false)`
    /// when something interrupted it (reset, busy, stopped short) and it should be sent again.
    fn run_motion(&mut self, req: Request, target: i32) -> Result<bool, DeviceError> {
        let homing = req == Request::Home;
        let what = if homing {
            "home".to_owned()
        } else {
            format!("move to {:.3} deg", target as f64 / 1000.0)
        };
        let start_angle = self.target.unwrap_or(0);
        match self.link.request(req)? {
            Reply::Ack => {}
            Reply::Nak { code, detail } => {
                return match NakCode::from_u8(code) {
                    Some(NakCode::Busy) => {
                        self.wait_idle()?;
                        Ok(false)
                    }
                    Some(NakCode::NotHomed) => {
                        let s = self.status_raw()?;
                        if self.observe(&s) || self.want_homed {
                            self.needs_recovery = true;
                            Ok(false)
                        } else {
                            Err(tt("not homed: home the turntable first", what))
                        }
                    }
                    Some(NakCode::OutOfRange) => Err(DeviceError::Limit {
                        device: "turntable".into(),
                        what,
                        reason: format!(
                            "outside the firmware's range [{}, {}] deg",
                            self.hello.min_angle as f64 / 1000.0,
                            self.hello.max_angle as f64 / 1000.0
                        ),
                    }),
                    _ => Err(tt(nak_reason(code, detail), what)),
                };
            }
            r => {
                return Err(DeviceError::Protocol {
                    device: self.device(),
                    reason: format!("{what}: unexpected {}", r.name()),
                });
            }
        }
        let distance = if homing {
            // Unknown before homing: allow a whole revolution.
            360_000.0
        } else {
            (target - start_angle).abs() as f64
        };
        let expected = super::motion::trapezoid_time(
            distance,
            self.settings.max_speed as f64,
            self.settings.max_accel as f64,
        );
        let deadline = Instant::now()
            + Duration::from_secs_f64(2.0 * expected + 2.0)
            + self.settings.link.timeout * (self.settings.link.retries + 1);
        loop {
            std::thread::sleep(self.settings.poll);
            let s = self.status_raw()?;
            if self.observe(&s) {
                return Ok(false);
            }
            if s.moving {
                if Instant::now() > deadline {
                    return Err(DeviceError::Timeout {
                        device: "turntable".into(),
                        attempts: 1,
                        what: format!("{what}: still moving after {:.1} s", 2.0 * expected + 2.0),
                    });
                }
                continue;
            }
            if homing {
                if s.faults & faults::HOME_FAILED != 0 {
                    return Err(DeviceError::Fault {
                        device: "turntable".into(),
                        reason: "home switch not found within one revolution".into(),
                    });
                }
                if s.homed && s.angle == 0 {
                    self.want_homed = true;
                    self.homed = true;
                    self.needs_recovery = false;
                    self.target = Some(0);
                    return Ok(true);
                }
                return Ok(false);
            }
            // Stopped short (watchdog, STOP): send the move again.
            return Ok((s.angle - target).abs() <= 1);
        }
    }

    fn wait_idle(&mut self) -> Result<(), DeviceError> {
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            let s = self.status_raw()?;
            if self.observe(&s) || !s.moving {
                return Ok(());
            }
            if Instant::now() > deadline {
                return Err(DeviceError::Timeout {
                    device: "turntable".into(),
                    attempts: 1,
                    what: "waiting for a motion to end".into(),
                });
            }
            std::thread::sleep(self.settings.poll);
        }
    }

    fn motion(&mut self, req: Request, target: i32) -> Result<(), DeviceError> {
        for _ in 0..MAX_INTERRUPTIONS {
            self.ensure_ready(false)?;
            if self.run_motion(req.clone(), target)? {
                if req != Request::Home {
                    self.target = Some(target);
                }
                if self.needs_lights {
                    self.restore_lights()?;
                }
                return Ok(());
            }
        }
        Err(DeviceError::Fault {
            device: "turntable".into(),
            reason: format!("gave up after {MAX_INTERRUPTIONS} interruptions"),
        })
    }

    /// Checks a target against the profile (and the firmware's range) before sending it.
    fn checked_target(&self, angle_deg: f64) -> Result<i32, DeviceError> {
        let s = &self.settings;
        let lo = s.min_angle.max(self.hello.min_angle);
        let hi = s.max_angle.min(self.hello.max_angle);
        let mdeg = angle_deg * 1000.0;
        if !mdeg.is_finite() || mdeg.round() < lo as f64 || mdeg.round() > hi as f64 {
            return Err(DeviceError::Limit {
                device: "turntable".into(),
                what: format!("move to {angle_deg} deg"),
                reason: format!(
                    "outside the allowed range [{}, {}] deg (profile and firmware)",
                    lo as f64 / 1000.0,
                    hi as f64 / 1000.0
                ),
            });
        }
        Ok(mdeg.round() as i32)
    }

    fn light_level(&self, channel: usize, level: f64) -> Result<u16, DeviceError> {
        let Some(&max) = self.settings.max_levels.get(channel) else {
            return Err(DeviceError::Limit {
                device: "light".into(),
                what: format!("channel {channel}"),
                reason: format!(
                    "the profile has channels 0..{}",
                    self.settings.max_levels.len()
                ),
            });
        };
        if !(level > 0.0 && level <= max) {
            return Err(DeviceError::Limit {
                device: "light".into(),
                what: format!("level {level} on channel {channel}"),
                reason: format!("the profile allows (0, {max}] on this channel"),
            });
        }
        Ok(((level * 65535.0).round() as u16).max(1))
    }

    fn light_on(&mut self, channel: usize, level: f64, exclusive: bool) -> Result<(), DeviceError> {
        let raw = self.light_level(channel, level)?;
        for _ in 0..MAX_INTERRUPTIONS {
            self.ensure_ready(true)?;
            let req = Request::LightOn {
                channel: channel as u8,
                level: raw,
                exclusive,
            };
            self.expect_ack(req, &format!("switch channel {channel} on"))?;
            if exclusive {
                self.lights.iter_mut().for_each(|l| *l = 0);
            }
            self.lights[channel] = raw;
            if self.hello.caps & caps::WARMUP_SENSING == 0 {
                return Ok(());
            }
            if self.wait_stable(channel, raw)? {
                return Ok(());
            }
        }
        Err(DeviceError::Fault {
            device: "light".into(),
            reason: format!("channel {channel} kept going off while warming up"),
        })
    }

    /// Polls until `channel` is stable. `Ok(false)` when it went off meanwhile (reset or
    /// watchdog: recovery is flagged and the caller switches it on again).
    fn wait_stable(&mut self, channel: usize, raw: u16) -> Result<bool, DeviceError> {
        let deadline = Instant::now() + self.settings.warmup_timeout;
        loop {
            let chans = self.light_status_raw()?;
            let Some(c) = chans.get(channel) else {
                return Err(DeviceError::Protocol {
                    device: self.device(),
                    reason: format!("LIGHT_STATUS has no channel {channel}"),
                });
            };
            if c.level != raw {
                let s = self.status_raw()?;
                self.observe(&s);
                self.needs_lights = false;
                return Ok(false);
            }
            if c.stable {
                return Ok(true);
            }
            if Instant::now() > deadline {
                return Err(DeviceError::Timeout {
                    device: "light".into(),
                    attempts: 1,
                    what: format!(
                        "channel {channel} not stable after {} ms of warm-up",
                        self.settings.warmup_timeout.as_millis()
                    ),
                });
            }
            std::thread::sleep(self.settings.poll.max(Duration::from_millis(1)));
        }
    }

    fn light_status_raw(&mut self) -> Result<Vec<crate::protocol::ChannelState>, DeviceError> {
        match self.link.request(Request::LightStatus)? {
            Reply::LightStatus(c) => Ok(c),
            r => Err(DeviceError::Protocol {
                device: self.device(),
                reason: format!("LIGHT_STATUS answered with {}", r.name()),
            }),
        }
    }

    fn light_off(&mut self, channel: Option<usize>) -> Result<(), DeviceError> {
        let wire = match channel {
            None => 0xFF,
            Some(c) if c < self.settings.max_levels.len() => c as u8,
            Some(c) => {
                return Err(DeviceError::Limit {
                    device: "light".into(),
                    what: format!("channel {c}"),
                    reason: format!(
                        "the profile has channels 0..{}",
                        self.settings.max_levels.len()
                    ),
                });
            }
        };
        // Off needs no recovery first: a reset switches lights off anyway.
        self.expect_ack(Request::LightOff { channel: wire }, "switch the light off")?;
        match channel {
            None => self.lights.iter_mut().for_each(|l| *l = 0),
            Some(c) => self.lights[c] = 0,
        }
        self.needs_lights = self.needs_lights && self.lights.iter().any(|&l| l != 0);
        Ok(())
    }

    /// Sends HEARTBEAT when nothing went out for `idle`.
    fn heartbeat_if_idle(&mut self, idle: Duration) {
        if self.link.last_tx().elapsed() >= idle {
            let _ = self.link.request(Request::Heartbeat);
        }
    }
}

fn lock(c: &Mutex<Controller>) -> MutexGuard<'_, Controller> {
    // A panic in another thread mid-request leaves at worst a request without its reply;
    // the next request has a new id, so carrying on is safe.
    c.lock().unwrap_or_else(|p| p.into_inner())
}

/// The turntable of a rig.
pub struct SerialTurntable {
    ctl: Arc<Mutex<Controller>>,
}

impl Turntable for SerialTurntable {
    fn home(&mut self) -> Result<(), DeviceError> {
        lock(&self.ctl).motion(Request::Home, 0)
    }

    fn move_to(&mut self, angle_deg: f64) -> Result<(), DeviceError> {
        let mut c = lock(&self.ctl);
        let target = c.checked_target(angle_deg)?;
        c.motion(Request::MoveAbs { angle: target }, target)
    }

    fn move_by(&mut self, delta_deg: f64) -> Result<(), DeviceError> {
        let mut c = lock(&self.ctl);
        let from = match c.target {
            Some(t) => t,
            None => {
                let s = c.status_raw()?;
                c.observe(&s);
                s.angle
            }
        };
        let target = c.checked_target(from as f64 / 1000.0 + delta_deg)?;
        c.motion(Request::MoveAbs { angle: target }, target)
    }

    fn stop(&mut self) -> Result<(), DeviceError> {
        lock(&self.ctl).expect_ack(Request::Stop, "stop")
    }

    fn status(&mut self) -> Result<TurntableStatus, DeviceError> {
        let mut c = lock(&self.ctl);
        let mut s = c.status_raw()?;
        if c.observe(&s) {
            c.ensure_ready(true)?;
            s = c.status_raw()?;
            c.observe(&s);
        }
        Ok(TurntableStatus {
            angle_deg: s.angle as f64 / 1000.0,
            target_deg: s.target as f64 / 1000.0,
            moving: s.moving,
            homed: s.homed,
        })
    }
}

/// The light of a rig.
pub struct SerialLight {
    ctl: Arc<Mutex<Controller>>,
    channels: usize,
}

impl Light for SerialLight {
    fn channel_count(&self) -> usize {
        self.channels
    }

    fn on(&mut self, channel: usize, level: f64, exclusive: bool) -> Result<(), DeviceError> {
        lock(&self.ctl).light_on(channel, level, exclusive)
    }

    fn off(&mut self, channel: Option<usize>) -> Result<(), DeviceError> {
        lock(&self.ctl).light_off(channel)
    }

    fn status(&mut self) -> Result<Vec<ChannelStatus>, DeviceError> {
        let chans = lock(&self.ctl).light_status_raw()?;
        Ok(chans
            .iter()
            .take(self.channels)
            .map(|c| ChannelStatus {
                level: c.level as f64 / 65535.0,
                stable: c.stable,
            })
            .collect())
    }
}

/// An open rig: its drivers and what the firmware said at handshake.
pub struct Rig {
    pub turntable: SerialTurntable,
    pub light: SerialLight,
    /// The handshake (name, protocol version, boot counter, firmware limits).
    pub hello: HelloInfo,
    /// The path actually opened.
    pub port: std::path::PathBuf,
    ctl: Arc<Mutex<Controller>>,
}

impl Rig {
    /// Events seen so far (resets, re-homing, watchdog trips).
    pub fn events(&self) -> Vec<RigEvent> {
        lock(&self.ctl).events().to_vec()
    }

    pub fn link_stats(&self) -> LinkStats {
        lock(&self.ctl).link_stats()
    }

    /// The settings the rig was opened with (link timing, limits).
    pub fn settings(&self) -> RigSettings {
        lock(&self.ctl).settings().clone()
    }

    /// The drivers as trait objects (the simulated firmware and the heartbeat live as long as
    /// either of them).
    pub fn into_boxes(self) -> (Box<dyn Turntable + Send>, Box<dyn Light + Send>) {
        (Box::new(self.turntable), Box::new(self.light))
    }
}

/// Opens the rig on `port` with the profile's link, limits and channels.
pub fn open(profile: &Profile, port: &Path) -> Result<Rig, DeviceError> {
    open_with(RigSettings::from_profile(profile, port), None)
}

/// Opens a rig from explicit settings; `server` (what serves the port from inside this
/// process, if anything) lives as long as the drivers.
pub fn open_with(settings: RigSettings, server: Option<PortServer>) -> Result<Rig, DeviceError> {
    let heartbeat = settings.heartbeat;
    let watchdog = Duration::from_millis(settings.watchdog_ms as u64);
    let port = settings.link.path.clone();
    let channels = settings.max_levels.len();
    let mut c = Controller::connect(settings)?;
    c._port_server = server;
    let hello = c.hello().clone();
    let ctl = Arc::new(Mutex::new(c));
    if heartbeat {
        spawn_heartbeat(Arc::downgrade(&ctl), watchdog);
    }
    Ok(Rig {
        turntable: SerialTurntable { ctl: ctl.clone() },
        light: SerialLight {
            ctl: ctl.clone(),
            channels,
        },
        hello,
        port,
        ctl,
    })
}

/// Sends HEARTBEAT whenever the link has been idle for a third of the watchdog timeout. Holds
/// only a weak reference: the thread ends soon after the drivers are dropped.
fn spawn_heartbeat(ctl: Weak<Mutex<Controller>>, watchdog: Duration) {
    let idle = watchdog / 3;
    let tick = (watchdog / 10).clamp(Duration::from_millis(5), Duration::from_millis(100));
    let _ = std::thread::Builder::new()
        .name("brdf-rig-heartbeat".into())
        .spawn(move || {
            loop {
                std::thread::sleep(tick);
                let Some(c) = ctl.upgrade() else { return };
                // Busy means a command is talking to the firmware already.
                if let Ok(mut c) = c.try_lock() {
                    c.heartbeat_if_idle(idle);
                }
            }
        });
}
