//! The paper's in-plane BRDF plot (section 4): light and view in one plane through the normal,
//! the light fixed, the view swept across the plane.
//!
//! Conventions (stated once here, checked by the tests below):
//! - The plane is the local x-z plane (normal = +z, as in [`crate::brdf`]). An in-plane direction
//!   is named by its angle `alpha` from the +x axis: `(cos alpha, 0, sin alpha)`, so the normal is
//!   at 90 degrees and `alpha` runs 0..180 degrees over the upper half of the plane.
//! - The light is at `alpha = 135` degrees by default: `theta_i = 45` degrees on the -x side.
//! - The view is swept over `alpha` in 0..=180 degrees; its signed polar angle is
//!   `theta_o = 90 - alpha` (positive on the +x side, where the mirror direction lies: for the
//!   default light the specular peak is at `alpha = 45`, `theta_o = +45`).
//! - Values are f_r in 1/sr per channel, without the cosine factor. At `alpha = 0` and `180` the
//!   view is grazing (`wo.z = 0`) and every BRDF of this crate gives 0 there.
//!
//! Pure: no files; charts of these curves are drawn by [`super::charts`].

use super::charts::{ChartError, ChartSpec, Series, line_chart};
use crate::brdf::Brdf;
use nalgebra::Vector3;

/// The light angle from the +x axis in the paper's in-plane plots (theta_i = 45 degrees).
pub const DEFAULT_LIGHT_ALPHA_DEG: f64 = 135.0;

/// Channel names, in the order of the RGB arrays.
pub const CHANNELS: [&str; 3] = ["red", "green", "blue"];

/// Where the light is and how finely the view is swept.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InPlaneSettings {
    /// Light angle from the +x axis, degrees, in (0, 180).
    pub light_alpha_deg: f64,
    /// Number of view angles from 0 to 180 degrees inclusive (at least 2).
    pub samples: usize,
}

impl Default for InPlaneSettings {
    fn default() -> Self {
        Self {
            light_alpha_deg: DEFAULT_LIGHT_ALPHA_DEG,
            samples: 361,
        }
    }
}

/// One BRDF along the in-plane sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct InPlaneCurve {
    /// What the curve is (e.g. "reconstruction", "truth (neural fit, not measured)").
    pub label: String,
    /// View angles from the +x axis, degrees, increasing from 0 to 180.
    pub view_alpha_deg: Vec<f64>,
    /// f_r in 1/sr, RGB, at each view angle.
    pub values: Vec<[f64; 3]>,
}

impl InPlaneCurve {
    /// `(view angle in degrees, f_r)` points of one channel (0 red, 1 green, 2 blue).
    pub fn channel_points(&self, channel: usize) -> Vec<(f64, f64)> {
        let c = channel.min(2);
        self.view_alpha_deg
            .iter()
            .zip(&self.values)
            .map(|(a, v)| (*a, v[c]))
            .collect()
    }

    /// The view angle (degrees) where the channel peaks; `None` if every value is zero or not
    /// finite.
    pub fn peak_alpha_deg(&self, channel: usize) -> Option<f64> {
        self.channel_points(channel)
            .into_iter()
            .filter(|(_, v)| v.is_finite() && *v > 0.0)
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(a, _)| a)
    }
}

/// The in-plane unit direction at `alpha_deg` from the +x axis.
pub fn in_plane_direction(alpha_deg: f64) -> Vector3<f64> {
    // Evaluated on the nearer half (sin a = sin(180 - a)) so that both ends of the sweep are
    // exactly grazing: sin(pi) in floating point is 1.2e-16, not 0.
    if alpha_deg > 90.0 {
        let m = (180.0 - alpha_deg).to_radians();
        Vector3::new(-m.cos(), 0.0, m.sin())
    } else {
        let a = alpha_deg.to_radians();
        Vector3::new(a.cos(), 0.0, a.sin())
    }
}

/// Signed polar angle of the view (degrees): `90 - alpha`, positive on the mirror side.
pub fn signed_theta_o_deg(view_alpha_deg: f64) -> f64 {
    90.0 - view_alpha_deg
}

/// The swept view angles, evenly spaced from 0 to 180 degrees inclusive.
pub fn view_angles_deg(samples: usize) -> Vec<f64> {
    let n = samples.max(2);
    (0..n).map(|k| 180.0 * k as f64 / (n - 1) as f64).collect()
}

/// Evaluates one BRDF along the sweep.
pub fn in_plane_curve(label: &str, brdf: &dyn Brdf, settings: &InPlaneSettings) -> InPlaneCurve {
    let wi = in_plane_direction(settings.light_alpha_deg);
    let view_alpha_deg = view_angles_deg(settings.samples);
    let values = view_alpha_deg
        .iter()
        .map(|&a| brdf.eval_local(&wi, &in_plane_direction(a)))
        .collect();
    InPlaneCurve {
        label: label.to_string(),
        view_alpha_deg,
        values,
    }
}

/// Evaluates several BRDFs (e.g. reconstruction, truth, baselines) along the same sweep.
pub fn compare(brdfs: &[(&str, &dyn Brdf)], settings: &InPlaneSettings) -> Vec<InPlaneCurve> {
    brdfs
        .iter()
        .map(|(label, b)| in_plane_curve(label, *b, settings))
        .collect()
}

/// A short description of the geometry, for captions.
pub fn describe(settings: &InPlaneSettings) -> String {
    let theta_i = (90.0 - settings.light_alpha_deg).abs();
    format!(
        "light and view in one plane through the normal; light at {:.0} deg from the +x axis \
         (theta_i = {theta_i:.0} deg), view swept 0..180 deg (theta_o from +90 to -90 through \
         the normal); mirror direction at {:.0} deg",
        settings.light_alpha_deg,
        180.0 - settings.light_alpha_deg
    )
}

/// The in-plane chart of one channel (0 red, 1 green, 2 blue): one line per curve, x the view
/// angle from the +x axis in degrees, y f_r in 1/sr (logarithmic if `log_y`, where the grazing
/// zeros are left out).
pub fn channel_chart(
    curves: &[InPlaneCurve],
    channel: usize,
    settings: &InPlaneSettings,
    log_y: bool,
) -> Result<String, ChartError> {
    let c = channel.min(2);
    let series: Vec<Series> = curves
        .iter()
        .map(|k| Series::new(k.label.clone(), k.channel_points(c)))
        .collect();
    let spec = ChartSpec::new(
        format!(
            "In-plane BRDF, {} channel (light at {:.0} deg)",
            CHANNELS[c], settings.light_alpha_deg
        ),
        "view angle from +x axis (deg); normal at 90",
        "f_r (1/sr)",
    )
    .log_y(log_y)
    .size(520, 400);
    line_chart(&series, &spec)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use crate::brdf::coords::HalfDiff;
    use crate::brdf::merl::MerlTable;
    use std::f64::consts::PI;

    use crate::sim::imaging::Lambertian as Lambert;

    /// A narrow lobe around the half vector: peaks exactly where h = n.
    struct Lobe;
    impl Brdf for Lobe {
        fn eval_local(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
            if wi.z <= 0.0 || wo.z <= 0.0 {
                return [0.0; 3];
            }
            let hd = HalfDiff::from_directions(wi, wo);
            let s = (-hd.theta_h * hd.theta_h / 0.01).exp();
            [0.1 + s, 0.05 + 2.0 * s, 0.02 + 0.5 * s]
        }
    }

    #[test]
    fn geometry_matches_the_paper() {
        let s = InPlaneSettings::default();
        let wi = in_plane_direction(s.light_alpha_deg);
        // theta_i = 45 degrees, on the -x side.
        assert!((wi.z.acos().to_degrees() - 45.0).abs() < 1e-12);
        assert!(wi.x < 0.0 && wi.y == 0.0);
        // The normal is at 90 degrees.
        assert!((in_plane_direction(90.0) - Vector3::z()).norm() < 1e-15);
        assert_eq!(in_plane_direction(180.0).z, 0.0);
        assert_eq!(signed_theta_o_deg(45.0), 45.0);
        assert_eq!(signed_theta_o_deg(180.0), -90.0);
        let a = view_angles_deg(181);
        assert_eq!(a.len(), 181);
        assert_eq!((a[0], a[90], a[180]), (0.0, 90.0, 180.0));
    }

    #[test]
    fn lambertian_is_flat_and_zero_at_grazing() {
        let c = in_plane_curve(
            "lambert",
            &Lambert([0.5, 0.25, 0.1]),
            &InPlaneSettings::default(),
        );
        for (a, v) in c.view_alpha_deg.iter().zip(&c.values) {
            if *a == 0.0 || *a == 180.0 {
                assert_eq!(*v, [0.0; 3]);
            } else {
                assert!((v[0] - 0.5 / PI).abs() < 1e-15 && (v[2] - 0.1 / PI).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn specular_peak_is_at_the_mirror_direction() {
        let s = InPlaneSettings::default();
        let c = in_plane_curve("lobe", &Lobe, &s);
        for ch in 0..3 {
            assert_eq!(c.peak_alpha_deg(ch), Some(45.0));
        }
        // A light elsewhere moves the peak to its own mirror direction.
        let s2 = InPlaneSettings {
            light_alpha_deg: 120.0,
            samples: 181,
        };
        assert_eq!(
            in_plane_curve("lobe", &Lobe, &s2).peak_alpha_deg(1),
            Some(60.0)
        );
    }

    #[test]
    fn merl_table_along_the_sweep_is_its_source_at_bin_centres() {
        // A tabulated BRDF is looked up by nearest bin: along the sweep it must equal its
        // analytic source evaluated at the centre of the bin that holds each (wi, wo).
        let s = InPlaneSettings {
            light_alpha_deg: 135.0,
            samples: 181,
        };
        let table = MerlTable::tabulate(&Lobe);
        let curves = compare(&[("table", &table), ("analytic", &Lobe)], &s);
        assert_eq!(curves.len(), 2);
        assert_eq!(curves[0].label, "table");
        assert_eq!(curves[0].peak_alpha_deg(1), Some(45.0));
        let wi = in_plane_direction(s.light_alpha_deg);
        for (alpha, got) in curves[0].view_alpha_deg.iter().zip(&curves[0].values) {
            let wo = in_plane_direction(*alpha);
            if wo.z <= 0.0 {
                assert_eq!(*got, [0.0; 3]);
                continue;
            }
            let (ci, co) = HalfDiff::from_directions(&wi, &wo)
                .merl_bin()
                .centre()
                .to_directions();
            let want = Lobe.eval_local(&ci, &co);
            for c in 0..3 {
                assert!(
                    (got[c] - want[c]).abs() <= 1e-12 * want[c],
                    "{alpha}: {got:?} {want:?}"
                );
            }
        }
    }

    #[test]
    fn channel_chart_has_one_line_per_curve() {
        let s = InPlaneSettings::default();
        let curves = compare(&[("lobe", &Lobe), ("lambert", &Lambert([0.5; 3]))], &s);
        for log_y in [false, true] {
            let svg = channel_chart(&curves, 1, &s, log_y).unwrap();
            assert!(svg.contains("green channel"));
            // Data line + legend swatch per curve (grazing zeros at both ends are dropped on
            // the log axis without splitting the line, as they are at its ends).
            assert_eq!(svg.matches("stroke=\"#1F77B4\"").count(), 2, "log {log_y}");
            assert_eq!(svg.matches("stroke=\"#FF7F0E\"").count(), 2, "log {log_y}");
        }
    }
}
