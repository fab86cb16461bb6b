//! The simulated rig firmware: a pure state machine that follows `firmware-protocol/PROTOCOL.md`
//! exactly as a board would. Feed it received bytes and the current time, get reply bytes back.
//!
//! It models what the host must cope with: motion that takes time (trapezoidal speed profile
//! under the current SET_LIMITS), lights that need a warm-up before they report `stable`, a boot
//! counter that survives resets, the host watchdog, and the memory of the last request id that
//! makes retries safe. It records every motion it executes so tests can prove that no move ran
//! twice.
//!
//! Conventions: wire units inside (millidegrees, millidegrees/s, u16 levels); time is
//! microseconds on a clock the caller owns (`now_us`, monotonic). "Physical" angle is where the
//! platter really is; the reported angle is relative to the position counter, which is zeroed at
//! boot and set by HOME (the home switch sits at physical 0).
//!
//! Must not touch ports, threads or the wall clock: `sim::runner` serves it on a pty.

use crate::protocol::frame::{self, Decoder};
use crate::protocol::messages::{
    ChannelState, HelloInfo, NakCode, PROTOCOL_MAJOR, PROTOCOL_MINOR, Packet, Reply, Request,
    StatusInfo, caps, faults,
};
use crate::protocol::{Body, Reject};

use super::motion::Motion;

/// What the simulated board is.
#[derive(Clone, Debug, PartialEq)]
pub struct FirmwareConfig {
    /// Reported in HELLO_REPLY (printable ASCII, at most 16 bytes).
    pub name: String,
    pub channels: u8,
    /// Range MOVE_ABS accepts, millidegrees.
    pub min_angle: i32,
    pub max_angle: i32,
    /// Hard limits, millidegrees/s and /s^2; SET_LIMITS may only lower them.
    pub max_speed: u32,
    pub max_accel: u32,
    /// Watchdog timeout at boot.
    pub watchdog_ms: u16,
    /// Time a channel needs after switching on or changing level before it reports stable.
    pub warmup_ms: u32,
    /// The boot counter in "non-volatile memory" before the first boot.
    pub boot_counter: u32,
    /// Physical angle at power-on (millidegrees): HOME has to travel back from it.
    pub power_on_angle: i32,
}

impl Default for FirmwareConfig {
    fn default() -> FirmwareConfig {
        FirmwareConfig {
            name: "brdf-sim".into(),
            channels: 3,
            min_angle: -3_600_000,
            max_angle: 3_600_000,
            max_speed: 90_000,
            max_accel: 180_000,
            watchdog_ms: 2000,
            warmup_ms: 50,
            boot_counter: 0,
            power_on_angle: 12_345,
        }
    }
}

/// Which motion command started a motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MoveKind {
    Home,
    Abs,
    Rel,
}

/// One motion the firmware executed (accepted and started).
#[derive(Clone, Debug, PartialEq)]
pub struct MoveRecord {
    pub id: u16,
    pub kind: MoveKind,
    /// Reported angles, millidegrees (for HOME: `to` is 0).
    pub from: i32,
    pub to: i32,
    pub boot: u32,
    pub at_us: u64,
}

/// Counters for tests and the bench.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FirmwareStats {
    pub frames: u64,
    pub dropped: u64,
    pub executed: u64,
    /// Requests answered from the last-id memory without executing them again.
    pub replayed: u64,
    pub watchdog_trips: u64,
}

/// What the simulated camera (and tests) can see of the rig at one instant.
#[derive(Clone, Debug, PartialEq)]
pub struct SimSnapshot {
    /// Physical platter angle, degrees.
    pub angle_deg: f64,
    /// Angle the firmware reports (relative to its position counter), degrees.
    pub reported_angle_deg: f64,
    pub moving: bool,
    pub homed: bool,
    /// Level of each channel in [0, 1].
    pub levels: Vec<f64>,
    pub stable: Vec<bool>,
    pub boot: u32,
    pub watchdog_trips: u64,
}

struct ActiveMotion {
    motion: Motion,
    start_us: u64,
    homing: bool,
}

pub struct SimFirmware {
    cfg: FirmwareConfig,
    boot: u32,
    boot_at_us: u64,
    decoder: Decoder,
    /// Physical angle when at rest (or where the current motion started), millidegrees.
    phys: f64,
    /// Reported = physical - offset.
    offset: f64,
    motion: Option<ActiveMotion>,
    target: i32,
    homed: bool,
    enabled: bool,
    speed: u32,
    accel: u32,
    watchdog_ms: u16,
    /// Time of the last valid frame; `None` until a host spoke after boot.
    last_rx_us: Option<u64>,
    watchdog_tripped: bool,
    faults: u16,
    levels: Vec<u16>,
    changed_at_us: Vec<u64>,
    last: Option<(u16, Reply)>,
    moves: Vec<MoveRecord>,
    stats: FirmwareStats,
}

impl SimFirmware {
    /// Powers the board on at `now_us` (the boot counter increments).
    pub fn new(cfg: FirmwareConfig, now_us: u64) -> SimFirmware {
        let n = cfg.channels as usize;
        let mut fw = SimFirmware {
            boot: cfg.boot_counter,
            boot_at_us: now_us,
            decoder: Decoder::new(),
            phys: cfg.power_on_angle as f64,
            offset: cfg.power_on_angle as f64,
            motion: None,
            target: 0,
            homed: false,
            enabled: false,
            speed: cfg.max_speed,
            accel: cfg.max_accel,
            watchdog_ms: cfg.watchdog_ms,
            last_rx_us: None,
            watchdog_tripped: false,
            faults: 0,
            levels: vec![0; n],
            changed_at_us: vec![now_us; n],
            last: None,
            moves: Vec::new(),
            stats: FirmwareStats::default(),
            cfg,
        };
        fw.boot_up(now_us);
        fw
    }

    fn boot_up(&mut self, now_us: u64) {
        self.boot = self.boot.wrapping_add(1);
        self.boot_at_us = now_us;
        self.decoder.clear();
        // The position counter starts at zero wherever the platter is.
        self.offset = self.phys;
        self.motion = None;
        self.target = 0;
        self.homed = false;
        self.enabled = false;
        self.speed = self.cfg.max_speed;
        self.accel = self.cfg.max_accel;
        self.watchdog_ms = self.cfg.watchdog_ms;
        self.last_rx_us = None;
        self.watchdog_tripped = false;
        self.faults = 0;
        for (l, t) in self.levels.iter_mut().zip(&mut self.changed_at_us) {
            *l = 0;
            *t = now_us;
        }
        self.last = None;
    }

    /// A reset (power glitch, watchdog of the MCU, reset button): the platter stops where it
    /// is, and the board boots again.
    pub fn reset(&mut self, now_us: u64) {
        self.phys = self.physical_at(now_us);
        self.boot_up(now_us);
    }

    /// Feeds received bytes; returns the reply bytes to send.
    pub fn receive(&mut self, bytes: &[u8], now_us: u64) -> Vec<u8> {
        self.advance(now_us);
        self.decoder.push(bytes);
        let mut out = Vec::new();
        while let Some(frame) = self.decoder.next_frame() {
            let reply = match frame {
                Ok(p) => {
                    self.heard(now_us);
                    match p.body {
                        Body::Request(r) => self.request(p.id, r, now_us),
                        Body::Reply(_) => Some((p.id, Reply::nak(NakCode::UnknownKind, 0))),
                    }
                }
                Err(Reject::Kind { id, .. }) => {
                    self.heard(now_us);
                    Some((id, Reply::nak(NakCode::UnknownKind, 0)))
                }
                Err(Reject::Length { id, kind, .. }) => {
                    self.heard(now_us);
                    let expected = Request::body_len(kind).unwrap_or(0) as u8;
                    Some((id, Reply::nak(NakCode::BadLength, expected)))
                }
                Err(Reject::Overflow) => {
                    self.stats.dropped += 1;
                    self.faults |= faults::RX_OVERFLOW;
                    None
                }
                Err(_) => {
                    self.stats.dropped += 1;
                    None
                }
            };
            if let Some((id, r)) = reply {
                self.stats.frames += 1;
                // Every reply this firmware builds fits a frame.
                if let Ok(bytes) = frame::encode(&Packet::reply(id, r)) {
                    out.extend(bytes);
                }
            }
        }
        out
    }

    fn heard(&mut self, now_us: u64) {
        self.last_rx_us = Some(now_us);
        self.watchdog_tripped = false;
    }

    /// Runs time forward: finishes motions, warms lights up, runs the watchdog.
    pub fn advance(&mut self, now_us: u64) {
        if let Some(m) = &self.motion {
            let t = now_us.saturating_sub(m.start_us) as f64 * 1e-6;
            if t >= m.motion.duration() {
                self.phys = m.motion.end();
                if m.homing {
                    self.phys = 0.0;
                    self.offset = 0.0;
                    self.homed = true;
                    self.target = 0;
                }
                self.motion = None;
            }
        }
        if let Some(last) = self.last_rx_us {
            let silent_us = now_us.saturating_sub(last);
            if !self.watchdog_tripped && silent_us > self.watchdog_ms as u64 * 1000 {
                self.watchdog_tripped = true;
                self.stats.watchdog_trips += 1;
                self.faults |= faults::WATCHDOG;
                for (l, t) in self.levels.iter_mut().zip(&mut self.changed_at_us) {
                    if *l != 0 {
                        *l = 0;
                        *t = now_us;
                    }
                }
                self.decelerate(now_us);
            }
        }
    }

    fn physical_at(&self, now_us: u64) -> f64 {
        match &self.motion {
            Some(m) => m
                .motion
                .position(now_us.saturating_sub(m.start_us) as f64 * 1e-6),
            None => self.phys,
        }
    }

    fn reported_at(&self, now_us: u64) -> i32 {
        (self.physical_at(now_us) - self.offset).round() as i32
    }

    /// Brings a motion to rest at the current acceleration (STOP, watchdog). An interrupted
    /// HOME leaves the turntable not homed.
    fn decelerate(&mut self, now_us: u64) {
        let Some(m) = &self.motion else { return };
        let t = now_us.saturating_sub(m.start_us) as f64 * 1e-6;
        let from = m.motion.position(t);
        let v0 = m.motion.velocity(t);
        let a = self.accel as f64;
        if v0 == 0.0 {
            self.phys = from;
            self.motion = None;
        } else {
            let decel = Motion::Decel { from, v0, a };
            self.target = (decel.end() - self.offset).round() as i32;
            self.motion = Some(ActiveMotion {
                motion: decel,
                start_us: now_us,
                homing: false,
            });
        }
    }

    fn start_motion(&mut self, to_phys: f64, now_us: u64, homing: bool) {
        let from = self.physical_at(now_us);
        self.enabled = true;
        let motion = Motion::Trapezoid {
            from,
            to: to_phys,
            v: self.speed as f64,
            a: self.accel as f64,
        };
        if motion.duration() == 0.0 {
            self.phys = to_phys;
            if homing {
                self.offset = 0.0;
                self.homed = true;
            }
            self.motion = None;
        } else {
            self.motion = Some(ActiveMotion {
                motion,
                start_us: now_us,
                homing,
            });
        }
    }

    fn request(&mut self, id: u16, r: Request, now_us: u64) -> Option<(u16, Reply)> {
        if id != 0
            && let Some((last_id, reply)) = &self.last
            && *last_id == id
        {
            self.stats.replayed += 1;
            return Some((id, reply.clone()));
        }
        self.stats.executed += 1;
        let reply = self.execute(id, r, now_us);
        if id != 0 {
            self.last = Some((id, reply.clone()));
        }
        Some((id, reply))
    }

    fn moving(&self) -> bool {
        self.motion.is_some()
    }

    fn execute(&mut self, id: u16, r: Request, now_us: u64) -> Reply {
        match r {
            Request::Hello => Reply::Hello(HelloInfo {
                major: PROTOCOL_MAJOR,
                minor: PROTOCOL_MINOR,
                caps: caps::TURNTABLE
                    | caps::LIGHT
                    | caps::HOME_SWITCH
                    | caps::SIMULTANEOUS_CHANNELS
                    | caps::WARMUP_SENSING,
                boot: self.boot,
                channels: self.cfg.channels,
                min_angle: self.cfg.min_angle,
                max_angle: self.cfg.max_angle,
                max_speed: self.cfg.max_speed,
                max_accel: self.cfg.max_accel,
                watchdog_ms: self.watchdog_ms,
                name: self.cfg.name.clone(),
            }),
            Request::Heartbeat => Reply::Ack,
            Request::SetWatchdog { timeout_ms } => {
                if (100..=60_000).contains(&timeout_ms) {
                    self.watchdog_ms = timeout_ms;
                    Reply::Ack
                } else {
                    Reply::nak(NakCode::OutOfRange, 0)
                }
            }
            Request::SetLimits {
                max_speed,
                max_accel,
            } => {
                if max_speed == 0
                    || max_accel == 0
                    || max_speed > self.cfg.max_speed
                    || max_accel > self.cfg.max_accel
                {
                    Reply::nak(NakCode::OutOfRange, 0)
                } else {
                    self.speed = max_speed;
                    self.accel = max_accel;
                    Reply::Ack
                }
            }
            Request::Home => {
                if self.moving() {
                    return Reply::nak(NakCode::Busy, 0);
                }
                let from = self.reported_at(now_us);
                self.homed = false;
                self.target = 0;
                self.record(id, MoveKind::Home, from, 0, now_us);
                self.start_motion(0.0, now_us, true);
                Reply::Ack
            }
            Request::MoveAbs { angle } => self.move_to(id, MoveKind::Abs, angle as i64, now_us),
            Request::MoveRel { delta } => {
                // PROTOCOL.md: relative to the last target, not the step-rounded position
                let to = self.target as i64 + delta as i64;
                self.move_to(id, MoveKind::Rel, to, now_us)
            }
            Request::Stop => {
                self.decelerate(now_us);
                Reply::Ack
            }
            Request::Status => {
                let s = StatusInfo {
                    angle: self.reported_at(now_us),
                    target: self.target,
                    moving: self.moving(),
                    homed: self.homed,
                    enabled: self.enabled,
                    faults: self.faults,
                    boot: self.boot,
                    uptime_ms: (now_us.saturating_sub(self.boot_at_us) / 1000) as u32,
                };
                self.faults = 0;
                Reply::Status(s)
            }
            Request::LightOn {
                channel,
                level,
                exclusive,
            } => {
                let c = channel as usize;
                if c >= self.levels.len() {
                    return Reply::nak(NakCode::BadChannel, self.cfg.channels);
                }
                if exclusive {
                    for i in 0..self.levels.len() {
                        if i != c {
                            self.set_level(i, 0, now_us);
                        }
                    }
                }
                self.set_level(c, level, now_us);
                Reply::Ack
            }
            Request::LightOff { channel } => {
                if channel == 0xFF {
                    for i in 0..self.levels.len() {
                        self.set_level(i, 0, now_us);
                    }
                    Reply::Ack
                } else if (channel as usize) < self.levels.len() {
                    self.set_level(channel as usize, 0, now_us);
                    Reply::Ack
                } else {
                    Reply::nak(NakCode::BadChannel, self.cfg.channels)
                }
            }
            Request::LightStatus => Reply::LightStatus(
                (0..self.levels.len())
                    .map(|i| ChannelState {
                        level: self.levels[i],
                        stable: self.stable(i, now_us),
                    })
                    .collect(),
            ),
        }
    }

    fn move_to(&mut self, id: u16, kind: MoveKind, to: i64, now_us: u64) -> Reply {
        if self.moving() {
            return Reply::nak(NakCode::Busy, 0);
        }
        if !self.homed {
            return Reply::nak(NakCode::NotHomed, 0);
        }
        if to < self.cfg.min_angle as i64 || to > self.cfg.max_angle as i64 {
            return Reply::nak(NakCode::OutOfRange, 0);
        }
        let to = to as i32;
        let from = self.reported_at(now_us);
        self.target = to;
        self.record(id, kind, from, to, now_us);
        self.start_motion(to as f64 + self.offset, now_us, false);
        Reply::Ack
    }

    fn record(&mut self, id: u16, kind: MoveKind, from: i32, to: i32, at_us: u64) {
        self.moves.push(MoveRecord {
            id,
            kind,
            from,
            to,
            boot: self.boot,
            at_us,
        });
    }

    fn set_level(&mut self, c: usize, level: u16, now_us: u64) {
        if self.levels[c] != level {
            self.levels[c] = level;
            self.changed_at_us[c] = now_us;
        }
    }

    fn stable(&self, c: usize, now_us: u64) -> bool {
        self.levels[c] != 0
            && now_us.saturating_sub(self.changed_at_us[c]) >= self.cfg.warmup_ms as u64 * 1000
    }

    /// Every motion executed since power-on, in order.
    pub fn moves(&self) -> &[MoveRecord] {
        &self.moves
    }

    pub fn stats(&self) -> FirmwareStats {
        self.stats
    }

    pub fn boot_counter(&self) -> u32 {
        self.boot
    }

    pub fn config(&self) -> &FirmwareConfig {
        &self.cfg
    }

    /// The rig as the camera would see it at `now_us` (runs time forward first).
    pub fn snapshot(&mut self, now_us: u64) -> SimSnapshot {
        self.advance(now_us);
        SimSnapshot {
            angle_deg: self.physical_at(now_us) / 1000.0,
            reported_angle_deg: (self.physical_at(now_us) - self.offset) / 1000.0,
            moving: self.moving(),
            homed: self.homed,
            levels: self.levels.iter().map(|&l| l as f64 / 65535.0).collect(),
            stable: (0..self.levels.len())
                .map(|i| self.stable(i, now_us))
                .collect(),
            boot: self.boot,
            watchdog_trips: self.stats.watchdog_trips,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1000;

    /// Sends one request at `now`, returns the one reply.
    fn ask(fw: &mut SimFirmware, id: u16, r: Request, now: u64) -> Reply {
        let wire = frame::encode(&Packet::request(id, r)).unwrap();
        let out = fw.receive(&wire, now);
        let mut d = Decoder::new();
        d.push(&out);
        let p = d.next_frame().unwrap().unwrap();
        assert_eq!(p.id, id);
        assert_eq!(d.next_frame(), None, "one reply per request");
        match p.body {
            Body::Reply(r) => r,
            Body::Request(_) => panic!("firmware sent a request"),
        }
    }

    fn status(fw: &mut SimFirmware, id: u16, now: u64) -> StatusInfo {
        match ask(fw, id, Request::Status, now) {
            Reply::Status(s) => s,
            r => panic!("not a status: {r:?}"),
        }
    }

    fn fast() -> FirmwareConfig {
        FirmwareConfig {
            max_speed: 90_000,
            max_accel: 180_000,
            power_on_angle: 90_000,
            ..FirmwareConfig::default()
        }
    }

    #[test]
    fn hello_reports_boot_and_limits() {
        let mut fw = SimFirmware::new(fast(), 0);
        let Reply::Hello(h) = ask(&mut fw, 1, Request::Hello, 0) else {
            panic!()
        };
        assert_eq!(
            (h.major, h.boot, h.channels, h.max_speed),
            (1, 1, 3, 90_000)
        );
        assert_eq!(h.name, "brdf-sim");
    }

    #[test]
    fn moves_need_homing_and_take_the_trapezoid_time() {
        let mut fw = SimFirmware::new(fast(), 0);
        let nak = |c: NakCode| Reply::nak(c, 0);
        assert_eq!(
            ask(&mut fw, 1, Request::MoveAbs { angle: 1000 }, 0),
            nak(NakCode::NotHomed)
        );
        // Home from physical 90 degrees: 1.5 s at 90 deg/s, 180 deg/s^2.
        assert_eq!(ask(&mut fw, 2, Request::Home, 0), Reply::Ack);
        assert_eq!(
            ask(&mut fw, 3, Request::MoveAbs { angle: 1000 }, 10 * MS),
            nak(NakCode::Busy)
        );
        let s = status(&mut fw, 4, 1400 * MS);
        assert!(s.moving && !s.homed);
        let s = status(&mut fw, 5, 1501 * MS);
        assert!(!s.moving && s.homed && s.angle == 0);
        assert_eq!(
            ask(&mut fw, 6, Request::MoveAbs { angle: 4_000_000 }, 1502 * MS),
            nak(NakCode::OutOfRange)
        );
        assert_eq!(
            ask(&mut fw, 7, Request::MoveRel { delta: -90_000 }, 2000 * MS),
            Reply::Ack
        );
        let s = status(&mut fw, 8, 2750 * MS);
        assert!(s.moving && (s.angle + 45_000).abs() < 10 && s.target == -90_000);
        let s = status(&mut fw, 9, 3501 * MS);
        assert!(!s.moving && s.angle == -90_000);
        assert_eq!(fw.moves().len(), 2);
    }

    #[test]
    fn move_rel_adds_to_the_last_target_also_after_a_stop() {
        let mut fw = SimFirmware::new(
            FirmwareConfig {
                power_on_angle: 0,
                ..fast()
            },
            0,
        );
        ask(&mut fw, 1, Request::Home, 0);
        fw.advance(MS);
        assert_eq!(
            ask(&mut fw, 2, Request::MoveAbs { angle: 90_000 }, 10 * MS),
            Reply::Ack
        );
        assert_eq!(ask(&mut fw, 3, Request::Stop, 400 * MS), Reply::Ack);
        let s = status(&mut fw, 4, 3000 * MS);
        assert!(!s.moving && s.target < 90_000, "{s:?}");
        let rest = s.target;
        assert_eq!(
            ask(&mut fw, 5, Request::MoveRel { delta: 1000 }, 3001 * MS),
            Reply::Ack
        );
        let s = status(&mut fw, 6, 6000 * MS);
        assert_eq!((s.target, s.angle), (rest + 1000, rest + 1000));
    }

    #[test]
    fn a_retried_id_is_answered_from_memory_not_executed() {
        let mut fw = SimFirmware::new(
            FirmwareConfig {
                power_on_angle: 0,
                ..fast()
            },
            0,
        );
        ask(&mut fw, 1, Request::Home, 0);
        fw.advance(MS);
        let r1 = ask(&mut fw, 2, Request::MoveRel { delta: 1000 }, 10 * MS);
        let r2 = ask(&mut fw, 2, Request::MoveRel { delta: 1000 }, 20 * MS);
        assert_eq!(
            (r1, r2),
            (Reply::Ack, Reply::Ack),
            "the retry gets the remembered ACK"
        );
        let s = status(&mut fw, 3, 2000 * MS);
        assert_eq!(s.angle, 1000, "moved once");
        assert_eq!(
            fw.moves()
                .iter()
                .filter(|m| m.kind == MoveKind::Rel)
                .count(),
            1
        );
        assert_eq!(fw.stats().replayed, 1);
        // Id 0 is never remembered.
        let a = ask(&mut fw, 0, Request::MoveRel { delta: 1000 }, 2100 * MS);
        fw.advance(4000 * MS);
        let b = ask(&mut fw, 0, Request::MoveRel { delta: 1000 }, 4000 * MS);
        assert_eq!((a, b), (Reply::Ack, Reply::Ack));
        assert_eq!(status(&mut fw, 4, 6000 * MS).angle, 3000);
    }

    #[test]
    fn watchdog_switches_lights_off_and_stops_motion() {
        let mut fw = SimFirmware::new(
            FirmwareConfig {
                power_on_angle: 0,
                ..fast()
            },
            0,
        );
        // No host yet: nothing trips.
        fw.advance(10_000 * MS);
        assert_eq!(fw.stats().watchdog_trips, 0);
        let t0 = 10_000 * MS;
        ask(&mut fw, 1, Request::SetWatchdog { timeout_ms: 500 }, t0);
        ask(&mut fw, 2, Request::Home, t0);
        let on = Request::LightOn {
            channel: 1,
            level: 40_000,
            exclusive: true,
        };
        assert_eq!(ask(&mut fw, 3, on, t0 + MS), Reply::Ack);
        ask(&mut fw, 4, Request::MoveAbs { angle: 360_000 }, t0 + 2 * MS);
        assert_eq!(fw.snapshot(t0 + 400 * MS).levels[1], 40_000.0 / 65535.0);
        let snap = fw.snapshot(t0 + 503 * MS);
        assert_eq!(
            snap.levels,
            vec![0.0; 3],
            "light off after 500 ms of silence"
        );
        assert_eq!(snap.watchdog_trips, 1);
        let s = status(&mut fw, 5, t0 + 5000 * MS);
        assert_eq!(s.faults & faults::WATCHDOG, faults::WATCHDOG);
        assert!(
            !s.moving && s.angle < 360_000,
            "decelerated short of the target"
        );
        assert!(s.homed, "the turntable stays homed");
        assert_eq!(
            status(&mut fw, 6, t0 + 5001 * MS).faults,
            0,
            "faults clear once read"
        );
    }

    #[test]
    fn reset_increments_boot_and_clears_homed_and_lights() {
        let mut fw = SimFirmware::new(
            FirmwareConfig {
                power_on_angle: 0,
                ..fast()
            },
            0,
        );
        ask(&mut fw, 1, Request::Home, 0);
        let on = Request::LightOn {
            channel: 0,
            level: 65535,
            exclusive: true,
        };
        ask(&mut fw, 2, on.clone(), MS);
        fw.reset(2 * MS);
        let s = status(&mut fw, 3, 3 * MS);
        assert_eq!((s.boot, s.homed), (2, false));
        assert_eq!(fw.snapshot(3 * MS).levels, vec![0.0; 3]);
        // The id memory is gone: the same id executes again.
        assert_eq!(ask(&mut fw, 2, on, 4 * MS), Reply::Ack);
        assert_eq!(fw.snapshot(4 * MS).levels[0], 1.0);
    }

    #[test]
    fn lights_warm_up_and_exclusive_switches_others_off() {
        let mut fw = SimFirmware::new(fast(), 0);
        ask(
            &mut fw,
            1,
            Request::LightOn {
                channel: 0,
                level: 100,
                exclusive: true,
            },
            0,
        );
        ask(
            &mut fw,
            2,
            Request::LightOn {
                channel: 2,
                level: 200,
                exclusive: false,
            },
            0,
        );
        let Reply::LightStatus(c) = ask(&mut fw, 3, Request::LightStatus, 10 * MS) else {
            panic!()
        };
        assert_eq!(
            c.iter().map(|c| c.level).collect::<Vec<_>>(),
            vec![100, 0, 200]
        );
        assert!(c.iter().all(|c| !c.stable));
        let Reply::LightStatus(c) = ask(&mut fw, 4, Request::LightStatus, 60 * MS) else {
            panic!()
        };
        assert!(c[0].stable && !c[1].stable && c[2].stable);
        ask(
            &mut fw,
            5,
            Request::LightOn {
                channel: 1,
                level: 5,
                exclusive: true,
            },
            70 * MS,
        );
        assert_eq!(fw.snapshot(70 * MS).levels[0], 0.0);
        assert_eq!(
            ask(
                &mut fw,
                6,
                Request::LightOn {
                    channel: 3,
                    level: 5,
                    exclusive: true
                },
                80 * MS
            ),
            Reply::nak(NakCode::BadChannel, 3)
        );
    }

    #[test]
    fn malformed_requests_get_naks_and_garbage_gets_nothing() {
        let mut fw = SimFirmware::new(fast(), 0);
        let bad_len = frame::encode_payload(&[0x11, 0x40, 0x00, 0x10, 0x27, 0x00]);
        let out = fw.receive(&bad_len, 0);
        assert_eq!(
            crate::protocol::vectors::decode_to_text(&out),
            "NAK id=64 code=2 detail=4"
        );
        let unknown = frame::encode_payload(&[0x05, 0x30, 0x00]);
        let out = fw.receive(&unknown, 0);
        assert_eq!(
            crate::protocol::vectors::decode_to_text(&out),
            "NAK id=48 code=1 detail=0"
        );
        assert!(
            fw.receive(&[0x05, 0x11, 0x22, 0x00, 0x42, 0x00], 0)
                .is_empty()
        );
    }
}
