//! Measurements of the serial stack against the simulated firmware on a pty (not timed tests:
//! figures for `docs/benchmarks-rig.md`, made by `brdf-rig bench rig`).
//!
//! Two numbers: the round trip of one STATUS request through driver, link, codec, pty and the
//! simulated firmware; and the controller's own overhead per turntable step, i.e. the wall time
//! of `move_to` minus the time the simulated motion itself takes (trapezoidal profile under the
//! profile's limits).

use std::time::{Duration, Instant};

use crate::devices::motion::trapezoid_time;
use crate::devices::{DeviceError, Turntable};
use crate::profile::Profile;
use crate::rig_factory;

#[derive(Clone, Debug)]
pub struct RigBenchOptions {
    pub round_trips: usize,
    pub steps: usize,
    pub step_deg: f64,
}

impl Default for RigBenchOptions {
    fn default() -> RigBenchOptions {
        RigBenchOptions {
            round_trips: 2000,
            steps: 40,
            step_deg: 1.0,
        }
    }
}

#[derive(Clone, Debug)]
pub struct RigBenchReport {
    pub options: RigBenchOptions,
    pub profile: String,
    pub speed_deg_s: f64,
    pub accel_deg_s2: f64,
    pub poll_ms: u64,
    /// STATUS round trip: median, 90th and 99th percentile, max.
    pub rtt: [Duration; 4],
    /// Simulated motion time of one step.
    pub motion: Duration,
    /// Wall time of one `move_to`: median, max.
    pub step_wall: [Duration; 2],
    /// Median of wall minus motion.
    pub overhead: Duration,
    /// Link counters over the whole run (resends mean a reply took longer than the timeout).
    pub link: crate::devices::link::LinkStats,
    /// Every step's wall time, in order.
    pub walls: Vec<Duration>,
}

impl RigBenchReport {
    pub fn overhead_pct(&self) -> f64 {
        100.0 * self.overhead.as_secs_f64() / self.motion.as_secs_f64()
    }

    /// The markdown page, with the command that made it and the machine it ran on.
    pub fn markdown(&self, command: &str, machine: &str) -> String {
        let ms = |d: Duration| format!("{:.3}", d.as_secs_f64() * 1000.0);
        let ok = |b: bool| if b { "met" } else { "NOT met" };
        let rtt_ok = self.rtt[0] < Duration::from_millis(2);
        let ovh_ok = self.overhead_pct() < 5.0;
        format!(
            "# Rig benchmarks\n\n\
             Serial stack (driver, link, codec) against the simulated firmware served on a\n\
             pseudo-terminal in the same process. Made by:\n\n\
             ```\n{command}\n```\n\n\
             Machine: {machine}. Profile: {profile} (speed {speed} deg/s, acceleration {accel} \
             deg/s^2, STATUS poll every {poll} ms while moving).\n\n\
             ## STATUS round trip ({n} requests)\n\n\
             | median | p90 | p99 | max | target |\n|---|---|---|---|---|\n\
             | {r0} ms | {r1} ms | {r2} ms | {r3} ms | < 2 ms: {rok} |\n\n\
             The median is the cost of the stack; the tail (p99, max) is scheduling: host, \
             firmware thread and\nwhatever else runs share the cores, and a thread that waits \
             for one waits a time slice.\n\n\
             ## Controller overhead per turntable step ({steps} steps of {step} deg)\n\n\
             The overhead is the wall time of `Turntable::move_to` minus the simulated motion \
             time of the step\n(trapezoidal profile), so it is what the host adds: the MOVE_ABS \
             round trip, STATUS polling\ngranularity, and the final STATUS that sees the platter \
             at rest.\nWith polling every {poll} ms the expected overhead is about half a poll \
             interval plus two round trips.\n\n\
             | motion time | wall (median) | wall (max) | overhead (median) | overhead | target |\n\
             |---|---|---|---|---|---|\n\
             | {m} ms | {w0} ms | {w1} ms | {o} ms | {op:.2} % | < 5 %: {ook} |\n\n\
             Link counters over the run: {req} requests, {res} re-sent after a timeout, {st} \
             stale replies, {rej} rejected frames.\n",
            profile = self.profile,
            speed = self.speed_deg_s,
            accel = self.accel_deg_s2,
            poll = self.poll_ms,
            n = self.options.round_trips,
            r0 = ms(self.rtt[0]),
            r1 = ms(self.rtt[1]),
            r2 = ms(self.rtt[2]),
            r3 = ms(self.rtt[3]),
            rok = ok(rtt_ok),
            steps = self.options.steps,
            step = self.options.step_deg,
            m = ms(self.motion),
            w0 = ms(self.step_wall[0]),
            w1 = ms(self.step_wall[1]),
            o = ms(self.overhead),
            op = self.overhead_pct(),
            ook = ok(ovh_ok),
            req = self.link.requests,
            res = self.link.resends,
            st = self.link.stale,
            rej = self.link.rejected,
        )
    }
}

fn percentile(sorted: &[Duration], q: f64) -> Duration {
    if sorted.is_empty() {
        return Duration::ZERO;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// Runs both measurements on a simulated rig spawned from `profile` (which should be
/// `port = "sim"`; the link faults of its `[sim]` section apply).
pub fn run(profile: &Profile, opts: &RigBenchOptions) -> Result<RigBenchReport, DeviceError> {
    let mut r = rig_factory::open(profile, None)?.rig;
    let tt = &mut r.turntable;
    // Warm up (page faults, first allocations), then measure.
    for _ in 0..50 {
        tt.status()?;
    }
    let mut rtt = Vec::with_capacity(opts.round_trips);
    for _ in 0..opts.round_trips {
        let t = Instant::now();
        tt.status()?;
        rtt.push(t.elapsed());
    }
    rtt.sort();

    tt.home()?;
    let v = profile.turntable.max_speed_deg_s * 1000.0;
    let a = profile.turntable.max_accel_deg_s2 * 1000.0;
    let motion = Duration::from_secs_f64(trapezoid_time(opts.step_deg.abs() * 1000.0, v, a));
    let mut walls = Vec::with_capacity(opts.steps);
    for i in 1..=opts.steps {
        let t = Instant::now();
        tt.move_to(i as f64 * opts.step_deg)?;
        walls.push(t.elapsed());
    }
    let in_order = walls.clone();
    walls.sort();
    let med = percentile(&walls, 0.5);
    Ok(RigBenchReport {
        options: opts.clone(),
        profile: profile.origin.clone(),
        speed_deg_s: profile.turntable.max_speed_deg_s,
        accel_deg_s2: profile.turntable.max_accel_deg_s2,
        poll_ms: profile.turntable.poll_ms,
        rtt: [
            percentile(&rtt, 0.5),
            percentile(&rtt, 0.9),
            percentile(&rtt, 0.99),
            percentile(&rtt, 1.0),
        ],
        motion,
        step_wall: [med, percentile(&walls, 1.0)],
        overhead: med.saturating_sub(motion),
        link: r.link_stats(),
        walls: in_order,
    })
}
