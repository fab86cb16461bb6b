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
//! while the image is read, so the full image is not held).
//!
//! An object of several materials ([`compare_image_materials`]) has each pixel re-rendered with
//! its own material's table and a fourth image, the material map: each thumbnail pixel in the
//! colour of the material most of its observed pixels carry (`geometry::labels::label_colour`,
//! the colours of `material_map.ply`; a tie goes to the lower label; a box average would blend
//! two colours into what looks like a third material), times the re-render's shading there so
//! the shape reads: the mean of its three channels over the 95th percentile of that material's
//! in this image, clamped to 1, mapped to `MAP_FLOOR..1`. At full shading a pixel is the
//! palette colour exactly (8-bit sRGB, as the panel is written). Dark grey where no labelled
//! pixel was observed. The per-material errors of the image come with it ([`MaterialFit`]).
//!
//! Pure: no files; the panel is written by `output::write`.

use super::observe::Observation;
use crate::brdf::merl::MerlTable;
use crate::geometry::labels::label_colour;
use crate::imageio::srgb_decode;
use crate::render::image::LinearImage;
use serde::{Deserialize, Serialize};

/// One light image's comparison.
pub struct Comparison {
    /// Index of the light image in the job.
    pub image: usize,
    /// Photo | re-render | error (| material map, for several materials), side by side,
    /// display-referred linear values in [0, 1].
    pub panel: LinearImage,
    /// Relative L2 error of the re-render over the image's observed pixels (the fit's error on
    /// pixels it was fitted to; the ladder reports the held-out one).
    pub error: f64,
    pub observed: usize,
    /// For several materials: per material (by label), its pixels in this image and their
    /// error. Empty for one material.
    pub materials: Vec<MaterialFit>,
}

/// One material's pixels in one light image (also their entry in `report.json`'s
/// comparisons).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialFit {
    /// Observed pixels of this material in the image.
    pub observed_pixels: usize,
    /// Relative L2 error of the re-render over them; `None` when it has none (or they are
    /// all black).
    pub fit_error: Option<f64>,
}

/// Value shown where no pixel was observed.
const UNOBSERVED: f32 = 0.08;

/// The material map's brightness (a factor on the palette colour, linear) where the re-render
/// is black: low enough for the shading to read, high enough for the colour to.
const MAP_FLOOR: f32 = 0.2;

/// The material map's reference shading: this quantile of a material's shading in the image
/// maps to its full colour (not the maximum, which a highlight would set).
const MAP_SHADE_QUANTILE: f64 = 0.95;

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

/// As [`compare_image`], with the BRDF value of each pixel from `brdf_of`.
pub fn compare_image_with(
    image_index: usize,
    photo: &Thumbnail,
    obs: &[&Observation],
    brdf_of: impl Fn(&Observation) -> [f64; 3],
) -> Comparison {
    render_panel(image_index, photo, obs, |_, o| brdf_of(o), None)
}

/// The comparison of one light image of an object of several materials (see the module
/// header): each pixel re-rendered with `tables[label]`, `label_of` its material (a pixel
/// without one, or whose label has no table, is re-rendered black and left out of the map and
/// of the per-material errors), and the material map as a fourth image.
pub fn compare_image_materials(
    image_index: usize,
    photo: &Thumbnail,
    obs: &[&Observation],
    tables: &[&MerlTable],
    label_of: impl Fn(&Observation) -> Option<u32>,
) -> Comparison {
    let labels: Vec<Option<usize>> = obs
        .iter()
        .map(|o| {
            label_of(o)
                .map(|l| l as usize)
                .filter(|&l| l < tables.len())
        })
        .collect();
    render_panel(
        image_index,
        photo,
        obs,
        |i, o| {
            labels[i]
                .and_then(|l| tables[l].get(o.bin))
                .unwrap_or([0.0; 3])
        },
        Some(MapLabels {
            labels: &labels,
            count: tables.len(),
        }),
    )
}

/// The labels of a comparison's observations (in their order), each below `count`.
struct MapLabels<'a> {
    labels: &'a [Option<usize>],
    count: usize,
}

/// The panel and errors; with `map`, the fourth image and the per-material errors.
/// `brdf_of(i, o)`: the BRDF value of `obs[i]`.
fn render_panel(
    image_index: usize,
    photo: &Thumbnail,
    obs: &[&Observation],
    brdf_of: impl Fn(usize, &Observation) -> [f64; 3],
    map: Option<MapLabels>,
) -> Comparison {
    let (w, h, step) = (photo.width, photo.height, photo.step);
    let (sw, sh) = (photo.image.width(), photo.image.height());
    // Per thumbnail pixel: sums of the re-render and of re-render minus photo over the observed
    // pixels, and their number.
    let mut render = vec![[0.0f64; 3]; sw * sh];
    let mut diff = vec![0.0f64; sw * sh];
    let mut n_seen = vec![0usize; sw * sh];
    let (mut num, mut den) = (0.0, 0.0);
    // With a map: per material, the error sums and pixel count; per thumbnail pixel and
    // material, the pixels seen.
    let count = map.as_ref().map_or(0, |m| m.count);
    let mut per_material = vec![(0.0f64, 0.0f64, 0usize); count];
    let mut votes = vec![0u32; if map.is_some() { sw * sh * count } else { 0 }];
    let mut vals: Vec<f32> = Vec::with_capacity(3 * obs.len());
    for (k, o) in obs.iter().enumerate() {
        let (x, y) = (o.x as usize, o.y as usize);
        if x >= w || y >= h {
            continue;
        }
        let f = brdf_of(k, o);
        let v = [0, 1, 2].map(|c| f[c] * o.irradiance[c] * o.cos_theta_i);
        let i = (y / step) * sw + x / step;
        let label = map
            .as_ref()
            .and_then(|m| m.labels.get(k).copied().flatten());
        for (vc, rc) in v.iter().zip(&o.radiance) {
            let (e2, r2) = ((vc - rc).powi(2), rc.powi(2));
            num += e2;
            den += r2;
            if let Some(l) = label {
                per_material[l].0 += e2;
                per_material[l].1 += r2;
            }
        }
        if let Some(l) = label {
            per_material[l].2 += 1;
            votes[i * count + l] += 1;
        }
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
    let mut panel = LinearImage::new(if map.is_some() { 4 * sw } else { 3 * sw }, sh);
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
    if map.is_some() {
        // the re-render's shading per thumbnail pixel (mean of the channels, on the panel's
        // scale) and the material most of its pixels carry
        let shading: Vec<f32> = (0..sw * sh)
            .map(|i| {
                let n = n_seen[i].max(1) as f64;
                let mean = render[i].iter().sum::<f64>() / 3.0 / n;
                ((mean as f32) / p99).clamp(0.0, 1.0)
            })
            .collect();
        let majority: Vec<Option<usize>> = (0..sw * sh)
            .map(|i| {
                let v = &votes[i * count..(i + 1) * count];
                // the first of the largest: a tie goes to the lower label
                let (l, &n) = v.iter().enumerate().rev().max_by_key(|&(_, n)| *n)?;
                (n > 0).then_some(l)
            })
            .collect();
        let reference: Vec<f32> = (0..count)
            .map(|l| {
                let mut s: Vec<f32> = (0..sw * sh)
                    .filter(|&i| majority[i] == Some(l))
                    .map(|i| shading[i])
                    .collect();
                s.sort_by(f32::total_cmp);
                s.get(((s.len().max(1) - 1) as f64 * MAP_SHADE_QUANTILE) as usize)
                    .copied()
                    .filter(|v| *v > 0.0)
                    .unwrap_or(1.0)
            })
            .collect();
        for py in 0..sh {
            for px in 0..sw {
                let i = py * sw + px;
                let value = match majority[i] {
                    Some(l) => {
                        let s = (shading[i] / reference[l]).min(1.0);
                        let k = MAP_FLOOR + (1.0 - MAP_FLOOR) * s;
                        palette_linear(l).map(|c| c * k)
                    }
                    None => [UNOBSERVED; 3],
                };
                panel.set(3 * sw + px, py, value);
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
        materials: per_material
            .into_iter()
            .map(|(num, den, observed_pixels)| MaterialFit {
                observed_pixels,
                fit_error: (den > 0.0).then(|| (num / den).sqrt()),
            })
            .collect(),
    }
}

/// The colour of `label` as a linear display value (the inverse of the sRGB encoding the
/// panel is written with, so full shading writes the palette's bytes).
fn palette_linear(label: usize) -> [f32; 3] {
    let label = u32::try_from(label).unwrap_or(u32::MAX);
    label_colour(label).map(|c| srgb_decode(f32::from(c) / 255.0))
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
        assert!(
            c.materials.is_empty(),
            "one material: no per-material errors"
        );
    }

    /// The panel as the PNG holds it: 8-bit sRGB.
    fn srgb8(p: [f32; 3]) -> [u8; 3] {
        p.map(|v| (crate::imageio::srgb_encode(v) * 255.0).round() as u8)
    }

    /// A 20 x 10 image: the left half a flat Lambertian patch seen head on, lit at 30 degrees,
    /// columns 0..4 of albedo 0.5 (label 0) and 4..10 of albedo 0.2 (label 1); the normals
    /// of rows 6..10 tilted 40 degrees about x (so those rows are darker: shading). Column 9
    /// is observed but has no label.
    fn two_material_scene() -> (LinearImage, Vec<Observation>, Vec<Option<u32>>) {
        let l = Vector3::new(0.5, 0.0, 0.866).normalize();
        let (w, h) = (20, 10);
        let mut photo = LinearImage::new(w, h);
        let (mut obs, mut labels) = (Vec::new(), Vec::new());
        for y in 0..h {
            let tilt = if y >= 6 { 40f64.to_radians() } else { 0.0 };
            let n = Vector3::new(0.0, -tilt.sin(), tilt.cos());
            for x in 0..w / 2 {
                let (label, albedo) = if x < 4 { (0, 0.5) } else { (1, 0.2) };
                let radiance = [albedo / std::f64::consts::PI * 2.0 * n.dot(&l); 3];
                photo.set(x, y, radiance.map(|v| v as f32));
                let seen = Seen::pixel(1, x as u32, y as u32, n);
                obs.push(Observation::new(seen, l, n, radiance, [2.0; 3]).unwrap());
                labels.push((x != 9).then_some(label));
            }
        }
        (photo, obs, labels)
    }

    #[test]
    fn several_materials_add_a_material_map_in_the_palette_and_their_own_errors() {
        let (photo, obs, labels) = two_material_scene();
        let tables = [0.5, 0.2].map(|a| MerlTable::tabulate(&Lambert { albedo: [a; 3] }));
        let refs: Vec<&Observation> = obs.iter().collect();
        let label_of = |o: &Observation| labels[obs.iter().position(|p| p == o).unwrap()];
        let thumb = Thumbnail::of(&photo, 10); // 2 x 2 pixels per thumbnail pixel: 10 x 5
        let c = compare_image_materials(1, &thumb, &refs, &[&tables[0], &tables[1]], label_of);
        assert_eq!((c.panel.width(), c.panel.height()), (40, 5), "four images");
        // the unlabelled column is re-rendered black: the whole image's error is its share
        let energy = |keep: &dyn Fn(&Observation) -> bool| -> f64 {
            let sq = |o: &&Observation| o.radiance.iter().map(|r| r * r).sum::<f64>();
            obs.iter().filter(|o| keep(o)).map(|o| sq(&o)).sum()
        };
        let expected = (energy(&|o| o.x == 9) / energy(&|_| true)).sqrt();
        assert!(
            (c.error - expected).abs() < 1e-6,
            "{} vs {expected}",
            c.error
        );

        // The first three images are the three-image panel of the same per-pixel BRDFs.
        let brdf_of = |o: &Observation| {
            label_of(o).map_or([0.0; 3], |l| tables[l as usize].get(o.bin).unwrap())
        };
        let three = compare_image_with(1, &thumb, &refs, brdf_of);
        assert_eq!((three.panel.width(), three.panel.height()), (30, 5));
        for y in 0..5 {
            for x in 0..30 {
                assert_eq!(c.panel.get(x, y), three.panel.get(x, y), "({x}, {y})");
            }
        }

        // The map: thumbnail columns 0-1 are material 0, 2-3 material 1, column 4 material 1
        // (its other half unlabelled, re-rendered black), 5-9 never observed.
        let colour = |l| crate::geometry::labels::label_colour(l);
        let map = |x: usize, y: usize| c.panel.get(30 + x, y);
        // Darker than `bright` by a factor above the floor, in the same colour.
        let darker = |dark: [f32; 3], bright: [f32; 3]| {
            let k = dark[0] / bright[0];
            assert!(k < 0.95 && k > MAP_FLOOR, "{dark:?} vs {bright:?}");
            for ch in 0..3 {
                assert!((dark[ch] - k * bright[ch]).abs() < 1e-5, "hue: {dark:?}");
            }
        };
        for y in 0..3 {
            // rows 0..6 are the brightest: full shading, the palette's own bytes
            assert_eq!(srgb8(map(0, y)), colour(0), "row {y}");
            assert_eq!(srgb8(map(1, y)), colour(0), "row {y}");
            assert_eq!(srgb8(map(2, y)), colour(1), "row {y}");
            assert_eq!(srgb8(map(3, y)), colour(1), "row {y}");
            darker(map(4, y), map(3, y));
            for x in 5..10 {
                assert_eq!(map(x, y), [UNOBSERVED; 3], "({x}, {y})");
            }
        }
        // the tilted rows (thumbnail rows 3-4) are darker, in the same colour
        darker(map(0, 4), map(0, 0));
        darker(map(3, 4), map(3, 0));

        // Per material: its pixels and its error; a wrong table shows in its material only.
        assert_eq!(c.materials.len(), 2);
        assert_eq!(c.materials[0].observed_pixels, 40);
        assert_eq!(c.materials[1].observed_pixels, 50);
        assert!(c.materials.iter().all(|m| m.fit_error.unwrap() < 1e-6));
        let bright = MerlTable::tabulate(&Lambert { albedo: [0.4; 3] });
        let c = compare_image_materials(1, &thumb, &refs, &[&tables[0], &bright], label_of);
        assert!(c.materials[0].fit_error.unwrap() < 1e-6);
        assert!((c.materials[1].fit_error.unwrap() - 1.0).abs() < 1e-3);
    }
}
