//! Shading of a rasterised mesh with a BRDF: the image the simulated camera sees, and the
//! renders reconstruction compares against the captured images.
//!
//! Per covered pixel, with `n` the interpolated vertex normal, `v` the unit direction to the
//! camera centre and `l` the light's `to_light`:
//! `L = f_r(l, v) * E * max(0, n . l)`, zero when the light is shadowed (BVH shadow ray, see
//! `geometry::shadow`) or `n . v <= 0`; plus, optionally, a uniform environment (see
//! [`UniformEnvironment`]): `L_env = (pi / N) * sum_k f_r(w_k, v) * L_uniform * V(w_k)` over
//! cosine-distributed `w_k` about `n`. Uncovered pixels get the background value.
//! An object of several materials ([`render_mesh_materials`]) takes the BRDF of the fragment's
//! face from its `geometry::labels::FaceLabels`; everything else is the same.
//! Conventions: radiance in the irradiance's unit per steradian; the BRDF is evaluated in the
//! frame of [`ShadingFrame`]. Pure: no file I/O (see `crate::imageio`).

use super::frame::ShadingFrame;
use super::image::LinearImage;
use super::light::{DirectionalLight, UniformEnvironment};
use crate::brdf::Brdf;
use crate::geometry::bvh::{Bvh, Ray};
use crate::geometry::camera::{Intrinsics, Pose};
use crate::geometry::labels::FaceLabels;
use crate::geometry::mesh::Mesh;
use crate::geometry::raster::{Fragment, GBuffer, Rasteriser};
use crate::geometry::shadow::{default_offset, light_visible};
use nalgebra::{Point3, Vector3};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// What lights a render and what fills the background.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadeOptions {
    pub light: Option<DirectionalLight>,
    pub environment: Option<UniformEnvironment>,
    /// Cast shadows from the directional light (self-shadowing by `n . l` always applies).
    pub shadows: bool,
    /// Radiance of pixels the mesh does not cover.
    pub background: [f32; 3],
}

impl ShadeOptions {
    /// One directional light with shadows, black background.
    pub fn single_light(light: DirectionalLight) -> Self {
        Self {
            light: Some(light),
            environment: None,
            shadows: true,
            background: [0.0; 3],
        }
    }
}

/// Rasterises and shades in one call (see [`shade`] to reuse a G-buffer); row by row, so no
/// G-buffer is held (a 24-megapixel one would take ~3 GB).
pub fn render_mesh(
    mesh: &Mesh,
    bvh: &Bvh,
    k: &Intrinsics,
    pose: &Pose,
    brdf: &dyn Brdf,
    opts: &ShadeOptions,
) -> LinearImage {
    render_mesh_with(mesh, bvh, k, pose, |_| Some(brdf), opts)
}

/// Why a mesh cannot be rendered with a material per face.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MaterialsError {
    #[error("{labels} face labels for a mesh of {faces} faces: there must be one label per face")]
    Labels { labels: usize, faces: usize },
    #[error("face {face} is material {label}, but only {brdfs} BRDFs were given")]
    NoBrdf {
        face: usize,
        label: u32,
        brdfs: usize,
    },
}

/// [`render_mesh`] for an object of several materials: face `f` is shaded with
/// `brdfs[labels.labels[f]]` (the same per-pixel kernel, [`shade_fragment`], so one material
/// gives exactly [`render_mesh`]'s image). The labels must fit (see [`check_materials`]): a face
/// without a label, or whose label has no BRDF, is left as background rather than panicking.
pub fn render_mesh_materials(
    mesh: &Mesh,
    bvh: &Bvh,
    k: &Intrinsics,
    pose: &Pose,
    brdfs: &[&dyn Brdf],
    labels: &FaceLabels,
    opts: &ShadeOptions,
) -> LinearImage {
    render_mesh_with(
        mesh,
        bvh,
        k,
        pose,
        |face| {
            let label = *labels.labels.get(face as usize)?;
            brdfs.get(label as usize).copied()
        },
        opts,
    )
}

/// Checks that `labels` has one label per face of `mesh` and that `brdfs` has a BRDF for each
/// (before [`render_mesh_materials`], which would leave such faces as background).
pub fn check_materials(
    mesh: &Mesh,
    brdfs: &[&dyn Brdf],
    labels: &FaceLabels,
) -> Result<(), MaterialsError> {
    if labels.labels.len() != mesh.faces().len() {
        return Err(MaterialsError::Labels {
            labels: labels.labels.len(),
            faces: mesh.faces().len(),
        });
    }
    match labels
        .labels
        .iter()
        .enumerate()
        .find(|(_, l)| **l as usize >= brdfs.len())
    {
        Some((face, &label)) => Err(MaterialsError::NoBrdf {
            face,
            label,
            brdfs: brdfs.len(),
        }),
        None => Ok(()),
    }
}

/// [`render_mesh`] with the BRDF of each fragment chosen by its face (`None`: background).
fn render_mesh_with<'b>(
    mesh: &Mesh,
    bvh: &Bvh,
    k: &Intrinsics,
    pose: &Pose,
    brdf_of: impl Fn(u32) -> Option<&'b dyn Brdf> + Sync,
    opts: &ShadeOptions,
) -> LinearImage {
    let r = Rasteriser::new(mesh, bvh, k, pose, None);
    let centre = pose.centre();
    let faces = r.faces();
    shade_with(k.width, k.height, opts, |x, y| {
        let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
        let f = match &faces {
            Some(fb) => r.fragment_on(fb.face(x, y)?, px, py)?,
            None => r.fragment(px, py)?,
        };
        Some(shade_fragment(
            mesh,
            bvh,
            &f,
            &centre,
            brdf_of(f.face)?,
            opts,
            (y * k.width + x) as u64,
        ))
    })
}

/// Shades a G-buffer seen from `camera_centre` (world). Cheap to call repeatedly with
/// different BRDFs on the same G-buffer (trial selection).
pub fn shade(
    mesh: &Mesh,
    bvh: &Bvh,
    gbuf: &GBuffer,
    camera_centre: &Point3<f64>,
    brdf: &dyn Brdf,
    opts: &ShadeOptions,
) -> LinearImage {
    let w = gbuf.width();
    shade_with(w, gbuf.height(), opts, |x, y| {
        let f = gbuf.get(x, y)?;
        Some(shade_fragment(
            mesh,
            bvh,
            f,
            camera_centre,
            brdf,
            opts,
            (y * w + x) as u64,
        ))
    })
}

/// A `w` x `h` image, rows in parallel, pixel `(x, y)` from `radiance` (`None`: background).
fn shade_with(
    w: usize,
    h: usize,
    opts: &ShadeOptions,
    radiance: impl Fn(usize, usize) -> Option<[f64; 3]> + Sync,
) -> LinearImage {
    let mut img = LinearImage::new(w, h);
    if w == 0 || h == 0 {
        return img;
    }
    img.data_mut()
        .par_chunks_mut(w * 3)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                let rgb = radiance(x, y).map_or(opts.background, |v| v.map(|c| c as f32));
                row[3 * x..3 * x + 3].copy_from_slice(&rgb);
            }
        });
    img
}

/// Radiance towards `camera_centre` from one fragment (see the module header): the per-pixel
/// kernel of [`shade`], public so callers can shade only the pixels they sample.
/// `pixel_id` seeds the environment's per-pixel jitter (row-major index in `shade`).
pub fn shade_fragment(
    mesh: &Mesh,
    bvh: &Bvh,
    f: &Fragment,
    camera_centre: &Point3<f64>,
    brdf: &dyn Brdf,
    opts: &ShadeOptions,
    pixel_id: u64,
) -> [f64; 3] {
    let offset = default_offset(mesh);
    let v = (camera_centre - f.position).normalize();
    let frame = ShadingFrame::new(f.normal);
    let wo = frame.to_local(&v);
    if wo.z <= 0.0 {
        return [0.0; 3];
    }
    let fnorm = mesh.face_normals()[f.face as usize];
    let mut l_out = [0.0f64; 3];
    if let Some(light) = &opts.light {
        let wi = frame.to_local(&light.to_light);
        let lit = wi.z > 0.0
            && (!opts.shadows
                || light_visible(bvh, &f.position, &fnorm, &light.to_light, &v, offset));
        if lit {
            let fr = brdf.eval_local(&wi, &wo);
            for c in 0..3 {
                l_out[c] += fr[c] * light.irradiance[c] * wi.z;
            }
        }
    }
    if let Some(env) = &opts.environment {
        let n_side = stratified_count(env.samples);
        let seed = env.seed ^ pixel_id.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let front = if fnorm.dot(&v) >= 0.0 { fnorm } else { -fnorm };
        let mut sum = [0.0f64; 3];
        for i in 0..n_side {
            for j in 0..n_side {
                // jittered stratification: one uniform point inside stratum (i, j)
                let u1 = (i as f64 + rng.r#gen::<f64>()) / n_side as f64;
                let u2 = (j as f64 + rng.r#gen::<f64>()) / n_side as f64;
                let wi = cosine_direction(u1, u2);
                if env.occlusion {
                    let d = frame.to_world(&wi);
                    let ray = Ray {
                        origin: f.position + front * offset,
                        dir: d,
                    };
                    if d.dot(&front) <= 0.0 || bvh.occluded(&ray, 0.0, f64::INFINITY) {
                        continue;
                    }
                }
                let fr = brdf.eval_local(&wi, &wo);
                for c in 0..3 {
                    sum[c] += fr[c];
                }
            }
        }
        let n = (n_side * n_side) as f64;
        for c in 0..3 {
            l_out[c] += std::f64::consts::PI / n * sum[c] * env.radiance[c];
        }
    }
    l_out
}

/// Side of the square sample grid: `ceil(sqrt(samples))`, at least 1.
fn stratified_count(samples: usize) -> usize {
    let mut s = (samples as f64).sqrt().ceil() as usize;
    while s * s < samples {
        s += 1;
    }
    s.max(1)
}

/// Cosine-distributed direction about +z from two uniforms (Malley's method: uniform on the
/// disk, lifted to the hemisphere).
fn cosine_direction(u1: f64, u2: f64) -> Vector3<f64> {
    let r = u1.sqrt();
    let phi = std::f64::consts::TAU * u2;
    Vector3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt())
}
