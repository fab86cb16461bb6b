//! The real serial stack (driver, link, codec) against the simulated firmware on a
//! pseudo-terminal: scans through lost and corrupted frames, a port pulled mid-scan, a firmware
//! reset mid-scan, and the watchdog. Motion is made fast through the profile (high speed and
//! acceleration) so the suite stays quick; ptys are created under the runner's global lock
//! (`TTYPort::pair` is not safe to call in parallel).

#![allow(clippy::unwrap_used)] // a panic in a test is a failed test

use std::time::{Duration, Instant};

use brdf_rig::devices::rig::{Rig, RigEvent};
use brdf_rig::devices::{DeviceError, Light, Turntable};
use brdf_rig::profile::{Profile, SIMULATED};
use brdf_rig::rig_factory::{self, OpenRig};
use brdf_rig::sim::{FaultControl, MoveKind, SimHandle};

/// The built-in profile, made fast: 3600 deg/s, 360000 deg/s^2 (a 1-degree step takes 3.3 ms),
/// 20 ms reply timeout, 5 ms warm-up. 100 retries (2 s) because a loaded 2-core CI machine can
/// starve the firmware thread for longer than a few timeouts; lost frames cost one timeout each.
fn fast_profile(extra: &[(&str, &str)]) -> Profile {
    let mut text = SIMULATED
        .replace("max_speed_deg_s = 90.0", "max_speed_deg_s = 3600.0")
        .replace("max_accel_deg_s2 = 180.0", "max_accel_deg_s2 = 360000.0")
        .replace("timeout_ms = 100", "timeout_ms = 20")
        .replace("retries = 5", "retries = 100")
        .replace("warmup_ms = 50", "warmup_ms = 5");
    for (a, b) in extra {
        assert!(text.contains(a), "{a}");
        text = text.replace(a, b);
    }
    Profile::parse(&text, "fast-test-profile").unwrap()
}

/// Checks the firmware's record: after the last HOME, every degree 0..360 was the target of
/// exactly one executed MOVE_ABS, in order, and nothing else moved.
fn assert_each_angle_once(sim: &brdf_rig::sim::SimHandle) {
    let moves = sim.moves();
    let abs: Vec<i32> = moves
        .iter()
        .filter(|m| m.kind == MoveKind::Abs)
        .map(|m| m.to)
        .collect();
    let want: Vec<i32> = (0..360).map(|i| i * 1000).collect();
    assert_eq!(
        abs, want,
        "every angle exactly once, in order, no duplicate"
    );
    assert!(moves.iter().all(|m| m.kind != MoveKind::Rel));
}

fn scan(tt: &mut dyn Turntable, mut each: impl FnMut(usize)) {
    for i in 0..360 {
        each(i);
        tt.move_to(i as f64).unwrap();
    }
}

#[test]
fn scan_through_five_percent_bad_frames_visits_every_angle_once() {
    let p = fast_profile(&[
        ("drop_rate = 0.0", "drop_rate = 0.025"),
        ("corrupt_rate = 0.0", "corrupt_rate = 0.025"),
        ("seed = 1", "seed = 7"),
    ]);
    let (mut r, sim, faults) = open_sim(&p);
    r.turntable.home().unwrap();
    r.light.on(1, 0.5, true).unwrap();
    for i in 0..360 {
        if let Err(e) = r.turntable.move_to(i as f64) {
            let st = r.link_stats();
            let fw = sim.stats();
            panic!("step {i}: {e}; link {st:?}; firmware {fw:?}");
        }
    }
    r.light.off(None).unwrap();

    assert_each_angle_once(&sim);
    let snap = sim.snapshot();
    assert_eq!(snap.levels, vec![0.0; 3], "light off at the end");
    assert!((snap.angle_deg - 359.0).abs() < 1e-6);
    // The faults really happened, and the driver really retried.
    let (dropped, corrupted) = faults.counts();
    assert!(
        dropped > 20 && corrupted > 20,
        "{dropped} dropped, {corrupted} corrupted"
    );
    let stats = r.link_stats();
    assert!(stats.resends > 20, "{stats:?}");
    assert!(
        sim.stats().replayed > 0,
        "some retries were answered from the id memory"
    );
}

#[test]
fn pulling_the_port_mid_scan_resumes_the_scan() {
    let p = fast_profile(&[]);
    let (mut r, sim, faults) = open_sim(&p);
    r.turntable.home().unwrap();
    r.light.on(0, 1.0, true).unwrap();
    let mut gone_at = None;
    scan(&mut r.turntable, |i| {
        if i == 120 {
            faults.unplug(Duration::from_millis(300));
            gone_at = Some(Instant::now());
        }
    });
    assert!(gone_at.unwrap().elapsed() >= Duration::from_millis(300));
    assert!(!faults.is_unplugged());
    assert_each_angle_once(&sim);
    assert!(r.link_stats().reconnects >= 1, "{:?}", r.link_stats());
    // The port was back within the watchdog timeout: the light never went off.
    assert_eq!(sim.snapshot().watchdog_trips, 0);
    assert_eq!(sim.snapshot().levels[0], 1.0);
    r.light.off(None).unwrap();
}

#[test]
fn a_firmware_reset_mid_scan_is_detected_and_the_turntable_rehomed() {
    let p = fast_profile(&[]);
    let (mut r, sim, _) = open_sim(&p);
    r.turntable.home().unwrap();
    r.light.on(2, 0.25, true).unwrap();
    let mut after_reset = None;
    let mut r_light_level = 0.0;
    {
        let tt = &mut r.turntable;
        let sim2 = sim.clone();
        for i in 0..360 {
            if i == 200 {
                sim2.reset();
                assert_eq!(
                    sim2.snapshot().levels[2],
                    0.0,
                    "a reset switches lights off"
                );
            }
            tt.move_to(i as f64).unwrap();
            if i == 200 {
                after_reset = Some(sim2.snapshot());
                r_light_level = sim2.snapshot().levels[2];
            }
        }
    }
    let snap = after_reset.unwrap();
    assert_eq!(snap.boot, 2);
    assert!(snap.homed);
    assert!(
        (r_light_level - 0.25).abs() < 1e-4,
        "light restored: {r_light_level}"
    );
    assert_each_angle_once(&sim);
    // Homed twice: at the start, and after the reset, before the move to 200 degrees.
    let moves = sim.moves();
    let homes: Vec<usize> = moves
        .iter()
        .enumerate()
        .filter(|(_, m)| m.kind == MoveKind::Home)
        .map(|(i, _)| i)
        .collect();
    assert_eq!(homes.len(), 2, "{moves:?}");
    assert_eq!(moves[homes[1]].boot, 2);
    assert_eq!(moves[homes[1] + 1].to, 200_000);
    let ev = r.events();
    assert!(ev.contains(&RigEvent::Reset {
        old_boot: 1,
        new_boot: 2
    }));
    assert!(ev.contains(&RigEvent::Rehomed));
    assert!(ev.contains(&RigEvent::LightsRestored));
    r.light.off(None).unwrap();
    assert_eq!(sim.snapshot().levels, vec![0.0; 3]);
}

/// The simulated rig of `p`, opened as every command opens it, with its state and faults.
fn open_sim(p: &Profile) -> (Rig, SimHandle, FaultControl) {
    let OpenRig { rig, sim, faults } = rig_factory::open(p, None).unwrap();
    (rig, sim.unwrap(), faults.unwrap())
}

/// The same with the driver's watchdog and heartbeat set.
fn open_sim_with(p: &Profile, watchdog_ms: u16, heartbeat: bool) -> (Rig, SimHandle) {
    let OpenRig { rig, sim, .. } = rig_factory::open_simulated(p, |s| {
        s.watchdog_ms = watchdog_ms;
        s.heartbeat = heartbeat;
    })
    .unwrap();
    (rig, sim.unwrap())
}

#[test]
fn the_watchdog_switches_the_light_off_when_the_host_goes_silent() {
    let p = fast_profile(&[]);
    // A host without heartbeat that stops talking after switching the light on.
    let (mut r, state) = open_sim_with(&p, 500, false);
    r.light.on(0, 1.0, true).unwrap();
    assert_eq!(state.snapshot().levels[0], 1.0);
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(
        state.snapshot().levels[0],
        1.0,
        "still on before the timeout"
    );
    std::thread::sleep(Duration::from_millis(700));
    let snap = state.snapshot();
    assert_eq!(snap.levels, vec![0.0; 3], "off after 500 ms of silence");
    assert_eq!(snap.watchdog_trips, 1);
    // The host notices the latched fault at its next STATUS.
    r.turntable.status().unwrap();
    assert!(r.events().contains(&RigEvent::WatchdogTripped));
}

#[test]
fn the_heartbeat_keeps_the_light_on_while_the_host_waits() {
    let p = fast_profile(&[]);
    let (mut r, state) = open_sim_with(&p, 600, true);
    r.light.on(0, 1.0, true).unwrap();
    // Three watchdog periods without a command: only the heartbeat talks.
    std::thread::sleep(Duration::from_millis(1800));
    let snap = state.snapshot();
    assert_eq!(snap.levels[0], 1.0);
    assert_eq!(snap.watchdog_trips, 0);
    assert!(state.stats().executed >= 5, "heartbeats were executed");
}

#[test]
fn limits_from_the_profile_are_checked_before_sending() {
    let p = fast_profile(&[("max_level = 1.0", "max_level = 0.5")]);
    let (mut r, sim, _) = open_sim(&p);
    r.turntable.home().unwrap();
    let before = sim.stats().executed;
    let e = r.turntable.move_to(400.0).unwrap_err();
    assert!(matches!(e, DeviceError::Limit { .. }), "{e}");
    assert!(e.to_string().contains("[-360, 360]"), "{e}");
    let e = r.turntable.move_to(f64::NAN).unwrap_err();
    assert!(matches!(e, DeviceError::Limit { .. }), "{e}");
    let e = r.light.on(0, 0.8, true).unwrap_err();
    assert!(e.to_string().contains("(0, 0.5]"), "{e}");
    let e = r.light.on(3, 0.1, true).unwrap_err();
    assert!(matches!(e, DeviceError::Limit { .. }), "{e}");
    assert!(!e.is_retryable());
    assert_eq!(sim.stats().executed, before, "nothing was sent");
    // Within limits it goes through; move_by is relative to the last target.
    r.turntable.move_to(10.0).unwrap();
    r.turntable.move_by(-25.5).unwrap();
    let s = r.turntable.status().unwrap();
    assert_eq!((s.angle_deg, s.homed, s.moving), (-15.5, true, false));
}

#[test]
fn a_move_before_homing_is_refused_with_a_clear_error() {
    let p = fast_profile(&[]);
    let (mut r, sim, _) = open_sim(&p);
    let e = r.turntable.move_to(10.0).unwrap_err();
    assert!(e.to_string().contains("home the turntable first"), "{e}");
    assert!(sim.moves().is_empty());
}

#[test]
fn a_missing_port_is_reported_with_its_path() {
    let p = fast_profile(&[]);
    let path = std::path::Path::new("/nonexistent/brdf-rig-tty");
    let e = rig_factory::open(&p, Some(path)).err().unwrap();
    assert!(matches!(e, DeviceError::Disconnected { .. }));
    assert!(e.to_string().contains("/nonexistent/brdf-rig-tty"), "{e}");
}

#[test]
fn a_port_that_never_comes_back_gives_up_in_bounded_time() {
    let p = fast_profile(&[("reconnect_ms = 3000", "reconnect_ms = 300")]);
    let (mut r, _, faults) = open_sim(&p);
    faults.unplug(Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(20));
    let t = Instant::now();
    let e = r.turntable.status().unwrap_err();
    assert!(e.is_retryable(), "{e}");
    assert!(matches!(e, DeviceError::Disconnected { .. }), "{e}");
    assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
}

#[test]
fn late_replies_and_lost_bytes_never_repeat_a_move() {
    let p = fast_profile(&[]);
    let (mut r, sim, faults) = open_sim(&p);
    r.turntable.home().unwrap();
    // Replies arrive after the 20 ms timeout: the driver re-sends the same id, takes the late
    // reply as the answer, and drops the firmware's replayed copy as stale.
    faults.set(brdf_rig::sim::LinkFaults {
        reply_delay: Duration::from_millis(30),
        ..Default::default()
    });
    for i in 1..=5 {
        r.turntable.move_to(i as f64 * 10.0).unwrap();
    }
    let stats = r.link_stats();
    assert!(stats.resends > 0 && stats.stale > 0, "{stats:?}");
    // Lost single bytes break frames anywhere, including the delimiter.
    faults.set(brdf_rig::sim::LinkFaults {
        byte_drop_rate: 0.01,
        ..Default::default()
    });
    for i in 6..=30 {
        r.turntable.move_to(i as f64 * 10.0).unwrap();
    }
    let abs: Vec<i32> = sim
        .moves()
        .iter()
        .filter(|m| m.kind == MoveKind::Abs)
        .map(|m| m.to)
        .collect();
    assert_eq!(abs, (1..=30).map(|i| i * 10_000).collect::<Vec<_>>());
    assert_eq!(r.turntable.status().unwrap().angle_deg, 300.0);
}

#[test]
fn a_reset_during_a_motion_rehomes_and_finishes_the_move() {
    // Slow enough that the reset lands mid-motion: 90 degrees at 2250 deg/s^2 takes 0.4 s.
    let p = fast_profile(&[]);
    let text = p
        .source
        .replace("max_speed_deg_s = 3600.0", "max_speed_deg_s = 900.0")
        .replace("max_accel_deg_s2 = 360000.0", "max_accel_deg_s2 = 2250.0");
    let p = Profile::parse(&text, "slow").unwrap();
    let (mut r, sim, _) = open_sim(&p);
    r.turntable.home().unwrap();
    let s2 = sim.clone();
    let resetter = std::thread::spawn(move || {
        let t = Instant::now();
        while !s2.snapshot().moving {
            assert!(
                t.elapsed() < Duration::from_secs(5),
                "the move never started"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
        std::thread::sleep(Duration::from_millis(100));
        assert!(s2.snapshot().moving, "the reset must land mid-motion");
        s2.reset();
    });
    r.turntable.move_to(90.0).unwrap();
    resetter.join().unwrap();
    let s = r.turntable.status().unwrap();
    assert_eq!((s.angle_deg, s.homed, s.moving), (90.0, true, false));
    let kinds: Vec<(MoveKind, i32, u32)> =
        sim.moves().iter().map(|m| (m.kind, m.to, m.boot)).collect();
    // The interrupted move never arrived; it runs again after homing on the new boot.
    assert_eq!(
        kinds,
        vec![
            (MoveKind::Home, 0, 1),
            (MoveKind::Abs, 90_000, 1),
            (MoveKind::Home, 0, 2),
            (MoveKind::Abs, 90_000, 2),
        ]
    );
    assert!(r.events().contains(&RigEvent::Rehomed));
}

#[test]
fn a_reset_seen_between_moves_returns_the_platter_and_the_light() {
    let p = fast_profile(&[]);
    let (mut r, sim, _) = open_sim(&p);
    r.turntable.home().unwrap();
    r.turntable.move_to(123.0).unwrap();
    r.light.on(0, 1.0, true).unwrap();
    sim.reset();
    // A capture would now take a picture: status is what it asks first.
    let s = r.turntable.status().unwrap();
    assert_eq!((s.angle_deg, s.homed, s.moving), (123.0, true, false));
    let snap = sim.snapshot();
    assert_eq!((snap.boot, snap.levels[0]), (2, 1.0));
    assert!((snap.angle_deg - 123.0).abs() < 1e-9);
    assert!(r.events().contains(&RigEvent::Resumed {
        angle_mdeg: 123_000
    }));
    // A relative move after the reset is relative to where the platter was put back.
    r.turntable.move_by(7.0).unwrap();
    assert_eq!(r.turntable.status().unwrap().angle_deg, 130.0);
}

#[test]
fn a_port_gone_longer_than_the_watchdog_comes_back_with_the_light_on() {
    let p = fast_profile(&[]);
    let OpenRig {
        rig: mut r,
        sim,
        faults,
    } = rig_factory::open_simulated(&p, |s| {
        s.watchdog_ms = 300;
        s.heartbeat = true;
    })
    .unwrap();
    let (state, faults) = (sim.unwrap(), faults.unwrap());
    r.turntable.home().unwrap();
    r.light.on(2, 1.0, true).unwrap();
    for i in 0..40 {
        if i == 20 {
            // Gone for twice the watchdog: the firmware switches the light off meanwhile.
            faults.unplug(Duration::from_millis(600));
        }
        r.turntable.move_to(i as f64).unwrap();
    }
    let snap = state.snapshot();
    assert!(snap.watchdog_trips >= 1);
    assert_eq!(snap.levels[2], 1.0, "the driver switched the light back on");
    assert_eq!(snap.angle_deg, 39.0);
    let ev = r.events();
    assert!(ev.contains(&RigEvent::WatchdogTripped), "{ev:?}");
    assert!(ev.contains(&RigEvent::LightsRestored), "{ev:?}");
}

/// A board that ignores its port for 400 ms from the host's open after it starts and after every
/// re-plug, as an Arduino's bootloader does after the reset that opening its port causes (timed
/// from the open, so a host that reconnects late on a loaded machine still meets the bootloader). With 20 ms x 3
/// attempts and no boot window the handshake gives up; with a boot window it waits the board
/// out, at start and again after the port vanished and came back.
#[test]
fn a_board_in_its_bootloader_is_waited_for_within_the_boot_window() {
    let booting = [
        ("retries = 100", "retries = 2"),
        ("seed = 1", "seed = 1\nboot_delay_ms = 400"),
    ];
    let p = fast_profile(&booting);
    assert_eq!(p.boot_window_ms(), 0, "the simulated profile has no window");
    let e = rig_factory::open(&p, None).err().unwrap();
    assert!(matches!(e, DeviceError::Timeout { .. }), "{e}");
    assert!(e.to_string().contains("20 ms per attempt"), "{e}");

    let mut with_window = booting.to_vec();
    with_window.push((
        "watchdog_ms = 2000",
        // The window is the host's whole budget after a reconnect too; 3 s leaves room for the
        // simulator's thread to be starved by the rest of the suite on 2 cores (the board boots
        // after 400 ms, and the checks below still require an answer well inside 1.5 s).
        "watchdog_ms = 2000\nboot_window_ms = 3000",
    ));
    let p = fast_profile(&with_window);
    let t = Instant::now();
    let (mut r, _, faults) = open_sim(&p);
    let stats = r.link_stats();
    let first = stats.first_reply_ms.unwrap();
    assert!(
        first >= 400,
        "answered {first} ms after opening, inside the bootloader"
    );
    assert!(stats.resends > 0, "{stats:?}");
    assert!(
        t.elapsed() < Duration::from_millis(1500),
        "{:?}",
        t.elapsed()
    );
    r.turntable.home().unwrap();
    // Unplugged and back: the board boots again, and the window starts again with the port.
    faults.unplug(Duration::from_millis(50));
    std::thread::sleep(Duration::from_millis(10));
    r.turntable.status().unwrap();
    assert_eq!(r.link_stats().reconnects, 1);
    assert!(
        r.link_stats().first_reply_ms.unwrap() >= 300,
        "{:?}",
        r.link_stats()
    );
}
