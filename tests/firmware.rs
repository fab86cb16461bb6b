//! The C reference firmware in QEMU (`qemu-system-avr -M mega2560`), driven over its serial
//! pseudo-terminal. Handshake, home, a scan with the light and the heartbeat go through the
//! project's serial driver (`devices::rig`), as on a bench. NAK codes, a retried move and the
//! watchdog's exact effects are checked at the byte level (`RawLink`), because a driver never
//! sends a malformed request or re-uses an id on purpose. The QEMU build (`make qemu`) finds "home" after 5 degrees of travel (SIM_HOME=1,
//! there is no switch) and uses 800 steps per turn (0.45 degree steps); at rest on a target it
//! reports the target as the angle.

use crate::firmware_qemu::{Qemu, RawLink, RawStatus, parse_status};
use brdf_rig::devices::link::LinkConfig;
use brdf_rig::devices::rig::{RigEvent, RigSettings, open_with};
use brdf_rig::devices::{Light, Turntable};
use std::time::{Duration, Instant};

const HELLO: u8 = 0x01;
const HEARTBEAT: u8 = 0x02;
const SET_WATCHDOG: u8 = 0x03;
const SET_LIMITS: u8 = 0x04;
const HOME: u8 = 0x10;
const MOVE_ABS: u8 = 0x11;
const MOVE_REL: u8 = 0x12;
const STOP: u8 = 0x13;
const STATUS: u8 = 0x14;
const LIGHT_ON: u8 = 0x20;
const LIGHT_OFF: u8 = 0x21;
const LIGHT_STATUS: u8 = 0x22;
const ACK: u8 = 0x80;
const NAK: u8 = 0x81;
const HELLO_REPLY: u8 = 0x82;
const LIGHT_STATUS_REPLY: u8 = 0x84;

struct Rig {
    link: RawLink,
    next_id: u16,
    _qemu: Qemu,
}

impl Rig {
    fn boot() -> Rig {
        let qemu = Qemu::start();
        let link = RawLink::open(qemu.pty());
        Rig {
            link,
            next_id: 1,
            _qemu: qemu,
        }
    }

    fn id(&mut self) -> u16 {
        let id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1).max(1);
        id
    }

    fn request(&mut self, kind: u8, body: &[u8]) -> crate::firmware_qemu::RawFrame {
        let id = self.id();
        self.link.request(kind, id, body)
    }

    fn ack(&mut self, kind: u8, body: &[u8]) {
        let r = self.request(kind, body);
        assert_eq!(
            r.kind, ACK,
            "kind 0x{kind:02x} {body:?}: expected ACK, got {r:?}"
        );
    }

    /// NAK code and detail.
    fn nak(&mut self, kind: u8, body: &[u8]) -> (u8, u8) {
        let r = self.request(kind, body);
        assert_eq!(
            r.kind, NAK,
            "kind 0x{kind:02x} {body:?}: expected NAK, got {r:?}"
        );
        assert_eq!(r.body.len(), 2);
        (r.body[0], r.body[1])
    }

    fn status(&mut self) -> RawStatus {
        let r = self.request(STATUS, &[]);
        parse_status(&r)
    }

    /// Polls STATUS until the turntable is at rest.
    fn wait_at_rest(&mut self, what: &str) -> RawStatus {
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            let s = self.status();
            if !s.moving {
                return s;
            }
            assert!(
                Instant::now() < deadline,
                "{what}: still moving after 20 s: {s:?}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn home(&mut self) {
        self.ack(HOME, &[]);
        let s = self.wait_at_rest("home");
        assert!(s.homed, "not homed after HOME: {s:?}");
        assert_eq!((s.angle, s.target), (0, 0), "home is angle 0");
        assert_eq!(s.faults, 0, "no fault while homing: {s:?}");
    }

    /// (level, stable) per channel.
    fn light_status(&mut self) -> Vec<(u16, bool)> {
        let r = self.request(LIGHT_STATUS, &[]);
        assert_eq!(r.kind, LIGHT_STATUS_REPLY, "{r:?}");
        let n = r.body[0] as usize;
        assert_eq!(r.body.len(), 1 + 3 * n);
        (0..n)
            .map(|c| {
                let o = 1 + 3 * c;
                (
                    u16::from_le_bytes([r.body[o], r.body[o + 1]]),
                    r.body[o + 2] & 1 != 0,
                )
            })
            .collect()
    }
}

fn light_on(channel: u8, level: u16, exclusive: bool) -> Vec<u8> {
    let mut b = vec![channel];
    b.extend_from_slice(&level.to_le_bytes());
    b.push(exclusive as u8);
    b
}

/// At rest on a target the firmware reports exactly the target (README, "Angles").
fn assert_at(angle: i32, target: i32, what: &str) {
    assert_eq!(
        angle, target,
        "{what}: at rest, angle must equal the target"
    );
}

/// The serial driver's settings for the QEMU build (its limits are the firmware's own).
fn driver_settings(qemu: &Qemu, watchdog_ms: u16, heartbeat: bool) -> RigSettings {
    RigSettings {
        link: LinkConfig {
            path: qemu.pty().to_path_buf(),
            baud: 115_200,
            timeout: Duration::from_millis(500),
            retries: 4,
            reconnect_timeout: Duration::from_secs(2),
            boot_window: Duration::ZERO,
        },
        watchdog_ms,
        max_speed: 180_000,
        max_accel: 720_000,
        min_angle: -3_600_000,
        max_angle: 3_600_000,
        max_levels: vec![1.0; 3],
        poll: Duration::from_millis(20),
        warmup_timeout: Duration::from_secs(5),
        heartbeat,
    }
}

#[test]
fn firmware_through_the_driver_handshake_home_scan_and_light() {
    let qemu = Qemu::start();
    let mut rig = open_with(driver_settings(&qemu, 2000, true), None)
        .unwrap_or_else(|e| panic!("the driver could not connect to the firmware: {e}"));
    let h = rig.hello.clone();
    assert_eq!((h.major, h.minor), (1, 0));
    assert_eq!(h.name, "brdf-mega-qemu");
    assert_eq!(h.channels, 3);
    assert_eq!((h.min_angle, h.max_angle), (-3_600_000, 3_600_000));
    assert!(h.boot >= 1);
    assert_eq!(rig.light.channel_count(), 3);

    // Before HOME the firmware answers NOT_HOMED, which the driver reports as a refusal.
    let err = rig.turntable.move_to(10.0).expect_err("a move before home");
    assert!(err.to_string().contains("not homed"), "{err}");

    rig.turntable.home().expect("home");
    let s = rig.turntable.status().expect("status");
    assert!(s.homed && !s.moving && s.angle_deg == 0.0, "{s:?}");

    // A full turn in eight stops, one exclusive light channel lit at each.
    for stop in 1..=8u32 {
        let angle = 45.0 * stop as f64;
        rig.turntable.move_to(angle).expect("scan move");
        let s = rig.turntable.status().expect("status");
        assert_eq!((s.angle_deg, s.target_deg), (angle, angle), "{s:?}");
        let channel = (stop % 3) as usize;
        rig.light.on(channel, 0.6, true).expect("light on");
        let lights = rig.light.status().expect("light status");
        for (c, l) in lights.iter().enumerate() {
            let want = if c == channel {
                39_321.0 / 65_535.0
            } else {
                0.0
            };
            assert!((l.level - want).abs() < 1e-9, "stop {stop}: {lights:?}");
        }
    }
    // A relative move the steps cannot hit exactly (0.45 degree steps) still arrives.
    rig.turntable.move_by(-10.0).expect("relative move");
    assert_eq!(rig.turntable.status().expect("status").angle_deg, 350.0);
    rig.light.on(0, 0.25, false).expect("second channel");
    let lights = rig.light.status().expect("light status");
    assert!(lights[0].level > 0.0 && lights[2].level > 0.0, "{lights:?}");
    // No warm-up sensor (capability bit 4 clear): `stable` follows LIGHT_SETTLE_MS after on.
    assert_eq!(rig.hello.caps & 0x10, 0);
    let deadline = Instant::now() + Duration::from_secs(5);
    while !rig.light.status().expect("light status")[0].stable {
        assert!(Instant::now() < deadline, "channel 0 never reported stable");
        std::thread::sleep(Duration::from_millis(20));
    }
    rig.light.off(Some(2)).expect("one channel off");
    rig.light.off(None).expect("all off");
    assert!(
        rig.light
            .status()
            .expect("light status")
            .iter()
            .all(|l| l.level == 0.0)
    );
    assert!(
        rig.events().is_empty(),
        "no reset, no watchdog trip: {:?}",
        rig.events()
    );
}

#[test]
fn firmware_through_the_driver_heartbeat_keeps_the_light_on() {
    // The firmware's watchdog at 300 ms, the host idle for much longer (a long exposure): the
    // driver's heartbeat thread must keep the light on.
    let qemu = Qemu::start();
    let mut rig = open_with(driver_settings(&qemu, 300, true), None)
        .unwrap_or_else(|e| panic!("the driver could not connect to the firmware: {e}"));
    rig.light.on(1, 1.0, true).expect("light on");
    std::thread::sleep(Duration::from_millis(2500));
    let lights = rig.light.status().expect("light status");
    assert_eq!(lights[1].level, 1.0, "{lights:?}");
    rig.turntable.status().expect("status");
    assert!(
        !rig.events().contains(&RigEvent::WatchdogTripped),
        "{:?}",
        rig.events()
    );
}

#[test]
fn firmware_handshake_reports_name_limits_and_boot_counter() {
    let mut rig = Rig::boot();
    // id 0: always executed, never remembered (section 4).
    let r = rig.link.request(HELLO, 0, &[]);
    assert_eq!(r.kind, HELLO_REPLY, "{r:?}");
    let b = &r.body;
    assert_eq!((b[0], b[1]), (1, 0), "protocol 1.0");
    let caps = u16::from_le_bytes([b[2], b[3]]);
    assert_eq!(
        caps & 0b111,
        0b111,
        "turntable, light, home switch: caps={caps:#x}"
    );
    let boot = u32::from_le_bytes([b[4], b[5], b[6], b[7]]);
    assert!(boot >= 1, "boot counter counts this boot");
    assert_eq!(b[8], 3, "three light channels");
    let i32_at = |o: usize| i32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
    assert_eq!((i32_at(9), i32_at(13)), (-3_600_000, 3_600_000));
    assert_eq!(
        (i32_at(17), i32_at(21)),
        (180_000, 720_000),
        "QEMU build limits"
    );
    assert_eq!(u16::from_le_bytes([b[25], b[26]]), 2000, "default watchdog");
    let name_len = b[27] as usize;
    assert_eq!(&b[28..28 + name_len], b"brdf-mega-qemu");

    let s = rig.status();
    assert_eq!(s.boot, boot, "STATUS and HELLO agree on the boot counter");
    assert!(!s.homed && !s.moving && !s.enabled, "fresh boot: {s:?}");
    assert_eq!(s.faults, 0);
    rig.ack(HEARTBEAT, &[]);
    // A second HELLO with id 0 is executed again, not answered from memory.
    assert_eq!(rig.link.request(HELLO, 0, &[]).kind, HELLO_REPLY);
}

#[test]
fn firmware_naks_bad_requests_with_the_right_codes() {
    let mut rig = Rig::boot();
    // NOT_HOMED (4) before HOME.
    assert_eq!(rig.nak(MOVE_ABS, &1000i32.to_le_bytes()), (4, 0));
    assert_eq!(rig.nak(MOVE_REL, &1000i32.to_le_bytes()), (4, 0));
    // UNKNOWN_KIND (1), also for a reply kind sent as a request.
    assert_eq!(rig.nak(0x7E, &[]), (1, 0));
    assert_eq!(rig.nak(ACK, &[]), (1, 0));
    // BAD_LENGTH (2), detail = expected body length.
    assert_eq!(rig.nak(MOVE_ABS, &[1, 2]), (2, 4));
    assert_eq!(rig.nak(HELLO, &[0]), (2, 0));
    assert_eq!(rig.nak(SET_LIMITS, &[0; 4]), (2, 8));
    // BAD_CHANNEL (6), detail = channel count; LIGHT_OFF too.
    assert_eq!(rig.nak(LIGHT_ON, &light_on(3, 100, true)), (6, 3));
    assert_eq!(rig.nak(LIGHT_OFF, &[7]), (6, 3));
    // OUT_OF_RANGE (3): watchdog and limits.
    assert_eq!(rig.nak(SET_WATCHDOG, &99u16.to_le_bytes()), (3, 0));
    assert_eq!(rig.nak(SET_WATCHDOG, &60_001u16.to_le_bytes()), (3, 0));
    let limits = |s: u32, a: u32| [s.to_le_bytes(), a.to_le_bytes()].concat();
    assert_eq!(rig.nak(SET_LIMITS, &limits(0, 1000)), (3, 0));
    assert_eq!(
        rig.nak(SET_LIMITS, &limits(180_001, 1000)),
        (3, 0),
        "only lower"
    );
    rig.ack(SET_LIMITS, &limits(90_000, 360_000));
    rig.ack(SET_WATCHDOG, &5000u16.to_le_bytes());

    rig.home();
    assert_eq!(rig.nak(MOVE_ABS, &3_600_001i32.to_le_bytes()), (3, 0));
    assert_eq!(rig.nak(MOVE_ABS, &(-3_600_001i32).to_le_bytes()), (3, 0));
    // MOVE_REL is relative to the target: 0 + 3 600 001 is out of range.
    assert_eq!(rig.nak(MOVE_REL, &3_600_001i32.to_le_bytes()), (3, 0));
    // BUSY (5) while moving; STOP is always accepted and brings it to rest early.
    rig.ack(MOVE_ABS, &360_000i32.to_le_bytes());
    assert_eq!(rig.nak(MOVE_ABS, &0i32.to_le_bytes()), (5, 0));
    assert_eq!(rig.nak(HOME, &[]), (5, 0));
    rig.ack(STOP, &[]);
    let s = rig.wait_at_rest("after STOP");
    assert!(s.angle < 300_000, "STOP ended the move early: {s:?}");
    assert_at(s.angle, s.target, "target is where it stopped");
    rig.ack(STOP, &[]); // at rest: still an ACK

    // Garbage, a corrupt frame and an overlong run are dropped; the next frame is answered.
    let mut junk = vec![0x13, 0x37, 0x00];
    let mut bad_crc = crate::firmware_qemu::frame(STATUS, 900, &[]);
    bad_crc[2] ^= 0x40;
    junk.extend_from_slice(&bad_crc);
    junk.extend(std::iter::repeat_n(0x55, 100));
    junk.push(0);
    rig.link.write(&junk);
    assert!(
        rig.link.recv(Duration::from_millis(500)).is_none(),
        "dropped frames get no reply"
    );
    let s = rig.status();
    assert!(s.homed, "the firmware survived the garbage: {s:?}");
    assert_eq!(
        s.faults, 0x10,
        "100 bytes without a delimiter latch RX_OVERFLOW: {s:?}"
    );
}

/// Duration of a move of `d` (millidegrees) in the firmware's profile: a trapezoid (triangle
/// when short) that starts and ends at sqrt(2 a) steps/s rather than at rest (stepper.c).
fn trapezoid_secs(d: f64, v: f64, a: f64, steps_per_turn: f64) -> f64 {
    let mdeg_per_step = 360_000.0 / steps_per_turn;
    let v0 = ((2.0 * a / mdeg_per_step).sqrt().floor() * mdeg_per_step).min(v);
    let ramp = (v * v - v0 * v0) / (2.0 * a);
    if 2.0 * ramp >= d {
        let vp = (a * d + v0 * v0).sqrt();
        2.0 * (vp - v0) / a
    } else {
        2.0 * (v - v0) / a + (d - 2.0 * ramp) / v
    }
}

#[test]
fn firmware_moves_in_the_time_its_limits_give() {
    // Timed on the firmware's own clock (uptime_ms). QEMU's timers lag and catch up unevenly
    // (the firmware's millisecond and step timers by different amounts over a second), hence
    // the 30 % tolerance; an exact replay of the ISR's integer arithmetic gives the profile's
    // times within 3 %.
    let mut rig = Rig::boot();
    rig.home();
    let timed_move = |rig: &mut Rig, target: i32| {
        let t0 = rig.status().uptime_ms;
        rig.ack(MOVE_ABS, &target.to_le_bytes());
        let s = rig.wait_at_rest("timed move");
        assert_at(s.angle, target, "timed move");
        (s.uptime_ms - t0) as f64 / 1000.0
    };
    // 90 degrees at the hard limits, 60 degrees at a quarter of the speed and an eighth of the
    // acceleration: the profile gives 0.67 s and 1.65 s.
    let fast = timed_move(&mut rig, 90_000);
    let limits = [45_000u32.to_le_bytes(), 90_000u32.to_le_bytes()].concat();
    rig.ack(SET_LIMITS, &limits);
    let slow = timed_move(&mut rig, 30_000);
    assert!(
        slow > 1.5 * fast,
        "lower limits, slower move: {fast:.3} s, {slow:.3} s"
    );
    for (took, d, v, a) in [
        (fast, 90_000.0, 180_000.0, 720_000.0),
        (slow, 60_000.0, 45_000.0, 90_000.0),
    ] {
        let want = trapezoid_secs(d, v, a, 800.0);
        assert!(
            (took - want).abs() <= 0.3 * want + 0.1,
            "{d} mdeg at {v} mdeg/s, {a} mdeg/s^2 took {took:.3} s, the profile gives {want:.3} s"
        );
    }
}

#[test]
fn firmware_executes_a_retried_move_once() {
    let mut rig = Rig::boot();
    rig.home();
    let id = 0x4242;
    let delta = 30_000i32.to_le_bytes();
    let first = rig.link.request(MOVE_REL, id, &delta);
    assert_eq!(first.kind, ACK, "{first:?}");
    // The reply "got lost": the host re-sends the same bytes, twice, while the move runs.
    for _ in 0..2 {
        let again = rig.link.request(MOVE_REL, id, &delta);
        assert_eq!(again, first, "a retry gets the remembered reply, not BUSY");
    }
    let s = rig.wait_at_rest("retried move");
    assert_eq!(s.target, 30_000, "moved once, not three times: {s:?}");
    assert_at(s.angle, 30_000, "moved once, not three times");
    // A new id is a new move.
    assert_eq!(rig.link.request(MOVE_REL, id + 1, &delta).kind, ACK);
    let s = rig.wait_at_rest("new move");
    assert_eq!(s.target, 60_000);
    assert_at(s.angle, 60_000, "a new id moves");
    // Memory is one request deep: once another request was executed, the old id is new again
    // (a host only re-sends its latest request).
    assert_eq!(rig.link.request(MOVE_REL, id, &delta).kind, ACK);
    assert_eq!(rig.wait_at_rest("old id, later").target, 90_000);
}

#[test]
fn firmware_watchdog_switches_the_light_off_and_keeps_home() {
    let mut rig = Rig::boot();
    rig.home();
    // 500 ms on the firmware's clock. QEMU's clock runs at 0.3-1.7x the wall clock in bursts
    // on a loaded machine, so heartbeats come every 50 ms of wall time (a tenth of the timeout)
    // and the silence lasts 4 s; both spans are checked on the firmware's own uptime.
    rig.ack(SET_WATCHDOG, &500u16.to_le_bytes());
    rig.ack(LIGHT_ON, &light_on(0, 65_535, true));
    let before = rig.status();
    let wall = Instant::now();
    while wall.elapsed() < Duration::from_millis(1500)
        || rig.status().uptime_ms < before.uptime_ms + 600
    {
        std::thread::sleep(Duration::from_millis(50));
        rig.ack(HEARTBEAT, &[]);
        assert!(
            wall.elapsed() < Duration::from_secs(10),
            "QEMU's clock stood still"
        );
    }
    assert_eq!(
        rig.light_status()[0].0,
        65_535,
        "heartbeats for longer than the timeout keep the light on"
    );
    let s = rig.status();
    assert_eq!(s.faults, 0, "no trip while heartbeats arrive: {s:?}");
    // Start a long move, then fall silent.
    rig.ack(MOVE_ABS, &3_000_000i32.to_le_bytes());
    let silent_from = rig.status();
    std::thread::sleep(Duration::from_millis(4000));
    let s = rig.status();
    assert!(
        s.uptime_ms >= silent_from.uptime_ms + 500,
        "QEMU ran too slowly to test the watchdog (4 s of wall time, {} ms on the firmware)",
        s.uptime_ms - silent_from.uptime_ms
    );
    assert_eq!(s.faults & 1, 1, "WATCHDOG fault latched: {s:?}");
    assert!(s.homed, "the turntable stays homed");
    assert!(s.target < 3_000_000, "motion was stopped: {s:?}");
    assert!(rig.light_status().iter().all(|&(l, _)| l == 0), "light off");
    let s = rig.wait_at_rest("stopped by the watchdog");
    assert_eq!(
        s.faults, 0,
        "the fault was cleared by the STATUS that reported it"
    );
    // The host switches the light on again explicitly.
    rig.ack(LIGHT_ON, &light_on(0, 65_535, true));
    assert_eq!(rig.light_status()[0].0, 65_535);
}

#[test]
fn firmware_c_codec_passes_the_shared_vectors() {
    // The pure C parts (cobs.c, crc16.c, protocol.c) built for the host, run over
    // firmware-protocol/vectors/*.txt: decode to the canonical text, encode back to the bytes.
    let build = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("firmware-host");
    let out = std::process::Command::new("make")
        .arg("-C")
        .arg(crate::firmware_qemu::firmware_dir())
        .arg("host-test")
        .arg(format!("BUILD={}", build.display()))
        .output()
        .expect("run make host-test (needs make and a host C compiler; see scripts/setup.sh)");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "make host-test failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for file in ["frames.txt", "reject.txt"] {
        assert!(
            stdout.contains(file),
            "the shared vector file {file} was not checked:\n{stdout}"
        );
    }
    assert!(stdout.contains(" 0 failures"), "{stdout}");
}
