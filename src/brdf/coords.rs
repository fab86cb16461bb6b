//! Rusinkiewicz half/difference angles and the MERL bin grid.
//!
//! Conventions (stated once here, checked by the tests below):
//! - Directions are unit vectors in the local frame, normal = +z, both pointing away from the
//!   surface: `wi` towards the light, `wo` towards the viewer.
//! - `h = (wi + wo) / |wi + wo|`, `theta_h = acos(h.z)`, `phi_h = atan2(h.y, h.x)`.
//! - The difference vector is `wi` rotated by `-phi_h` about z, then by `-theta_h` about y (the
//!   MERL reference code, `std_coords_to_half_diff_coords`): `theta_d = acos(d.z)`,
//!   `phi_d = atan2(d.y, d.x)` in `[0, 2 pi)`.
//! - MERL bins: `theta_h` bin `floor(90 sqrt(theta_h / (pi/2)))`, `theta_d` bin
//!   `floor(90 theta_d / (pi/2))`, `phi_d` bin `floor(180 (phi_d mod pi) / pi)` (reciprocity:
//!   f(phi_d) = f(phi_d + pi)), each clamped to its range; flat index
//!   `phi_d + 180 (theta_d + 90 theta_h)`.
//! - Bin centres are the middle of each bin in *index* space, so the centre of the `theta_h` bin
//!   `i` is `((i + 0.5) / 90)^2 pi/2`; a centre always maps back to its own bin.
//!
//! Pure math: no files, no other crate module.

use nalgebra::Vector3;
use std::f64::consts::{FRAC_PI_2, PI};
use std::sync::OnceLock;

/// Number of `theta_h` bins.
pub const THETA_H_BINS: usize = 90;
/// Number of `theta_d` bins.
pub const THETA_D_BINS: usize = 90;
/// Number of `phi_d` bins over `[0, pi)`.
pub const PHI_D_BINS: usize = 180;
/// Bins in one MERL channel.
pub const MERL_BINS: usize = THETA_H_BINS * THETA_D_BINS * PHI_D_BINS;

/// Rusinkiewicz angles in radians.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfDiff {
    pub theta_h: f64,
    pub phi_h: f64,
    pub theta_d: f64,
    pub phi_d: f64,
}

/// A MERL bin as its three axis indices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MerlBin {
    pub theta_h: usize,
    pub theta_d: usize,
    pub phi_d: usize,
}

fn rotate_z(v: &Vector3<f64>, angle: f64) -> Vector3<f64> {
    let (s, c) = angle.sin_cos();
    Vector3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z)
}

fn rotate_y(v: &Vector3<f64>, angle: f64) -> Vector3<f64> {
    let (s, c) = angle.sin_cos();
    Vector3::new(c * v.x + s * v.z, v.y, -s * v.x + c * v.z)
}

fn wrap_two_pi(a: f64) -> f64 {
    let w = a.rem_euclid(2.0 * PI);
    // rem_euclid can return exactly 2 pi for tiny negative inputs.
    if w >= 2.0 * PI { 0.0 } else { w }
}

impl HalfDiff {
    /// Angles of a pair of directions. `wi` and `wo` need not be normalised but must not be
    /// opposite (their sum defines the half vector).
    pub fn from_directions(wi: &Vector3<f64>, wo: &Vector3<f64>) -> Self {
        let wi = wi.normalize();
        let wo = wo.normalize();
        let h = (wi + wo).normalize();
        let theta_h = h.z.clamp(-1.0, 1.0).acos();
        let phi_h = wrap_two_pi(h.y.atan2(h.x));
        let d = rotate_y(&rotate_z(&wi, -phi_h), -theta_h);
        let theta_d = d.z.clamp(-1.0, 1.0).acos();
        let phi_d = wrap_two_pi(d.y.atan2(d.x));
        Self {
            theta_h,
            phi_h,
            theta_d,
            phi_d,
        }
    }

    /// The directions `(wi, wo)` these angles describe (inverse of [`Self::from_directions`]).
    pub fn to_directions(&self) -> (Vector3<f64>, Vector3<f64>) {
        let (st, ct) = self.theta_d.sin_cos();
        let (sp, cp) = self.phi_d.sin_cos();
        let d = Vector3::new(st * cp, st * sp, ct);
        let wi = rotate_z(&rotate_y(&d, self.theta_h), self.phi_h);
        let h = rotate_z(&rotate_y(&Vector3::z(), self.theta_h), self.phi_h);
        let wo = 2.0 * wi.dot(&h) * h - wi;
        (wi, wo)
    }

    /// The MERL bin holding these angles.
    pub fn merl_bin(&self) -> MerlBin {
        MerlBin {
            theta_h: theta_h_bin(self.theta_h),
            theta_d: theta_d_bin(self.theta_d),
            phi_d: phi_d_bin(self.phi_d),
        }
    }
}

/// `theta_h` bin: `floor(90 sqrt(theta_h / (pi/2)))`, clamped to `0..90`.
pub fn theta_h_bin(theta_h: f64) -> usize {
    if theta_h.is_nan() || theta_h <= 0.0 {
        return 0;
    }
    let x = (theta_h / FRAC_PI_2).sqrt() * THETA_H_BINS as f64;
    (x.floor() as usize).min(THETA_H_BINS - 1)
}

/// `theta_d` bin: `floor(90 theta_d / (pi/2))`, clamped to `0..90`.
pub fn theta_d_bin(theta_d: f64) -> usize {
    if theta_d.is_nan() || theta_d <= 0.0 {
        return 0;
    }
    let x = theta_d / FRAC_PI_2 * THETA_D_BINS as f64;
    (x.floor() as usize).min(THETA_D_BINS - 1)
}

/// `phi_d` bin: `floor(180 (phi_d mod pi) / pi)`, clamped to `0..180` (reciprocity folds
/// `phi_d` and `phi_d + pi` together).
pub fn phi_d_bin(phi_d: f64) -> usize {
    if phi_d.is_nan() {
        return 0;
    }
    let folded = phi_d.rem_euclid(PI);
    let x = folded / PI * PHI_D_BINS as f64;
    (x.floor() as usize).min(PHI_D_BINS - 1)
}

impl MerlBin {
    /// Flat MERL index `phi_d + 180 (theta_d + 90 theta_h)`.
    pub fn index(&self) -> usize {
        self.phi_d + PHI_D_BINS * (self.theta_d + THETA_D_BINS * self.theta_h)
    }

    /// Inverse of [`Self::index`]; `None` past the table.
    pub fn from_index(index: usize) -> Option<Self> {
        (index < MERL_BINS).then_some(Self {
            phi_d: index % PHI_D_BINS,
            theta_d: (index / PHI_D_BINS) % THETA_D_BINS,
            theta_h: index / (PHI_D_BINS * THETA_D_BINS),
        })
    }

    /// The angles at the centre of this bin, with `phi_h = 0` and `phi_d` in `[0, pi)`.
    pub fn centre(&self) -> HalfDiff {
        let u = (self.theta_h as f64 + 0.5) / THETA_H_BINS as f64;
        HalfDiff {
            theta_h: u * u * FRAC_PI_2,
            phi_h: 0.0,
            theta_d: (self.theta_d as f64 + 0.5) / THETA_D_BINS as f64 * FRAC_PI_2,
            phi_d: (self.phi_d as f64 + 0.5) / PHI_D_BINS as f64 * PI,
        }
    }

    /// `centre().to_directions()` with the centre angles' sines and cosines looked up (computed
    /// once per process): the same values, bit for bit, without the six trigonometric calls a
    /// bin costs (tabulating a model evaluates all 1.46 million bins, often several times).
    pub fn centre_directions(&self) -> (Vector3<f64>, Vector3<f64>) {
        let t = centre_trig();
        let (sh, ch) = t.theta_h[self.theta_h.min(THETA_H_BINS - 1)];
        let (st, ct) = t.theta_d[self.theta_d.min(THETA_D_BINS - 1)];
        let (sp, cp) = t.phi_d[self.phi_d.min(PHI_D_BINS - 1)];
        let d = Vector3::new(st * cp, st * sp, ct);
        // `rotate_y` by theta_h, then `rotate_z` by phi_h = 0 (an identity, written out so the
        // rounding matches `to_directions`).
        let wi = Vector3::new(ch * d.x + sh * d.z, d.y, -sh * d.x + ch * d.z);
        let wi = Vector3::new(wi.x - 0.0 * wi.y, 0.0 * wi.x + wi.y, wi.z);
        let h = Vector3::new(ch * 0.0 + sh * 1.0, 0.0, -sh * 0.0 + ch * 1.0);
        let h = Vector3::new(h.x - 0.0 * h.y, 0.0 * h.x + h.y, h.z);
        let wo = 2.0 * wi.dot(&h) * h - wi;
        (wi, wo)
    }

    /// `cos(theta_i) cos(theta_o)` at the bin centre (negative when a direction is below the
    /// horizon).
    pub fn centre_cosines(&self) -> (f64, f64) {
        let (wi, wo) = self.centre_directions();
        (wi.z, wo.z)
    }

    /// Both centre directions strictly above the horizon: the bins a BRDF is defined on.
    /// Looked up for a bin of the table (the test is made once per process for all 1.46
    /// million: every pass over a table asks it of every bin).
    pub fn is_above_horizon(&self) -> bool {
        if self.theta_h < THETA_H_BINS && self.theta_d < THETA_D_BINS && self.phi_d < PHI_D_BINS {
            above_horizon()[self.index()]
        } else {
            self.centre_above_horizon()
        }
    }

    fn centre_above_horizon(&self) -> bool {
        let (ci, co) = self.centre_cosines();
        ci > 0.0 && co > 0.0
    }
}

/// [`MerlBin::is_above_horizon`] of every bin, by index, computed once per process, serially:
/// a rayon worker running parallel work inside the initialiser could take, while it waits,
/// another task that asks for the same lock, and wait for itself.
fn above_horizon() -> &'static [bool] {
    static ABOVE: OnceLock<Vec<bool>> = OnceLock::new();
    ABOVE.get_or_init(|| {
        (0..MERL_BINS)
            .map(|i| MerlBin::from_index(i).is_some_and(|b| b.centre_above_horizon()))
            .collect()
    })
}

/// Sines and cosines of the bin centres' angles, per axis (`MerlBin::centre`'s angles).
struct CentreTrig {
    theta_h: Vec<(f64, f64)>,
    theta_d: Vec<(f64, f64)>,
    phi_d: Vec<(f64, f64)>,
}

fn centre_trig() -> &'static CentreTrig {
    static TRIG: OnceLock<CentreTrig> = OnceLock::new();
    TRIG.get_or_init(|| {
        let at = |theta_h: usize, theta_d: usize, phi_d: usize| {
            MerlBin {
                theta_h,
                theta_d,
                phi_d,
            }
            .centre()
        };
        CentreTrig {
            theta_h: (0..THETA_H_BINS)
                .map(|i| at(i, 0, 0).theta_h.sin_cos())
                .collect(),
            theta_d: (0..THETA_D_BINS)
                .map(|i| at(0, i, 0).theta_d.sin_cos())
                .collect(),
            phi_d: (0..PHI_D_BINS)
                .map(|i| at(0, 0, i).phi_d.sin_cos())
                .collect(),
        }
    })
}

/// The MERL bin index of a pair of directions.
pub fn merl_index(wi: &Vector3<f64>, wo: &Vector3<f64>) -> usize {
    HalfDiff::from_directions(wi, wo).merl_bin().index()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(theta: f64, phi: f64) -> Vector3<f64> {
        Vector3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    fn close(a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
        (a - b).norm() < 1e-12
    }

    #[test]
    fn the_looked_up_horizon_test_is_the_computed_one() {
        let mut above = 0;
        for index in (0..MERL_BINS).step_by(3) {
            let b = MerlBin::from_index(index).unwrap();
            let (wi, wo) = b.centre().to_directions();
            assert_eq!(b.is_above_horizon(), wi.z > 0.0 && wo.z > 0.0, "{b:?}");
            above += usize::from(b.is_above_horizon());
        }
        // both kinds occur, and a bin past the table is still answered
        assert!(above > 0 && above < MERL_BINS.div_ceil(3));
        let past = MerlBin {
            theta_h: THETA_H_BINS + 2,
            theta_d: 3,
            phi_d: 5,
        };
        let (ci, co) = past.centre_cosines();
        assert_eq!(past.is_above_horizon(), ci > 0.0 && co > 0.0);
    }

    #[test]
    fn looked_up_centre_directions_equal_the_computed_ones_bit_for_bit() {
        for index in (0..MERL_BINS).step_by(7) {
            let b = MerlBin::from_index(index).unwrap();
            assert_eq!(b.centre_directions(), b.centre().to_directions(), "{b:?}");
        }
    }

    #[test]
    fn directions_round_trip_through_angles() {
        for i in 0..17 {
            for j in 0..13 {
                let wi = unit(0.05 + 1.4 * i as f64 / 17.0, 0.3 + 0.47 * j as f64);
                let wo = unit(0.02 + 1.5 * j as f64 / 13.0, -1.1 + 0.39 * i as f64);
                let hd = HalfDiff::from_directions(&wi, &wo);
                let (wi2, wo2) = hd.to_directions();
                assert!(close(&wi, &wi2) && close(&wo, &wo2), "{wi:?} {wo:?} {hd:?}");
            }
        }
    }

    #[test]
    fn angles_round_trip_through_directions() {
        for &(th, ph, td, pd) in &[
            (0.3, 0.0, 0.4, 0.5),
            (0.1, 2.0, 1.2, 3.5),
            (0.7, 5.0, 0.2, 6.0),
            (1.0, 1.0, 0.5, 1.5),
        ] {
            let hd = HalfDiff {
                theta_h: th,
                phi_h: ph,
                theta_d: td,
                phi_d: pd,
            };
            let (wi, wo) = hd.to_directions();
            let back = HalfDiff::from_directions(&wi, &wo);
            for (a, b) in [
                (hd.theta_h, back.theta_h),
                (hd.phi_h, back.phi_h),
                (hd.theta_d, back.theta_d),
                (hd.phi_d, back.phi_d),
            ] {
                assert!((a - b).abs() < 1e-10, "{hd:?} -> {back:?}");
            }
        }
    }

    #[test]
    fn closed_form_cases() {
        // Mirror configuration in the xz plane: h = n, theta_d = angle of incidence.
        let t = 0.6;
        let hd = HalfDiff::from_directions(&unit(t, 0.0), &unit(t, PI));
        assert!(hd.theta_h.abs() < 1e-12);
        assert!((hd.theta_d - t).abs() < 1e-12);
        // Retro-reflection: wi = wo, so h = wi, theta_h = theta_i and theta_d = 0.
        let hd = HalfDiff::from_directions(&unit(0.8, 1.0), &unit(0.8, 1.0));
        assert!((hd.theta_h - 0.8).abs() < 1e-12 && hd.theta_d.abs() < 1e-7);
        // In-plane, light at +x tilt a, view at -x tilt b: theta_h = |a - b| / 2,
        // theta_d = (a + b) / 2, and d lies in the xz plane (phi_d = 0 or pi).
        let (a, b) = (0.9, 0.3);
        let hd = HalfDiff::from_directions(&unit(a, 0.0), &unit(b, PI));
        assert!((hd.theta_h - (a - b) / 2.0).abs() < 1e-12);
        assert!((hd.theta_d - (a + b) / 2.0).abs() < 1e-12);
        assert!(hd.phi_d.sin().abs() < 1e-12);
        // Light and view at the same tilt in perpendicular planes: h in between, d along y.
        let hd = HalfDiff::from_directions(&unit(0.5, 0.0), &unit(0.5, FRAC_PI_2));
        assert!((hd.phi_h - PI / 4.0).abs() < 1e-12);
        assert!(
            ((hd.phi_d - 3.0 * FRAC_PI_2).abs() < 1e-9) || ((hd.phi_d - FRAC_PI_2).abs() < 1e-9)
        );
    }

    #[test]
    fn merl_bin_formulas() {
        assert_eq!(theta_h_bin(0.0), 0);
        assert_eq!(theta_h_bin(-0.1), 0);
        assert_eq!(theta_h_bin(FRAC_PI_2), 89);
        // sqrt(x / (pi/2)) * 90 = 45 exactly at x = pi/8.
        assert_eq!(theta_h_bin(PI / 8.0 * 1.000001), 45);
        assert_eq!(theta_h_bin(PI / 8.0 * 0.999999), 44);
        assert_eq!(theta_d_bin(FRAC_PI_2 * 0.5 + 1e-9), 45);
        assert_eq!(theta_d_bin(FRAC_PI_2), 89);
        assert_eq!(phi_d_bin(0.0), 0);
        assert_eq!(phi_d_bin(PI - 1e-9), 179);
        // Reciprocity: phi_d and phi_d + pi share a bin.
        for k in 0..50 {
            let p = 0.0123 + k as f64 * 0.0611;
            assert_eq!(phi_d_bin(p), phi_d_bin(p + PI));
        }
        assert_eq!(phi_d_bin(PI / 2.0 + 1e-9), 90);
        let bin = MerlBin {
            theta_h: 2,
            theta_d: 3,
            phi_d: 4,
        };
        assert_eq!(bin.index(), 4 + 180 * (3 + 90 * 2));
        assert_eq!(MerlBin::from_index(MERL_BINS), None);
    }

    #[test]
    fn index_and_centres_round_trip() {
        for index in (0..MERL_BINS).step_by(997).chain([0, MERL_BINS - 1]) {
            let bin = MerlBin::from_index(index).expect("in range");
            assert_eq!(bin.index(), index);
            assert_eq!(bin.centre().merl_bin(), bin);
            // Through directions as well (with phi_h = 0).
            let (wi, wo) = bin.centre().to_directions();
            assert_eq!(merl_index(&wi, &wo), index, "{bin:?}");
        }
    }

    #[test]
    fn horizon_test_matches_geometry() {
        // Near-normal light and view: above. theta_h + theta_d far past 90 deg at phi_d = 0:
        // the viewer is below the horizon.
        let low = MerlBin {
            theta_h: 1,
            theta_d: 1,
            phi_d: 0,
        };
        assert!(low.is_above_horizon());
        let past = MerlBin {
            theta_h: 80,
            theta_d: 70,
            phi_d: 0,
        };
        assert!(!past.is_above_horizon());
    }
}
