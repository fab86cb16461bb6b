//! How long a turntable move takes under the speed and acceleration limits the handshake
//! agrees (SET_LIMITS): a trapezoidal profile, accelerating at `a`, cruising at `v`,
//! decelerating at `a` (a triangle when the move is too short to reach `v`). The driver sizes
//! its wait for a move with it; the simulated firmware moves by it (`sim::motion`).
//!
//! Units: the wire's (millidegrees, millidegrees per second, per second squared) as f64, time in
//! seconds. Pure.

/// Duration of a rest-to-rest move of length `d` (closed form: a triangle when
/// `d <= v^2/a`).
pub fn trapezoid_time(d: f64, v: f64, a: f64) -> f64 {
    if d <= 0.0 {
        return 0.0;
    }
    if d <= v * v / a {
        2.0 * (d / a).sqrt()
    } else {
        d / v + v / a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_below_v_squared_over_a_trapezoid_above() {
        // 1 degree at 90 deg/s, 180 deg/s^2: a triangle, 2 sqrt(1/180) s.
        let t = trapezoid_time(1000.0, 90_000.0, 180_000.0);
        assert!((t - 2.0 * (1.0f64 / 180.0).sqrt()).abs() < 1e-12);
        // 90 degrees: 0.5 s up (22.5 deg), 45 deg at 90 deg/s, 0.5 s down.
        assert!((trapezoid_time(90_000.0, 90_000.0, 180_000.0) - 1.5).abs() < 1e-12);
        // The two forms meet at d = v^2/a.
        let (v, a) = (30_000.0f64, 50_000.0f64);
        let d = v * v / a;
        assert!((2.0 * (d / a).sqrt() - (d / v + v / a)).abs() < 1e-9);
        assert_eq!(trapezoid_time(0.0, v, a), 0.0);
    }
}
