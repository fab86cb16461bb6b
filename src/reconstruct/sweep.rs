//! One light image's observations without a G-buffer: the z-buffer (`geometry::zbuffer`) names
//! the face each pixel sees; a pixel's fragment (exact ray against that face) is made only when
//! the mask and the reduction's lattice (`reduce`) let it through; the cheap tests of
//! `observe::check_pixel` run next; the survivors are offered to the reduction's cells, and
//! only the pixels it selects are made again and get their shadow ray
//! (`geometry::shadow::light_visible`). So the cost per pixel is a few hundred nanoseconds,
//! the costly traversals follow the pixels kept, not the sensor, and memory is the z-buffer,
//! 16 bytes per candidate and the kept observations. Without a reduction every surviving
//! pixel gets its shadow ray and is kept.
//!
//! Equal to `observe::observe_view` over a ray-cast G-buffer with a shadow ray per pixel (then
//! `reduce::reduce`), up to silhouette pixels (see `geometry::raster`); the drop counts differ
//! only in order (`observe::DropCounts`), and a reduced pixel that would have been shadowed
//! counts as redundant. Rows are shared out with rayon; the selection depends only on the
//! pixels' hashes, not on the thread count. Pure.

use super::observe::{
    DropCounts, Observation, ObserveSettings, SurfacePixel, ViewInput, black_level, check_pixel,
};
use super::reduce::{Cells, Reduction, priority};
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

/// Rows per band of the parallel scan.
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
    let (w, h) = (
        faces.width().min(img.width()),
        faces.height().min(img.height()),
    );
    let black = black_level(
        (0..h)
            .into_par_iter()
            .map(|y| {
                faces.row(y)[..w]
                    .iter()
                    .enumerate()
                    .filter(|(_, f)| **f != u32::MAX)
                    .map(|(x, _)| img.luminance(x, y))
                    .filter(|v| v.is_finite())
                    .fold(0.0f32, f32::max)
            })
            .collect::<Vec<f32>>()
            .into_iter(),
        settings,
    );
    let stride = settings.reduce.map_or(1, |r| r.stride(w, h));
    let offset = default_offset(mesh);
    let fragment = |x: usize, y: usize, face: u32| {
        let f = rasteriser.fragment_on(face, x as f64 + 0.5, y as f64 + 0.5)?;
        let s = SurfacePixel {
            x: x as u32,
            y: y as u32,
            position: f.position,
            normal: f.normal,
            mean_curvature: f.mean_curvature.unwrap_or(f64::NAN),
            face: f.face,
            lit: true,
        };
        Some((f, s))
    };
    let lit = |f: &crate::geometry::raster::Fragment| {
        light_visible(
            bvh,
            &f.position,
            &mesh.face_normals()[f.face as usize],
            &input.light_world,
            &(input.camera_centre - f.position),
            offset,
        )
    };
    // pass 1: every pixel's cheap tests; kept pixels (no reduction) or candidates by cell
    let parts: Vec<(ViewSweep, Option<Cells>)> = (0..h)
        .step_by(BAND_ROWS)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|y0| {
            let mut part = ViewSweep::default();
            let mut cells = settings.reduce.map(|r| Cells::new(r.cap));
            for y in y0..(y0 + BAND_ROWS).min(h) {
                for (x, &face) in faces.row(y)[..w].iter().enumerate() {
                    if face == u32::MAX {
                        continue;
                    }
                    if let Some(mask) = input.mask
                        && !mask.get(y * img.width() + x).copied().unwrap_or(false)
                    {
                        part.covered += 1;
                        part.dropped.masked_out += 1;
                        continue;
                    }
                    if !Reduction::on_lattice(stride, x, y) {
                        part.covered += 1;
                        part.dropped.redundant += 1;
                        continue;
                    }
                    // an edge pixel whose ray misses the mesh is not covered
                    let Some((f, s)) = fragment(x, y, face) else {
                        continue;
                    };
                    part.covered += 1;
                    let o = match check_pixel(input, &s, settings, black) {
                        Ok(o) => o,
                        Err(reason) => {
                            part.dropped.count(reason);
                            continue;
                        }
                    };
                    match (&mut cells, &settings.reduce) {
                        (Some(c), Some(r)) => c.offer(
                            (o.bin, r.region(s.x, s.y, w, h)),
                            (priority(o.image, s.x, s.y), s.x, s.y),
                        ),
                        _ if lit(&f) => part.observations.push(o),
                        _ => part.dropped.shadowed += 1,
                    }
                }
            }
            (part, cells)
        })
        .collect();
    let mut out = ViewSweep::default();
    let mut all_cells: Option<Cells> = None;
    for (p, c) in parts {
        out.observations.extend(p.observations);
        out.dropped.add(&p.dropped);
        out.covered += p.covered;
        if let Some(c) = c {
            match &mut all_cells {
                Some(a) => a.merge(c),
                None => all_cells = Some(c),
            }
        }
    }
    // pass 2 (reducing): the selected pixels again, and their shadow rays
    if let (Some(cells), Some(r)) = (all_cells, &settings.reduce) {
        let offered = cells.offered();
        let chosen = cells.select(r.budget);
        out.dropped.redundant += offered - chosen.len();
        let made: Vec<Option<Observation>> = chosen
            .par_iter()
            .map(|&(x, y)| {
                let (x, y) = (x as usize, y as usize);
                let (f, s) = fragment(x, y, faces.face(x, y)?)?;
                let o = check_pixel(input, &s, settings, black).ok()?;
                lit(&f).then_some(o)
            })
            .collect();
        for o in made {
            match o {
                Some(o) => out.observations.push(o),
                None => out.dropped.shadowed += 1,
            }
        }
    }
    out
}
