//! The written basis fit corrected for the blur a wrong normal puts on the pixels' values (a
//! study knob, off by default: `reconstruct --deblur DEG`).
//!
//! A pixel whose normal is off by a small tilt lends its row the value of another half vector:
//! over the surface, the table the pixels give is the true one averaged over the normals'
//! error, its peak lower and wider. With the error taken as an isotropic Gaussian tilt of RMS
//! `sigma`, the blurred value at a bin is the average of `f(R wi, R wo) cos(R wi) / cos wi`
//! over the tilts `R` (a 5 x 5 Gauss-Hermite rule). One step of Van Cittert's deconvolution:
//! fit, multiply every sample by the fit's `f / blur(f)` at its bin (bounded by
//! [`MAX_RATIO`] either way), fit again. More steps amplify what the rows do not pin.
//!
//! Held-out images cannot choose `sigma`: they are blurred by the same normals, so a sharper
//! table predicts them no better (docs/evaluation.md section 1v). Study only.
//!
//! Pure: wraps a prior; no I/O. Must not change anything but the samples of the prior's fits.

use super::observe::to_local;
use super::prior::{Candidate, Prior, Sample, delegate_prior};
use crate::brdf::coords::{MerlBin, merl_index};
use crate::brdf::ridge::RidgeError;
use nalgebra::Vector3;

/// The largest factor a sample is corrected by (either way).
pub const MAX_RATIO: f64 = 10.0;

/// Nodes and weights of the 5-point Gauss-Hermite rule for a standard normal variable.
const NODES: [(f64, f64); 5] = [
    (-2.856_970_013_872_806, 0.011_257_411_327_720_69),
    (-1.355_626_179_974_266, 0.222_075_922_005_612_6),
    (0.0, 0.533_333_333_333_333_3),
    (1.355_626_179_974_266, 0.222_075_922_005_612_6),
    (2.856_970_013_872_806, 0.011_257_411_327_720_69),
];

/// `c`'s value at `bin` averaged over normal tilts of RMS `sigma` (radians), times the ratio
/// of the cosines of incidence; `None` below the horizon or when no tilt leaves both
/// directions above it.
pub fn blurred(c: &dyn Candidate, bin: usize, sigma: f64) -> Option<[f64; 3]> {
    let (wi, wo) = MerlBin::from_index(bin)?.centre_directions();
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return None;
    }
    let s = sigma / std::f64::consts::SQRT_2;
    let (mut acc, mut total) = ([0.0; 3], 0.0);
    for (x, wx) in NODES {
        for (y, wy) in NODES {
            let n = Vector3::new((x * s).tan(), (y * s).tan(), 1.0).normalize();
            let (ti, to) = to_local(&n, &wi, &wo);
            if ti.z <= 1e-3 || to.z <= 1e-3 {
                continue;
            }
            let v = c.eval_bin(merl_index(&ti, &to));
            let w = wx * wy;
            for k in 0..3 {
                acc[k] += w * v[k] * ti.z / wi.z;
            }
            total += w;
        }
    }
    (total > 0.0).then(|| acc.map(|a| a / total))
}

/// The samples multiplied by `fit`'s `f / blur(f)` at their bins, channel by channel (a sample
/// is kept as it is where either value is not positive and finite).
pub fn corrected(fit: &dyn Candidate, samples: &[Sample], sigma: f64) -> Vec<Sample> {
    samples
        .iter()
        .map(|s| {
            let Some(b) = blurred(fit, s.bin, sigma) else {
                return *s;
            };
            let v = fit.eval_bin(s.bin);
            Sample {
                bin: s.bin,
                reflectance: std::array::from_fn(|k| {
                    let r = v[k] / b[k];
                    if v[k] > 0.0 && b[k] > 0.0 && r.is_finite() {
                        s.reflectance[k] * r.clamp(1.0 / MAX_RATIO, MAX_RATIO)
                    } else {
                        s.reflectance[k]
                    }
                }),
            }
        })
        .collect()
}

/// A prior whose fits are deblurred by one Van Cittert step at tilt `sigma` (radians).
pub struct DeblurredPrior<'a> {
    pub inner: &'a dyn Prior,
    pub sigma: f64,
}

impl Prior for DeblurredPrior<'_> {
    delegate_prior!();

    fn fit(
        &self,
        samples: &[Sample],
        k: usize,
        eta: f64,
    ) -> Result<Box<dyn Candidate>, RidgeError> {
        let first = self.inner.fit_lazy(samples, k, eta)?;
        self.inner
            .fit(&corrected(first.as_ref(), samples, self.sigma), k, eta)
    }

    fn fit_lazy<'b>(
        &'b self,
        samples: &[Sample],
        k: usize,
        eta: f64,
    ) -> Result<Box<dyn Candidate + 'b>, RidgeError> {
        let first = self.inner.fit_lazy(samples, k, eta)?;
        let again = corrected(first.as_ref(), samples, self.sigma);
        drop(first);
        self.inner.fit_lazy(&again, k, eta)
    }

    fn row_value(&self, o: &super::observe::Observation) -> [f64; 3] {
        self.inner.row_value(o)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::coords::HalfDiff;

    /// A narrow Gaussian lobe in theta_h on a floor, or a constant (`width_deg` 0).
    struct Lobe(f64);

    impl Candidate for Lobe {
        fn eval_bin(&self, bin: usize) -> [f64; 3] {
            if self.0 == 0.0 {
                return [0.2; 3];
            }
            let h = MerlBin::from_index(bin).map_or(0.0, |m| m.centre().theta_h);
            [0.05 + 5.0 * (-(h.to_degrees() / self.0).powi(2)).exp(); 3]
        }
    }

    fn bin(th: f64, td: f64) -> usize {
        let (wi, wo) = HalfDiff {
            theta_h: th.to_radians(),
            phi_h: 0.0,
            theta_d: td.to_radians(),
            phi_d: 1.0,
        }
        .to_directions();
        merl_index(&wi, &wo)
    }

    #[test]
    fn a_tilt_lowers_a_narrow_peak_and_raises_its_flank() {
        let t = Lobe(4.0);
        let (peak, flank) = (bin(0.5, 20.0), bin(7.0, 20.0));
        let sigma = 3f64.to_radians();
        let (bp, bf) = (
            blurred(&t, peak, sigma).unwrap()[0],
            blurred(&t, flank, sigma).unwrap()[0],
        );
        let (vp, vf) = (t.eval_bin(peak)[0], t.eval_bin(flank)[0]);
        assert!(bp < 0.9 * vp, "peak {vp} blurred to {bp}");
        assert!(bf > 1.1 * vf, "flank {vf} blurred to {bf}");
    }

    #[test]
    fn no_tilt_and_a_flat_table_leave_the_samples_as_they_are() {
        let t = Lobe(4.0);
        let samples = vec![
            Sample {
                bin: bin(0.5, 20.0),
                reflectance: [1.0, 2.0, 3.0],
            },
            Sample {
                bin: bin(10.0, 40.0),
                reflectance: [0.5, 0.5, 0.5],
            },
        ];
        for (s, c) in corrected(&t, &samples, 0.0).iter().zip(&samples) {
            for k in 0..3 {
                assert!((s.reflectance[k] - c.reflectance[k]).abs() < 1e-9);
            }
        }
        let flat = Lobe(0.0);
        let moved = corrected(&flat, &samples, 5f64.to_radians());
        // A Lambertian table blurs to itself up to the cosine ratio, whose mean over a
        // symmetric tilt is within a few per mille of 1 at moderate angles.
        for (s, c) in moved.iter().zip(&samples) {
            let r = s.reflectance[0] / c.reflectance[0];
            assert!((r - 1.0).abs() < 0.01, "flat table moved a sample by {r}");
        }
    }

    #[test]
    fn a_peak_sample_is_raised_within_the_bound() {
        let t = Lobe(2.0);
        let s = [Sample {
            bin: bin(0.3, 20.0),
            reflectance: [1.0; 3],
        }];
        let out = corrected(&t, &s, 6f64.to_radians());
        assert!(out[0].reflectance[0] > 1.5, "{:?}", out[0].reflectance);
        assert!(out[0].reflectance[0] <= MAX_RATIO);
    }
}
