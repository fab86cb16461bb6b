//! Trapezoidal motion profiles for the simulated turntable: accelerate at `a`, cruise at `v`,
//! decelerate at `a` (a triangle when the move is too short to reach `v`), and a plain
//! deceleration to rest for STOP and the watchdog.
//!
//! Units: the wire's (millidegrees, millidegrees per second, per second squared) as f64, time in
//! seconds since the motion started. Pure: no clock. A move's duration is the driver's
//! (`devices::motion::trapezoid_time`): the host waits for the motion the firmware makes.

use crate::devices::motion::trapezoid_time;

/// A motion in progress.
#[derive(Clone, Debug, PartialEq)]
pub enum Motion {
    /// From `from` to `to` with speed limit `v` and acceleration `a`.
    Trapezoid { from: f64, to: f64, v: f64, a: f64 },
    /// From `from`, moving at `v0` (signed), decelerating at `a` until at rest.
    Decel { from: f64, v0: f64, a: f64 },
}

impl Motion {
    /// Total duration in seconds.
    pub fn duration(&self) -> f64 {
        match *self {
            Motion::Trapezoid { from, to, v, a } => trapezoid_time((to - from).abs(), v, a),
            Motion::Decel { v0, a, .. } => v0.abs() / a,
        }
    }

    /// Position at `t` seconds (clamped to the motion's span).
    pub fn position(&self, t: f64) -> f64 {
        let t = t.clamp(0.0, self.duration());
        match *self {
            Motion::Trapezoid { from, to, v, a } => {
                let d = (to - from).abs();
                let s = (to - from).signum();
                let (t_acc, v_peak) = peak(d, v, a);
                let total = trapezoid_time(d, v, a);
                let x = if t < t_acc {
                    0.5 * a * t * t
                } else if t < total - t_acc {
                    0.5 * a * t_acc * t_acc + v_peak * (t - t_acc)
                } else {
                    let r = total - t;
                    d - 0.5 * a * r * r
                };
                from + s * x
            }
            Motion::Decel { from, v0, a } => from + v0.signum() * (v0.abs() * t - 0.5 * a * t * t),
        }
    }

    /// Signed velocity at `t` seconds.
    pub fn velocity(&self, t: f64) -> f64 {
        let total = self.duration();
        if t >= total {
            return 0.0;
        }
        let t = t.max(0.0);
        match *self {
            Motion::Trapezoid { from, to, v, a } => {
                let d = (to - from).abs();
                let (t_acc, v_peak) = peak(d, v, a);
                let speed = if t < t_acc {
                    a * t
                } else if t < total - t_acc {
                    v_peak
                } else {
                    a * (total - t)
                };
                (to - from).signum() * speed
            }
            Motion::Decel { v0, a, .. } => v0.signum() * (v0.abs() - a * t),
        }
    }

    /// Where the motion ends.
    pub fn end(&self) -> f64 {
        self.position(self.duration())
    }
}

/// Acceleration time and peak speed of a move of length `d`.
fn peak(d: f64, v: f64, a: f64) -> (f64, f64) {
    let t_full = v / a;
    if a * t_full * t_full >= d {
        let t = (d / a).sqrt();
        (t, a * t)
    } else {
        (t_full, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_and_trapezoid_durations() {
        // 1 degree at 90 deg/s, 180 deg/s^2: triangle, 2 sqrt(1/180) s.
        let m = Motion::Trapezoid {
            from: 0.0,
            to: 1000.0,
            v: 90_000.0,
            a: 180_000.0,
        };
        assert!((m.duration() - 2.0 * (1.0f64 / 180.0).sqrt()).abs() < 1e-12);
        // 90 degrees: accelerate 0.5 s (22.5 deg), cruise 45 deg for 0.5 s, decelerate 0.5 s.
        let m = Motion::Trapezoid {
            from: 0.0,
            to: 90_000.0,
            v: 90_000.0,
            a: 180_000.0,
        };
        assert!((m.duration() - 1.5).abs() < 1e-12);
        assert!((m.position(0.5) - 22_500.0).abs() < 1e-6);
        assert!((m.position(1.0) - 67_500.0).abs() < 1e-6);
        assert!((m.position(1.5) - 90_000.0).abs() < 1e-6);
        assert!((m.velocity(0.75) - 90_000.0).abs() < 1e-6);
    }

    #[test]
    fn position_is_continuous_and_monotonic() {
        let m = Motion::Trapezoid {
            from: 5000.0,
            to: -40_000.0,
            v: 30_000.0,
            a: 50_000.0,
        };
        let n = 1000;
        let mut last = m.position(0.0);
        for i in 1..=n {
            let p = m.position(m.duration() * i as f64 / n as f64);
            assert!(p <= last + 1e-9, "moving backwards at step {i}");
            assert!((p - last).abs() < 100.0, "jump at step {i}");
            last = p;
        }
        assert!((last + 40_000.0).abs() < 1e-6);
    }

    #[test]
    fn deceleration_stops_at_v_squared_over_2a() {
        let m = Motion::Decel {
            from: 0.0,
            v0: -60_000.0,
            a: 120_000.0,
        };
        assert!((m.duration() - 0.5).abs() < 1e-12);
        assert!((m.end() + 15_000.0).abs() < 1e-6);
    }
}
