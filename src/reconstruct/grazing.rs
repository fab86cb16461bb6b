//! The grazing peak carried along theta_d by Lambert + GGX's shape: in the cells of the
//! specular peak (theta_h below 10 degrees) at grazing theta_d (55 degrees and above), the
//! written model is averaged, geometrically, with its own value at theta_d 54 degrees carried
//! up by the ratio of the Lambert + GGX fit of the same pixels between the two cells.
//!
//! Why it was tried: a rendered sphere's rim reads the peak at grazing theta_d, where a rig
//! with lights spread around the camera has few pixels (p99 of theta_d about 63 degrees on the
//! simulated grid), seen through the normals' error; the basis fills those cells from the rows
//! below them and, on a varnished wood (fruitwood-241), rises too slowly towards grazing (the
//! two losses of issue #11's grid; docs/evaluation.md sections 1n, 1r). A Schlick Fresnel
//! times GGX's masking and `1 / (4 cos theta_i cos theta_o)` is a physical shape for that
//! rise; its height at grazing is the model's, where the data still were. The average bounds
//! the written value's distance from either guess by the square root of their ratio, as the
//! hedge does (`reconstruct::hedge`).
//!
//! A study knob (`reconstruct --grazing-transfer W`), off by default: on the simulated grid
//! it lifts both fruitwood-241 losses and leaves one other scene worse; on the independent
//! renderer's scenes, where Lambert + GGX's own render of the same wood is twice the basis's
//! error, the carried shape costs (docs/evaluation.md section 1x).
//!
//! Pure: no I/O. Must not refit anything: it wraps a model and a fitted shape.

use super::prior::Candidate;
use crate::brdf::coords::MerlBin;

/// The first theta_d bin (degrees: MERL's theta_d bins are one degree wide) whose peak cells
/// are carried; the bin below it is the reference.
pub const FIRST_THETA_D_BIN: usize = 55;

/// The peak cells: theta_h at the bin centre below this, degrees.
pub const MAX_THETA_H_DEG: f64 = 10.0;

/// Whether a bin is one of the carried peak cells.
pub fn carried(bin: &MerlBin) -> bool {
    bin.theta_d >= FIRST_THETA_D_BIN && bin.centre().theta_h.to_degrees() < MAX_THETA_H_DEG
}

/// A model whose grazing peak cells are averaged with its value at the reference theta_d
/// carried up by `shape`'s ratio (see the module header); every other bin is the model's.
pub struct GrazingTransfer<'a> {
    pub model: &'a dyn Candidate,
    /// The theta_d shape: Lambert + GGX fitted to the same pixels.
    pub shape: &'a dyn Candidate,
    /// The carried value's weight in the geometric average (0: the model alone, 1: the
    /// carried value alone).
    pub weight: f64,
}

impl Candidate for GrazingTransfer<'_> {
    fn eval_bin(&self, bin: usize) -> [f64; 3] {
        let m = self.model.eval_bin(bin);
        let w = self.weight.clamp(0.0, 1.0);
        let Some(b) = MerlBin::from_index(bin).filter(|b| w > 0.0 && carried(b)) else {
            return m;
        };
        let reference = MerlBin {
            theta_d: FIRST_THETA_D_BIN - 1,
            ..b
        }
        .index();
        let (mr, sr, sc) = (
            self.model.eval_bin(reference),
            self.shape.eval_bin(reference),
            self.shape.eval_bin(bin),
        );
        let positive = |v: &[f64; 3]| v.iter().all(|x| x.is_finite() && *x > 0.0);
        if !(positive(&m) && positive(&mr) && positive(&sr) && positive(&sc)) {
            return m;
        }
        [0, 1, 2].map(|c| m[c].powf(1.0 - w) * (mr[c] * sc[c] / sr[c]).powf(w))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::coords::{PHI_D_BINS, THETA_D_BINS};

    /// f = g(theta_h) h(theta_d) per channel: a table whose theta_d shape is `h`.
    struct Separable(fn(usize) -> f64, fn(usize) -> f64);
    impl Candidate for Separable {
        fn eval_bin(&self, bin: usize) -> [f64; 3] {
            let b = MerlBin::from_index(bin).expect("a bin of the table");
            let v = (self.0)(b.theta_h) * (self.1)(b.theta_d);
            [v, 2.0 * v, 3.0 * v]
        }
    }

    fn bin(theta_h: usize, theta_d: usize) -> usize {
        MerlBin {
            theta_h,
            theta_d,
            phi_d: PHI_D_BINS / 2,
        }
        .index()
    }

    #[test]
    fn the_peak_cells_at_grazing_take_the_shapes_rise_from_the_reference_and_others_stay() {
        // The model is flat in theta_d; the shape rises 10 % per degree.
        let model = Separable(|h| 1.0 + h as f64, |_| 1.0);
        let shape = Separable(|_| 1.0, |d| 1.1f64.powi(d as i32));
        let full = GrazingTransfer {
            model: &model,
            shape: &shape,
            weight: 1.0,
        };
        let half = GrazingTransfer {
            weight: 0.5,
            ..full
        };
        for h in [0, 10, 29] {
            // Carried: the model at theta_d 54 times the shape's rise from 54.
            for d in [55, 60, 75] {
                let want = (1.0 + h as f64) * 1.1f64.powi(d as i32 - 54);
                let got = full.eval_bin(bin(h, d));
                assert!((got[0] / want - 1.0).abs() < 1e-12, "{h} {d}: {got:?}");
                assert!(
                    (got[2] / (3.0 * want) - 1.0).abs() < 1e-12,
                    "{h} {d}: {got:?}"
                );
                // Half weight: the geometric mean of the model and the carried value.
                let m = model.eval_bin(bin(h, d))[1];
                let got = half.eval_bin(bin(h, d))[1];
                assert!((got / (m * 2.0 * want).sqrt() - 1.0).abs() < 1e-12, "{got}");
            }
            // Below the first carried theta_d: the model.
            assert_eq!(full.eval_bin(bin(h, 54)), model.eval_bin(bin(h, 54)));
        }
        // Outside the peak (theta_h 10 degrees and more: bin 30 is centred at 10.3): the model.
        assert!(!carried(&MerlBin::from_index(bin(30, 70)).expect("a bin")));
        assert_eq!(full.eval_bin(bin(30, 70)), model.eval_bin(bin(30, 70)));
        // The last theta_d bin too.
        let got = full.eval_bin(bin(5, THETA_D_BINS - 1))[0];
        assert!(
            (got / (6.0 * 1.1f64.powi(89 - 54)) - 1.0).abs() < 1e-12,
            "{got}"
        );
    }

    #[test]
    fn weight_zero_and_non_positive_values_leave_the_model() {
        let model = Separable(|_| 1.0, |d| if d == 54 { 0.0 } else { 1.0 });
        let shape = Separable(|_| 1.0, |d| d as f64);
        let off = GrazingTransfer {
            model: &model,
            shape: &shape,
            weight: 0.0,
        };
        assert_eq!(off.eval_bin(bin(3, 70)), model.eval_bin(bin(3, 70)));
        // A reference without a value (zero) carries nothing.
        let on = GrazingTransfer { weight: 1.0, ..off };
        assert_eq!(on.eval_bin(bin(3, 70)), model.eval_bin(bin(3, 70)));
    }
}
