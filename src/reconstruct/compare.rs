//! The check a user can make without ground truth: every light image beside its re-render with
//! the recovered BRDF (same camera, light and irradiance, through the same observed pixels) and
//! the signed error between them.
//!
//! A re-rendered pixel is `f(bin) E cos theta_i`, with `f` read from the written table at the
//! pixel's MERL bin: exactly what the reconstruction claims that pixel shows. Pixels the
//! reconstruction did not observe (background, shadow, grazing, clipped, masked) are left dark
//! grey in the re-render and the error map, so a user sees what was and was not used.
//!
//! The panel is three images side by side at a common exposure (the photo's 99th percentile
//! maps to 1): photo, re-render, error. The error map is the signed difference on the same
//! scale, red where the re-render is brighter than the photo, blue where it is darker. Images
//! are box-downsampled by an integer factor to at most a panel's width ([`Thumbnail`]: taken
//! while the image is read, so the full image is not held). Pure.

use super::observe::Observation;
use crate::brdf::merl::MerlTable;
use crate::render::image::LinearImage;

/// One light image's comparison.
pub struct Comparison {
    /// Index of the light image in the job.
    pub image: usize,
    /// Photo | re-render | error, side by side, display-referred linear values in [0, 1].
    pub panel: LinearImage,
    /// Relative L2 error of the re-render over the image's observed pixels (the fit's error on
    /// pixels it was fitted to; the ladder reports the held-out one).
    pub error: f64,
    pub observed: usize,
}

/// Value shown where no pixel was observed.
const UNOBSERVED: f32 = 0.08;

/// A light image box-downsampled by an integer factor for the photo panel: all a comparison
/// needs of the photo besides the observed pixels' values (which the observations carry), so
/// the full image need not be held until the BRDF is known. Non-finite values count as 0.
#[derive(Clone, Debug)]
pub struct Thumbnail {
    /// Size of the full image.
    pub width: usize,
    pub height: usize,
    /// Full-resolution pixels per thumbnail pixel, along each axis.
    pub step: usize,
    /// Block means.
    pub image: LinearImage,
}

impl Thumbnail {
    /// `photo` downsampled to at most `max_width` pixels across.
    pub fn of(photo: &LinearImage, max_width: usize) -> Self {
        let (w, h) = (photo.width(), photo.height());
        let step = w.div_ceil(max_width.max(1)).max(1);
        let (sw, sh) = (w.div_ceil(step), h.div_ceil(step));
        let mut image = LinearImage::new(sw, sh);
        for py in 0..sh {
            for px in 0..sw {
                let (mut p, mut n) = ([0.0f32; 3], 0.0f32);
                for y in py * step..((py + 1) * step).min(h) {
                    for x in px * step..((px + 1) * step).min(w) {
                        let ph = photo.get(x, y);
                        n += 1.0;
                        for c in 0..3 {
                            p[c] += if ph[c].is_finite() { ph[c] } else { 0.0 };
                        }
                    }
                }
                image.set(px, py, p.map(|v| v / n));
            }
        }
        Self {
            width: w,
            height: h,
            step,
            image,
        }
    }
}

/// The comparison of one light image (see the module header), from its thumbnail
/// ([`Thumbnail::of`] with the panel width) and its observations.
pub fn compare_image(
    image_index: usize,
    photo: &Thumbnail,
    obs: &[&Observation],
    table: &MerlTable,
) -> Comparison {
    compare_image_with(image_index, photo, obs, |o| {
        table.get(o.bin).unwrap_or([0.0; 3])
    })
}

/// As [`compare_image`], with the BRDF value of each pixel from `brdf_of` (an object of several
/// materials: each pixel's own material's table).
pub fn compare_image_with(
    image_index: usize,
    photo: &Thumbnail,
    obs: &[&Observation],
    brdf_of: impl Fn(&Observation) -> [f64; 3],
) -> Comparison {
    let (w, h, step) = (photo.width, photo.height, photo.step);
    let (sw, sh) = (photo.image.width(), photo.image.height());
    // Per thumbnail pixel: sums of the re-render and of re-render minus photo over the observed
    // pixels, and their number.
    let mut render = vec![[0.0f64; 3]; sw * sh];
    let mut diff = vec![0.0f64; sw * sh];
    let mut n_seen = vec![0usize; sw * sh];
    let (mut num, mut den) = (0.0, 0.0);
    let mut vals: Vec<f32> = Vec::with_capacity(3 * obs.len());
    for o in obs {
        let (x, y) = (o.x as usize, o.y as usize);
        if x >= w || y >= h {
            continue;
        }
        let f = brdf_of(o);
        let v = [0, 1, 2].map(|c| f[c] * o.irradiance[c] * o.cos_theta_i);
        for (vc, rc) in v.iter().zip(&o.radiance) {
            num += (vc - rc).powi(2);
            den += rc.powi(2);
        }
        let i = (y / step) * sw + x / step;
        for c in 0..3 {
            render[i][c] += v[c];
            // the photo's value as the pixel was read (f32), as the panel shows it
            let ph = o.radiance[c] as f32;
            diff[i] += v[c] - f64::from(ph);
            vals.push(ph);
        }
        n_seen[i] += 1;
    }
    // Exposure: the photo's 99th percentile channel value over the observed pixels (the
    // object, not the backdrop); the thumbnail's when none was observed.
    if vals.is_empty() {
        vals = photo.image.data().to_vec();
    }
    vals.retain(|v| v.is_finite());
    vals.sort_by(f32::total_cmp);
    let p99 = vals
        .get(((vals.len().max(1) - 1) as f64 * 0.99) as usize)
        .copied()
        .filter(|v| *v > 0.0)
        .unwrap_or(1.0);
    let mut panel = LinearImage::new(3 * sw, sh);
    for py in 0..sh {
        for px in 0..sw {
            let i = py * sw + px;
            panel.set(
                px,
                py,
                photo.image.get(px, py).map(|v| (v / p99).clamp(0.0, 1.0)),
            );
            if n_seen[i] > 0 {
                let n = n_seen[i] as f64;
                let r = render[i].map(|v| ((v / n) as f32 / p99).clamp(0.0, 1.0));
                panel.set(sw + px, py, r);
                let d = ((diff[i] / 3.0 / n) as f32 / p99).clamp(-1.0, 1.0);
                let err = if d >= 0.0 {
                    [d, 0.0, 0.0]
                } else {
                    [0.0, 0.0, -d]
                };
                panel.set(2 * sw + px, py, err);
            } else {
                panel.set(sw + px, py, [UNOBSERVED; 3]);
                panel.set(2 * sw + px, py, [UNOBSERVED; 3]);
            }
        }
    }
    Comparison {
        image: image_index,
        panel,
        error: if den > 0.0 {
            (num / den).sqrt()
        } else {
            f64::NAN
        },
        observed: obs.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::analytic::Lambert;
    use crate::reconstruct::observation::Seen;
    use nalgebra::Vector3;

    #[test]
    fn a_perfect_fit_shows_no_error_and_a_wrong_one_shows_red() {
        // A flat Lambertian patch seen head on, lit at 30 degrees.
        let albedo = 0.5;
        let table = MerlTable::tabulate(&Lambert {
            albedo: [albedo; 3],
        });
        let l = Vector3::new(0.5, 0.0, 0.866).normalize();
        let (w, h) = (20, 10);
        let mut photo = LinearImage::new(w, h);
        let mut obs = Vec::new();
        for y in 0..h {
            for x in 0..w / 2 {
                let radiance = [albedo / std::f64::consts::PI * 2.0 * l.z; 3];
                photo.set(x, y, radiance.map(|v| v as f32));
                obs.push(
                    Observation::new(
                        Seen::pixel(3, x as u32, y as u32, Vector3::z()),
                        l,
                        Vector3::z(),
                        radiance,
                        [2.0; 3],
                    )
                    .unwrap(),
                );
            }
        }
        let refs: Vec<&Observation> = obs.iter().collect();
        let c = compare_image(3, &Thumbnail::of(&photo, 10), &refs, &table);
        assert_eq!(c.image, 3);
        assert!(c.error < 1e-6, "{}", c.error);
        assert_eq!((c.panel.width(), c.panel.height()), (30, 5));
        // Observed half: photo and re-render agree; the unobserved half is grey.
        assert_eq!(c.panel.get(0, 0), c.panel.get(10, 0));
        assert_eq!(c.panel.get(19, 0), [UNOBSERVED; 3]);
        assert!(c.panel.get(20, 0).iter().all(|v| v.abs() < 1e-6));
        // A table twice too bright: 100 % error, red in the map.
        let bright = MerlTable::tabulate(&Lambert {
            albedo: [2.0 * albedo; 3],
        });
        let c = compare_image(3, &Thumbnail::of(&photo, 10), &refs, &bright);
        assert!((c.error - 1.0).abs() < 1e-3, "{}", c.error);
        let e = c.panel.get(20, 0);
        assert!(e[0] > 0.5 && e[2] == 0.0, "{e:?}");
    }
}
