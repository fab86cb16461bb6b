//! The model that scores a count of materials (issue #17): one reflectance *shape* shared by
//! the whole object, a coarse non-parametric table over (theta_h, theta_d, phi_d), times an
//! RGB scale per material. Two regions are then two materials only when they differ by more
//! than how the same reflectance looks from other angles: a glossy paint whose regions face the
//! lights differently (each region's pixels at other (theta_h, theta_d)) is one material,
//! however different the regions' levels, while a second colour, or a second level of the same
//! colour, lowers the held-out error as it should. Pure: observations in, a candidate per
//! material out; no I/O, no basis.
//!
//! Fitted by alternating least squares in image space (each pixel's squared residual in `f`
//! weighted by `(E cos theta_i)^2`: the analytic baselines' `pixel_weight`, with each pixel's
//! own irradiance since the lights differ): per-material scales with the shape held,
//! then the shape cell by cell with the scales held. A cell no training pixel saw takes the
//! mean of the seen cells of its `theta_h` row, else of every seen cell.

use super::observation::Observation;
use super::prior::Candidate;
use crate::brdf::coords::MerlBin;
use std::sync::Arc;

/// `theta_h` bins (90, square-root spaced) per cell.
const TH_STEP: usize = 10;
/// `theta_d` bins (90) per cell.
const TD_STEP: usize = 10;
/// `phi_d` bins (180) per cell.
const PD_STEP: usize = 45;
const TH_CELLS: usize = 90 / TH_STEP;
const TD_CELLS: usize = 90 / TD_STEP;
const PD_CELLS: usize = 180 / PD_STEP;
const CELLS: usize = TH_CELLS * TD_CELLS * PD_CELLS;
/// Alternations of the least squares.
const ROUNDS: usize = 6;

fn cell(bin: usize) -> Option<usize> {
    let b = MerlBin::from_index(bin)?;
    let (h, d, p) = (
        (b.theta_h / TH_STEP).min(TH_CELLS - 1),
        (b.theta_d / TD_STEP).min(TD_CELLS - 1),
        (b.phi_d / PD_STEP).min(PD_CELLS - 1),
    );
    Some(p + PD_CELLS * (d + TD_CELLS * h))
}

/// A material of the shared-shape model: its scale times the shared table.
struct Scaled {
    scale: [f64; 3],
    shape: Arc<Vec<f64>>,
}

impl Candidate for Scaled {
    fn eval_bin(&self, bin: usize) -> [f64; 3] {
        let g = cell(bin).map_or(0.0, |c| self.shape[c]);
        self.scale.map(|s| s * g)
    }
}

/// A usable pixel as the fit reads it.
#[derive(Clone, Copy)]
struct Px {
    /// Material.
    m: usize,
    /// Cell of the shape.
    c: usize,
    /// [`weight`].
    w: f64,
    /// Reflectance.
    r: [f64; 3],
}

fn weight(o: &Observation) -> f64 {
    let e = (o.irradiance[0] + o.irradiance[1] + o.irradiance[2]) / 3.0;
    (e * o.cos_theta_i).powi(2)
}

fn usable(o: &Observation) -> bool {
    o.reflectance.iter().all(|r| r.is_finite()) && weight(o).is_finite() && weight(o) > 0.0
}

/// Fits the shared shape and one scale per material to `labelled` (material, pixel) pairs,
/// materials `0..count`; one candidate per material (`None` for a material without pixels).
/// `None` when no pixel is usable.
pub fn fit_shared_shape(
    labelled: &[(u32, &Observation)],
    count: usize,
) -> Option<Vec<Option<Box<dyn Candidate>>>> {
    // Each usable pixel once, compactly: its material, cell, weight and reflectance (the
    // alternation reads them thirteen times; a whole observation is some 280 bytes).
    let px: Vec<Px> = labelled
        .iter()
        .filter(|(m, o)| (*m as usize) < count && usable(o))
        .filter_map(|(m, o)| {
            Some(Px {
                m: *m as usize,
                c: cell(o.bin)?,
                w: weight(o),
                r: o.reflectance,
            })
        })
        .collect();
    if px.is_empty() {
        return None;
    }
    // start: the shape is the cells' mean level, every scale 1
    let mut shape = vec![0.0f64; CELLS];
    let mut scale = vec![[1.0f64; 3]; count];
    {
        let (mut num, mut den) = (vec![0.0f64; CELLS], vec![0.0f64; CELLS]);
        for &Px { c, w, r, .. } in &px {
            num[c] += w * r.iter().sum::<f64>() / 3.0;
            den[c] += w;
        }
        for c in 0..CELLS {
            shape[c] = if den[c] > 0.0 { num[c] / den[c] } else { 0.0 };
        }
    }
    let mut seen = vec![false; CELLS];
    for p in &px {
        seen[p.c] = true;
    }
    for _ in 0..ROUNDS {
        // scales, shape held
        let mut num = vec![[0.0f64; 3]; count];
        let mut den = vec![0.0f64; count];
        for &Px { m, c, w, r } in &px {
            let g = shape[c];
            for (n, r) in num[m].iter_mut().zip(r) {
                *n += w * g * r;
            }
            den[m] += w * g * g;
        }
        for m in 0..count {
            if den[m] > 0.0 {
                scale[m] = num[m].map(|x| (x / den[m]).max(0.0));
            }
        }
        // shape, scales held
        let (mut num, mut den) = (vec![0.0f64; CELLS], vec![0.0f64; CELLS]);
        for &Px { m, c, w, r } in &px {
            for (s, r) in scale[m].iter().zip(r) {
                num[c] += w * s * r;
                den[c] += w * s * s;
            }
        }
        for c in 0..CELLS {
            if den[c] > 0.0 {
                shape[c] = (num[c] / den[c]).max(0.0);
            }
        }
    }
    fill_unseen(&mut shape, &seen);
    let shape = Arc::new(shape);
    let mut has = vec![false; count];
    for p in &px {
        has[p.m] = true;
    }
    Some(
        (0..count)
            .map(|m| {
                has[m].then(|| {
                    Box::new(Scaled {
                        scale: scale[m],
                        shape: Arc::clone(&shape),
                    }) as Box<dyn Candidate>
                })
            })
            .collect(),
    )
}

/// Unseen cells: the mean of the seen cells of their `theta_h` row, else of all seen cells.
fn fill_unseen(shape: &mut [f64], seen: &[bool]) {
    let row = TD_CELLS * PD_CELLS;
    let (mut all, mut n_all) = (0.0, 0usize);
    for c in 0..CELLS {
        if seen[c] {
            all += shape[c];
            n_all += 1;
        }
    }
    let global = if n_all > 0 { all / n_all as f64 } else { 0.0 };
    for h in 0..TH_CELLS {
        let cells = h * row..(h + 1) * row;
        let (mut s, mut n) = (0.0, 0usize);
        for c in cells.clone() {
            if seen[c] {
                s += shape[c];
                n += 1;
            }
        }
        let fill = if n > 0 { s / n as f64 } else { global };
        for c in cells {
            if !seen[c] {
                shape[c] = fill;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::Brdf;
    use crate::brdf::analytic::LambertGgx;
    use crate::reconstruct::baselines::fit_lambert;
    use crate::reconstruct::observation::Seen;
    use nalgebra::{Point3, Vector3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn glossy(kd: [f64; 3]) -> LambertGgx {
        LambertGgx {
            kd,
            ks: [1.0; 3],
            alpha: 0.15,
            f0: 0.04,
        }
    }

    fn unit(rng: &mut ChaCha8Rng, max_deg: f64) -> Vector3<f64> {
        let t = rng.gen_range(0.0..max_deg).to_radians();
        let p = rng.gen_range(0.0..std::f64::consts::TAU);
        Vector3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    }

    /// Pixels of a flat patch (normal +z) under random lights and views, the BRDF of each
    /// pixel from `brdf_of(i)`.
    fn pixels(n: usize, brdf_of: impl Fn(usize) -> LambertGgx) -> Vec<Observation> {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        (0..n)
            .filter_map(|i| {
                let (light, view) = (unit(&mut rng, 70.0), unit(&mut rng, 70.0));
                let (wi, wo) =
                    crate::reconstruct::observation::to_local(&Vector3::z(), &light, &view);
                let b = brdf_of(i);
                let fr = b.eval_local(&wi, &wo);
                let rad = fr.map(|f| f * light.z);
                let seen = Seen {
                    position: Point3::origin(),
                    ..Seen::pixel(i % 8, 0, 0, Vector3::z())
                };
                Observation::new(seen, light, view, rad, [1.0; 3])
            })
            .collect()
    }

    fn theta_h_deg(o: &Observation) -> f64 {
        crate::brdf::coords::MerlBin::from_index(o.bin).map_or(90.0, |b| {
            let u = (b.theta_h as f64 + 0.5) / 90.0;
            (u * u * 90.0).min(90.0)
        })
    }

    /// One glossy material whose pixels are split by angle (mostly near the highlight or
    /// mostly not), as a region that faces the lights differently is: the per-region Lambert
    /// fits differ by a fifth, the shared shape's scales by a few per cent (what varies inside
    /// one of its coarse cells).
    #[test]
    fn a_split_by_angle_of_one_material_gets_equal_scales() {
        let obs = pixels(4000, |_| glossy([0.5, 0.3, 0.2]));
        // a region that faces the lights shows more of the highlight: most pixels near it
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let labelled: Vec<(u32, &Observation)> = obs
            .iter()
            .map(|o| {
                let p = if theta_h_deg(o) < 15.0 { 0.9 } else { 0.1 };
                (u32::from(rng.r#gen::<f64>() < p), o)
            })
            .collect();
        let fits = fit_shared_shape(&labelled, 2).expect("pixels to fit");
        // the two materials at the same bin: the ratio of their scales
        let at = |m: usize, bin: usize| fits[m].as_ref().expect("fit").eval_bin(bin);
        let bin = labelled
            .iter()
            .find(|(l, _)| *l == 0)
            .expect("a pixel")
            .1
            .bin;
        let (a, b) = (at(0, bin), at(1, bin));
        let ratio = a[0] / b[0];
        assert!(
            (0.9..1.1).contains(&ratio),
            "shared-shape scale ratio {ratio}"
        );
        // the Lambert fit per region, for contrast
        let own = |m: u32| -> Vec<Observation> {
            labelled
                .iter()
                .filter(|(l, _)| *l == m)
                .map(|(_, o)| **o)
                .collect()
        };
        let (l0, l1) = (
            fit_lambert(&own(0)).expect("fit"),
            fit_lambert(&own(1)).expect("fit"),
        );
        let lambert_ratio = l1.albedo[0] / l0.albedo[0];
        // measured: 1.23 against the shared shape's 1.06
        assert!(
            lambert_ratio > 1.15 && (ratio - 1.0).abs() < (lambert_ratio - 1.0) / 3.0,
            "Lambert per region: ratio {lambert_ratio}, shared shape {ratio}"
        );
    }

    /// Two colours with the same gloss: the scales carry the colour ratio.
    #[test]
    fn two_colours_get_their_colour_ratio() {
        let (a, b) = ([0.5, 0.3, 0.2], [0.1, 0.2, 0.6]);
        let obs = pixels(4000, |i| glossy(if i % 2 == 0 { a } else { b }));
        let labelled: Vec<(u32, &Observation)> = obs
            .iter()
            .enumerate()
            .map(|(i, o)| ((i % 2) as u32, o))
            .collect();
        let fits = fit_shared_shape(&labelled, 2).expect("pixels to fit");
        // away from the highlight, the diffuse part dominates: compare the blue/red shares
        let bin = obs
            .iter()
            .find(|o| theta_h_deg(o) > 40.0)
            .expect("a pixel away from the highlight")
            .bin;
        let (fa, fb) = (
            fits[0].as_ref().expect("fit").eval_bin(bin),
            fits[1].as_ref().expect("fit").eval_bin(bin),
        );
        assert!(fa[0] > 2.0 * fa[2], "first material red: {fa:?}");
        assert!(fb[2] > 2.0 * fb[0], "second material blue: {fb:?}");
        // a material with no pixels gets no fit, and no pixels at all no model
        let one: Vec<(u32, &Observation)> =
            labelled.iter().filter(|(l, _)| *l == 0).copied().collect();
        let fits = fit_shared_shape(&one, 2).expect("pixels to fit");
        assert!(fits[0].is_some() && fits[1].is_none());
        assert!(fit_shared_shape(&[], 2).is_none());
    }
}
