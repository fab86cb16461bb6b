//! Visibility by scan conversion: which face each pixel sees (a z-buffer holding face ids), so a
//! view costs one pass over the mesh's triangles plus a constant per pixel, not one traversal
//! of the BVH per pixel.
//!
//! Method: every vertex is projected once (`Intrinsics::project`, lens distortion included);
//! each triangle is filled at the pixel centres `(x + 0.5, y + 0.5)` its projected edges
//! enclose (edge functions in f64; a centre on a shared edge goes to either face), keeping the
//! nearest by perspective-correct depth (1/z interpolated linearly on the image). Rows are
//! shared out in bands with rayon. The buffer only names the face: the fragment itself
//! (barycentrics, position, depth) comes from the pixel's exact ray against that face
//! (`raster::Rasteriser::fragment_on`), so it is the ray caster's to rounding, and a pixel whose
//! ray misses its face (an edge pixel, or a curved edge under lens distortion) is ray-cast
//! through the BVH instead.
//!
//! Limits: a triangle with a corner at or behind the camera plane cannot be projected; then
//! [`face_buffer`] returns `None` and callers ray-cast the view (the object is in front of the
//! camera in every capture we make). Memory: 4 bytes per pixel for the ids plus 4 for depth
//! while filling (24 MP: ~190 MB), against ~130 bytes per pixel for a G-buffer of fragments.
//! Pure; depends on `mesh`, `camera`.

use super::camera::{Intrinsics, Pose};
use super::mesh::Mesh;
use rayon::prelude::*;

/// Marks a pixel the mesh does not cover.
const NO_FACE: u32 = u32::MAX;

/// Rows per band filled by one task.
const BAND_ROWS: usize = 32;

/// The face seen through each pixel, row-major.
#[derive(Clone, Debug)]
pub struct FaceBuffer {
    width: usize,
    height: usize,
    faces: Vec<u32>,
}

impl FaceBuffer {
    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// The face seen through pixel `(x, y)`; `None` off the mesh or outside the image.
    pub fn face(&self, x: usize, y: usize) -> Option<u32> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let f = self.faces[y * self.width + x];
        (f != NO_FACE).then_some(f)
    }

    /// One row's face ids (`u32::MAX` where nothing is seen).
    pub fn row(&self, y: usize) -> &[u32] {
        &self.faces[y * self.width..(y + 1) * self.width]
    }

    /// Number of covered pixels.
    pub fn covered(&self) -> usize {
        self.faces.iter().filter(|&&f| f != NO_FACE).count()
    }
}

/// A projected corner: pixel position and 1/z.
#[derive(Clone, Copy)]
struct Corner {
    x: f64,
    y: f64,
    inv_z: f64,
}

/// Scan-converts `mesh` seen by camera `k`, `pose`; `None` when a vertex of the mesh lies at or
/// behind the camera plane (see the module header).
pub fn face_buffer(mesh: &Mesh, k: &Intrinsics, pose: &Pose) -> Option<FaceBuffer> {
    let (w, h) = (k.width, k.height);
    let corners: Vec<Corner> = mesh
        .positions()
        .par_iter()
        .map(|p| {
            let pc = pose.camera_from_world(p);
            let (x, y) = k.project(&pc)?;
            Some(Corner {
                x,
                y,
                inv_z: 1.0 / pc.z,
            })
        })
        .collect::<Option<Vec<_>>>()?;
    // each face's corners and its pixel-row range, kept for the faces that touch the image
    let tris: Vec<(u32, [Corner; 3], usize, usize)> = mesh
        .faces()
        .iter()
        .enumerate()
        .filter_map(|(f, face)| {
            let c = face.map(|i| corners[i as usize]);
            let (lo, hi) = span(c.map(|c| c.y), h)?;
            span(c.map(|c| c.x), w)?;
            Some((f as u32, c, lo, hi))
        })
        .collect();
    let mut faces = vec![NO_FACE; w * h];
    if w > 0 {
        faces
            .par_chunks_mut(w * BAND_ROWS)
            .enumerate()
            .for_each(|(band, ids)| {
                let y0 = band * BAND_ROWS;
                let rows = ids.len() / w;
                let mut depth = vec![0.0f32; ids.len()];
                for (f, c, lo, hi) in &tris {
                    if *hi < y0 || *lo >= y0 + rows {
                        continue;
                    }
                    fill(*f, c, w, y0, rows, ids, &mut depth);
                }
            });
    }
    Some(FaceBuffer {
        width: w,
        height: h,
        faces,
    })
}

/// The range of pixel indices `i` (centres `i + 0.5`) within `[0, n)` that coordinates `v` can
/// cover, inclusive; `None` when it is empty.
fn span(v: [f64; 3], n: usize) -> Option<(usize, usize)> {
    let lo = v[0].min(v[1]).min(v[2]);
    let hi = v[0].max(v[1]).max(v[2]);
    if !(lo.is_finite() && hi.is_finite()) || hi < 0.5 || lo > n as f64 - 0.5 {
        return None;
    }
    let a = (lo - 0.5).ceil().max(0.0) as usize;
    let b = ((hi - 0.5).floor() as usize).min(n - 1);
    (a <= b).then_some((a, b))
}

/// Fills one triangle into the band starting at row `y0` with `rows` rows.
fn fill(
    face: u32,
    c: &[Corner; 3],
    w: usize,
    y0: usize,
    rows: usize,
    ids: &mut [u32],
    depth: &mut [f32],
) {
    let edge =
        |a: &Corner, b: &Corner, x: f64, y: f64| (b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x);
    let area = edge(&c[0], &c[1], c[2].x, c[2].y);
    if area == 0.0 || !area.is_finite() {
        return;
    }
    let Some((ya, yb)) = span(c.map(|c| c.y), y0 + rows) else {
        return;
    };
    let Some((xa, xb)) = span(c.map(|c| c.x), w) else {
        return;
    };
    for y in ya.max(y0)..=yb {
        let py = y as f64 + 0.5;
        let row = (y - y0) * w;
        for x in xa..=xb {
            let px = x as f64 + 0.5;
            // weights of corners 0, 1, 2 (each the edge opposite it), signed like `area`
            let w0 = edge(&c[1], &c[2], px, py) / area;
            let w1 = edge(&c[2], &c[0], px, py) / area;
            let w2 = 1.0 - w0 - w1;
            if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                continue;
            }
            let inv_z = (w0 * c[0].inv_z + w1 * c[1].inv_z + w2 * c[2].inv_z) as f32;
            let i = row + x;
            // 1/z > 0 in front of the camera; larger is nearer; 0 marks an empty pixel
            if inv_z > depth[i] {
                depth[i] = inv_z;
                ids[i] = face;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Vector3};

    #[test]
    fn the_nearer_of_two_overlapping_squares_wins_and_coverage_is_exact() {
        // two unit squares facing the camera at z = 0 (faces 0, 1) and z = 1 (faces 2, 3),
        // the nearer shifted right by 0.5; camera 5 units up z
        let sq = |dx: f64, z: f64| {
            vec![
                Point3::new(-0.5 + dx, -0.5, z),
                Point3::new(0.5 + dx, -0.5, z),
                Point3::new(0.5 + dx, 0.5, z),
                Point3::new(-0.5 + dx, 0.5, z),
            ]
        };
        let mut p = sq(0.0, 0.0);
        p.extend(sq(0.5, 1.0));
        let f = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
        let (mesh, _) = Mesh::new(p, f, "<squares>").unwrap();
        let k = Intrinsics::pinhole(100, 80, 100.0, 100.0, 50.0, 40.0);
        let pose = Pose::look_at(Point3::new(0.0, 0.0, 5.0), Point3::origin(), Vector3::y());
        let fb = face_buffer(&mesh, &k, &pose).unwrap();
        // far square: half width 100 * 0.5 / 5 = 10 px; near: 100 * 0.5 / 4 = 12.5 px, its
        // centre where its middle projects
        let near_c = k
            .project(&pose.camera_from_world(&Point3::new(0.5, 0.0, 1.0)))
            .unwrap();
        for y in 0..80 {
            for x in 0..100 {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let (fx, fy) = ((px - 50.0).abs(), (py - 40.0).abs());
                let (nx, ny) = ((px - near_c.0).abs(), (py - near_c.1).abs());
                // a pixel centre on an edge may go either way
                let on_edge = |d: f64, half: f64| (d - half).abs() < 1e-6;
                if [(fx, 10.0), (fy, 10.0), (nx, 12.5), (ny, 12.5)]
                    .iter()
                    .any(|&(d, half)| on_edge(d, half))
                {
                    continue;
                }
                let in_far = fx < 10.0 && fy < 10.0;
                let in_near = nx < 12.5 && ny < 12.5;
                let got = fb.face(x, y);
                if in_near {
                    assert!(matches!(got, Some(2 | 3)), "pixel {x},{y}: {got:?}");
                } else if in_far {
                    assert!(matches!(got, Some(0 | 1)), "pixel {x},{y}: {got:?}");
                } else {
                    assert_eq!(got, None, "pixel {x},{y}");
                }
            }
        }
        // a vertex behind the camera: no buffer
        let behind = Pose::look_at(
            Point3::new(0.0, 0.0, 0.5),
            Point3::new(0.0, 0.0, -1.0),
            Vector3::y(),
        );
        assert!(face_buffer(&mesh, &k, &behind).is_none());
    }
}
