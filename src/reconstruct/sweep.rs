//! One light image's observations in one pass over its pixels, without a G-buffer: the
//! z-buffer (`geometry::zbuffer`) names the face each pixel sees, a pixel's fragment (exact ray
//! against that face) is made only when the mask lets it through, the cheap tests of
//! `observe::check_pixel` run next, then the reduction (`reduce`) decides whether the pixel
//! would be kept, and only then is its shadow ray cast (`geometry::shadow::light_visible`). So
//! the cost per pixel is a few hundred nanoseconds and the costly traversals follow the pixels
//! kept, not the sensor; memory is the z-buffer plus the kept observations.
//!
//! Equal to `observe::observe_view` over a ray-cast G-buffer with a shadow ray per pixel (then
//! `reduce::reduce`), up to silhouette pixels (see `geometry::raster`); the drop counts differ
//! only in order (`observe::DropCounts`). Rows are shared out with rayon in bands that share no
//! reduction cell, so the result does not depend on the thread count. Pure.

use super::observe::{
    DropCounts, Observation, ObserveSettings, SurfacePixel, ViewInput, black_level, check_pixel,
};
use super::reduce::{Reservoir, priority};
use crate::geometry::bvh::Bvh;
use crate::geometry::mesh::Mesh;
use crate::geometry::raster::Rasteriser;
use crate::geometry::shadow::{default_offset, light_visible};
use crate::geometry::zbuffer::FaceBuffer;
use rayon::prelude::*;

/// What one view gave.
#[derive(Debug, Default)]
pub struct ViewSweep {
    pub observations: Vec<Observation>,
    pub dropped: DropCounts,
    /// Pixels where the mesh is seen.
    pub covered: usize,
}

/// Rows per band when nothing is reduced.
const BAND_ROWS: usize = 32;

/// Observes one view (see the module header). `rasteriser` is the view's camera on `mesh`
/// (with the per-vertex mean curvature), `faces` its z-buffer.
pub fn sweep_view(
    mesh: &Mesh,
    bvh: &Bvh,
    rasteriser: &Rasteriser<'_>,
    faces: &FaceBuffer,
    input: &ViewInput<'_>,
    settings: &ObserveSettings,
) -> ViewSweep {
    let img = input.image;
    let (w, h) = (faces.width(), faces.height());
    let black = black_level(
        (0..h)
            .into_par_iter()
            .map(|y| {
                faces
                    .row(y)
                    .iter()
                    .enumerate()
                    .filter(|(x, f)| **f != u32::MAX && *x < img.width() && y < img.height())
                    .map(|(x, _)| img.luminance(x, y))
                    .filter(|v| v.is_finite())
                    .fold(0.0f32, f32::max)
            })
            .collect::<Vec<f32>>()
            .into_iter(),
        settings,
    );
    // bands of rows: one per region row when reducing (no cell spans two bands)
    let bands: Vec<(usize, usize)> = match &settings.reduce {
        Some(r) => {
            let mut b: Vec<(usize, usize)> = Vec::new();
            for y in 0..h {
                match b.last_mut() {
                    Some(last) if r.region_row(last.0, h) == r.region_row(y, h) => last.1 = y + 1,
                    _ => b.push((y, y + 1)),
                }
            }
            b
        }
        None => (0..h)
            .step_by(BAND_ROWS)
            .map(|y| (y, (y + BAND_ROWS).min(h)))
            .collect(),
    };
    let offset = default_offset(mesh);
    let parts: Vec<ViewSweep> = bands
        .par_iter()
        .map(|&(y0, y1)| {
            let mut part = ViewSweep::default();
            let mut kept = settings.reduce.map(|r| (r, Reservoir::new(r.cap)));
            for y in y0..y1 {
                for (x, &face) in faces.row(y).iter().enumerate() {
                    if face == u32::MAX || x >= img.width() || y >= img.height() {
                        continue;
                    }
                    if let Some(mask) = input.mask
                        && !mask.get(y * img.width() + x).copied().unwrap_or(false)
                    {
                        part.covered += 1;
                        part.dropped.masked_out += 1;
                        continue;
                    }
                    let Some(f) = rasteriser.fragment_on(face, x as f64 + 0.5, y as f64 + 0.5)
                    else {
                        continue; // an edge pixel whose ray misses the mesh: not covered
                    };
                    part.covered += 1;
                    let s = SurfacePixel {
                        x: x as u32,
                        y: y as u32,
                        position: f.position,
                        normal: f.normal,
                        mean_curvature: f.mean_curvature.unwrap_or(f64::NAN),
                        lit: true,
                    };
                    let o = match check_pixel(input, &s, settings, black) {
                        Ok(o) => o,
                        Err(reason) => {
                            part.dropped.count(reason);
                            continue;
                        }
                    };
                    let key_prio = kept.as_ref().map(|(r, _)| {
                        let key = (o.bin, r.region(s.x, s.y, w, h));
                        (key, priority(o.image, s.x, s.y))
                    });
                    if let (Some((_, res)), Some((key, prio))) = (&kept, key_prio)
                        && !res.admits(key, prio)
                    {
                        part.dropped.redundant += 1;
                        continue;
                    }
                    let lit = light_visible(
                        bvh,
                        &f.position,
                        &mesh.face_normals()[f.face as usize],
                        &input.light_world,
                        &(input.camera_centre - f.position),
                        offset,
                    );
                    if !lit {
                        part.dropped.shadowed += 1;
                        continue;
                    }
                    match (&mut kept, key_prio) {
                        (Some((_, res)), Some((key, prio))) => res.insert(key, prio, o),
                        _ => part.observations.push(o),
                    }
                }
            }
            if let Some((_, res)) = kept {
                part.dropped.redundant += res.evicted();
                part.observations = res.into_observations();
            }
            part
        })
        .collect();
    let mut out = ViewSweep::default();
    for p in parts {
        out.observations.extend(p.observations);
        out.dropped.add(&p.dropped);
        out.covered += p.covered;
    }
    out
}
