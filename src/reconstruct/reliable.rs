//! The three assumptions that pick reliable pixels (METHOD.md section 4, the paper's 3.1).
//!
//! 1. **Curvature**: SfM/MVS normals are wrong mostly where the surface is curved, so pixels with
//!    a large mean curvature |H| are dropped. The threshold is either absolute (1 / mesh unit) or
//!    a quantile of |H| over the observed pixels (the default: scale-free, so one setting works
//!    for a bunny in metres and a mug in millimetres).
//! 2. **Monotonicity** (eq. 1, Higo et al. 2010): `n_i.h_i > n_j.h_j <=> r_i > r_j`. Checked as
//!    samples are added, against every already chosen pixel *with a comparable theta_d* (within
//!    `monotonic_theta_d_tolerance`; in the paper's rig every pixel has the same theta_d, so this
//!    is "every pixel"; across light directions the ordering need not hold, Fresnel changes it).
//!    The reflectance compared is the **luminance**, the mean of the three channel reflectances,
//!    so a coloured BRDF is not rejected for channel noise.
//! 3. **Brightest pixel**: the pixel with the largest `I / E` (mean over channels) over all
//!    images is the specular peak; its normal is set to its half vector (eq. 2, n.h = 1) and it
//!    is always used (first sample, exempt from the curvature filter). `I / E` rather than
//!    reflectance because the reflectance divides by cos(theta_i), which uses the unreliable normal.
//!
//! Each assumption can be switched off for the ablation (METHOD.md section 7).
//! Pure: no I/O.

use super::observe::Observation;
use serde::{Deserialize, Serialize};

/// How the curvature threshold is given.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", content = "value", rename_all = "snake_case")]
pub enum CurvatureThreshold {
    /// Keep |H| <= this, in 1 / (mesh unit).
    Absolute(f64),
    /// Keep the pixels whose |H| is at or below this quantile (0..1) of |H| over all observations.
    Quantile(f64),
}

/// Switches and thresholds of the three assumptions.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReliableSettings {
    pub use_curvature: bool,
    pub curvature_threshold: CurvatureThreshold,
    pub use_monotonicity: bool,
    /// Radians: two pixels are compared by eq. 1 only when their theta_d differ by at most this.
    pub monotonic_theta_d_tolerance: f64,
    pub use_brightest: bool,
}

impl Default for ReliableSettings {
    fn default() -> Self {
        Self {
            use_curvature: true,
            curvature_threshold: CurvatureThreshold::Quantile(0.5),
            use_monotonicity: true,
            monotonic_theta_d_tolerance: 5f64.to_radians(),
            use_brightest: true,
        }
    }
}

impl ReliableSettings {
    /// None of the three assumptions (the ablation baseline).
    pub fn none() -> Self {
        Self {
            use_curvature: false,
            use_monotonicity: false,
            use_brightest: false,
            ..Self::default()
        }
    }
}

/// Result of the curvature filter and the brightest-pixel search.
#[derive(Clone, Debug)]
pub struct Reliable {
    /// Pixels that passed the curvature filter (all of them when it is off), brightest excluded.
    pub pixels: Vec<Observation>,
    /// The brightest pixel with n = h, when assumption 3 is on and it is above both horizons.
    pub brightest: Option<Observation>,
    /// The |H| threshold applied (absolute), when the filter is on.
    pub curvature_threshold: Option<f64>,
    /// Pixels dropped by the curvature filter.
    pub dropped_by_curvature: usize,
}

/// Applies assumptions 1 and 3 (assumption 2 acts during sample selection: [`MonotonicSet`]).
pub fn select_reliable(obs: &[Observation], settings: &ReliableSettings) -> Reliable {
    let brightest_idx = if settings.use_brightest {
        brightest_index(obs)
    } else {
        None
    };
    let brightest = brightest_idx.and_then(|i| as_peak(&obs[i]));
    let threshold = settings
        .use_curvature
        .then(|| match settings.curvature_threshold {
            CurvatureThreshold::Absolute(t) => t,
            CurvatureThreshold::Quantile(q) => quantile_abs_curvature(obs, q),
        });
    let mut pixels = Vec::with_capacity(obs.len());
    let mut dropped = 0;
    for (i, o) in obs.iter().enumerate() {
        if Some(i) == brightest_idx {
            continue;
        }
        match threshold {
            // NaN curvature counts as unreliable.
            Some(t)
                if o.mean_curvature.abs().partial_cmp(&t) != Some(std::cmp::Ordering::Greater)
                    && o.mean_curvature.is_finite() =>
            {
                pixels.push(*o)
            }
            Some(_) => dropped += 1,
            None => pixels.push(*o),
        }
    }
    Reliable {
        pixels,
        brightest,
        curvature_threshold: threshold,
        dropped_by_curvature: dropped,
    }
}

/// Index of the pixel with the largest `I / E` (mean over channels), ignoring non-finite ones.
pub fn brightest_index(obs: &[Observation]) -> Option<usize> {
    obs.iter()
        .enumerate()
        .map(|(i, o)| {
            let ie = (0..3).map(|c| o.radiance[c] / o.irradiance[c]).sum::<f64>() / 3.0;
            (i, ie)
        })
        .filter(|(_, v)| v.is_finite())
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// Eq. 2: the pixel re-observed with its normal set to its half vector (`None` when that puts
/// a direction below the horizon).
pub fn as_peak(o: &Observation) -> Option<Observation> {
    o.with_normal(o.half())
}

/// The `q` quantile (nearest rank) of |H| over the observations; 0 when there are none.
pub fn quantile_abs_curvature(obs: &[Observation], q: f64) -> f64 {
    let mut h: Vec<f64> = obs
        .iter()
        .map(|o| o.mean_curvature.abs())
        .filter(|v| v.is_finite())
        .collect();
    if h.is_empty() {
        return 0.0;
    }
    h.sort_by(f64::total_cmp);
    let rank = ((q.clamp(0.0, 1.0) * h.len() as f64).ceil() as usize).clamp(1, h.len());
    h[rank - 1]
}

/// The pixels chosen so far, against which eq. 1 is checked for each new one.
#[derive(Clone, Debug, Default)]
pub struct MonotonicSet {
    enabled: bool,
    theta_d_tolerance: f64,
    /// (n.h, luminance of r, theta_d) of each chosen pixel.
    chosen: Vec<(f64, f64, f64)>,
}

impl MonotonicSet {
    pub fn new(settings: &ReliableSettings) -> Self {
        Self {
            enabled: settings.use_monotonicity,
            theta_d_tolerance: settings.monotonic_theta_d_tolerance,
            chosen: Vec::new(),
        }
    }

    /// Whether `o` satisfies eq. 1 against every chosen pixel of comparable theta_d (always
    /// true when the assumption is off). Ties (in n.h below 1e-9, or equal reflectance)
    /// constrain nothing: a violation is a strictly opposite order.
    pub fn accepts(&self, o: &Observation) -> bool {
        if !self.enabled {
            return true;
        }
        let (ndh, lum, td) = (o.n_dot_h, o.luminance(), o.angles.theta_d);
        self.chosen.iter().all(|&(ndh_j, lum_j, td_j)| {
            if (td - td_j).abs() > self.theta_d_tolerance || (ndh - ndh_j).abs() < 1e-9 {
                return true;
            }
            (ndh - ndh_j) * (lum - lum_j) >= 0.0
        })
    }

    pub fn push(&mut self, o: &Observation) {
        self.chosen
            .push((o.n_dot_h, o.luminance(), o.angles.theta_d));
    }

    pub fn len(&self) -> usize {
        self.chosen.len()
    }

    pub fn is_empty(&self) -> bool {
        self.chosen.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::observation::Seen;
    use nalgebra::{Point3, Vector3};

    /// A pixel lit at `light_deg` from the normal in the xz plane, seen from above, with the given
    /// value and curvature.
    fn obs(light_deg: f64, value: f64, curvature: f64) -> Observation {
        let l = Vector3::new(
            light_deg.to_radians().sin(),
            0.0,
            light_deg.to_radians().cos(),
        );
        Observation::new(
            Seen {
                image: 0,
                x: 0,
                y: 0,
                position: Point3::origin(),
                normal: Vector3::z(),
                mean_curvature: curvature,
                face: crate::reconstruct::observation::NO_FACE,
            },
            l,
            Vector3::z(),
            [value; 3],
            [1.0; 3],
        )
        .unwrap()
    }

    #[test]
    fn curvature_quantile_and_absolute_thresholds() {
        let o: Vec<_> = (0..10).map(|i| obs(10.0, 0.1, i as f64 - 4.5)).collect();
        // sorted |H| = .5 .5 1.5 1.5 2.5 2.5 3.5 3.5 4.5 4.5 ; nearest rank 5 = 2.5
        assert_eq!(quantile_abs_curvature(&o, 0.5), 2.5);
        let s = ReliableSettings {
            use_brightest: false,
            ..Default::default()
        };
        let r = select_reliable(&o, &s);
        assert_eq!(r.pixels.len(), 6);
        assert_eq!(r.dropped_by_curvature, 4);
        let s = ReliableSettings {
            curvature_threshold: CurvatureThreshold::Absolute(0.6),
            ..s
        };
        assert_eq!(select_reliable(&o, &s).pixels.len(), 2);
        assert_eq!(
            select_reliable(&o, &ReliableSettings::none()).pixels.len(),
            10
        );
    }

    #[test]
    fn brightest_pixel_gets_n_equal_h_and_skips_the_curvature_filter() {
        let o = vec![
            obs(20.0, 0.1, 0.0),
            obs(40.0, 5.0, 100.0),
            obs(30.0, 0.2, 0.0),
        ];
        let r = select_reliable(&o, &ReliableSettings::default());
        let b = r.brightest.unwrap();
        assert!((b.n_dot_h - 1.0).abs() < 1e-12);
        assert!((b.normal - b.half()).norm() < 1e-12);
        // with n = h, cos(theta_i) = cos(20 deg): r = 5 / cos 20
        assert!((b.reflectance[0] - 5.0 / 20f64.to_radians().cos()).abs() < 1e-9);
        assert!(r.pixels.iter().all(|p| p.radiance[0] != 5.0));
    }

    #[test]
    fn monotonicity_rejects_a_pixel_that_breaks_the_order() {
        let mut set = MonotonicSet::new(&ReliableSettings::default());
        // light 20 deg -> n.h = cos 10 ; light 60 deg -> n.h = cos 30 (smaller)
        let a = obs(20.0, 1.0, 0.0);
        set.push(&a);
        // Smaller n.h but brighter than a: violates eq. 1 (theta_d differs by 20 deg though:
        // compared only with a wide tolerance).
        let bad = obs(60.0, 2.0, 0.0);
        assert!(set.accepts(&bad), "different theta_d: not compared");
        let mut wide = MonotonicSet::new(&ReliableSettings {
            monotonic_theta_d_tolerance: 1.0,
            ..Default::default()
        });
        wide.push(&a);
        assert!(!wide.accepts(&bad));
        assert!(wide.accepts(&obs(60.0, 0.5, 0.0)));
        let off = MonotonicSet::new(&ReliableSettings::none());
        assert!(off.accepts(&bad));
    }
}
