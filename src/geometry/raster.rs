//! Rasterisation of a mesh from a camera: per pixel the visible face, barycentrics, depth, world
//! position, interpolated normal and (optionally) interpolated mean curvature.
//!
//! Method: visibility from a z-buffer of face ids (`zbuffer`: one pass over the triangles),
//! then per covered pixel the exact ray through its centre, `Intrinsics::ray(x + 0.5, y + 0.5)`
//! (which undistorts, so lens distortion is exact with no resampling), against the face the
//! z-buffer names; a ray that misses that face (an edge pixel) is cast through the BVH, which
//! also serves views the z-buffer cannot take (a vertex behind the camera) and the shadow
//! rays. So a fragment is the ray caster's ([`Rasteriser::gbuffer_ray_cast`], kept as the
//! reference) up to pixels on a silhouette, whose centre the two may assign differently.
//! Rows are shared out with rayon. One sample per pixel: edges are aliased, which is what
//! reconstruction wants (a pixel belongs to one face or to none).
//!
//! Conventions: `depth` is the camera-space z of the hit (COLMAP's depth-map convention, not the
//! ray length); positions and normals are in world coordinates; the normal is the barycentric
//! blend of the vertex normals, renormalised (the face normal where the blend vanishes), and is
//! not flipped towards the camera, so `n . v < 0` marks a pixel whose normal disagrees with
//! visibility (common on SfM meshes near silhouettes). Pure; depends on `mesh`, `bvh`, `camera`.

use super::bvh::{Bvh, Hit, Ray, intersect_triangle};
use super::camera::{Intrinsics, Pose};
use super::mesh::Mesh;
use super::zbuffer::{FaceBuffer, face_buffer};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// What one pixel sees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fragment {
    pub face: u32,
    /// Weights of the face's corners 0, 1, 2.
    pub bary: [f64; 3],
    /// Camera-space z of the hit.
    pub depth: f64,
    pub position: Point3<f64>,
    /// Interpolated unit vertex normal (world).
    pub normal: Vector3<f64>,
    /// Interpolated per-vertex mean curvature, when the caller supplied one.
    pub mean_curvature: Option<f64>,
}

/// Per-pixel fragments, row-major, `None` where the mesh does not cover the pixel.
#[derive(Clone, Debug)]
pub struct GBuffer {
    width: usize,
    height: usize,
    frags: Vec<Option<Fragment>>,
}

impl GBuffer {
    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// The fragment at `(x, y)`; `None` outside the image or off the mesh.
    pub fn get(&self, x: usize, y: usize) -> Option<&Fragment> {
        if x >= self.width || y >= self.height {
            return None;
        }
        self.frags[y * self.width + x].as_ref()
    }

    /// All pixels row-major.
    pub fn fragments(&self) -> &[Option<Fragment>] {
        &self.frags
    }

    /// Coverage mask, row-major: `true` where the mesh is seen.
    pub fn coverage(&self) -> Vec<bool> {
        self.frags.iter().map(Option::is_some).collect()
    }

    /// Number of covered pixels.
    pub fn covered(&self) -> usize {
        self.frags.iter().filter(|f| f.is_some()).count()
    }
}

/// One mesh seen by one camera: build once per (mesh, camera), then ask for whole images
/// ([`Rasteriser::gbuffer`]), the visible face of every pixel ([`Rasteriser::faces`]) or single
/// pixels ([`Rasteriser::fragment`], [`Rasteriser::fragment_on`]), e.g. to go through a
/// full-resolution photograph without holding a G-buffer for all of it (a `Fragment` is ~120
/// bytes, so a 24-megapixel G-buffer would need ~3 GB).
#[derive(Clone, Copy)]
pub struct Rasteriser<'a> {
    mesh: &'a Mesh,
    bvh: &'a Bvh,
    k: &'a Intrinsics,
    pose: Pose,
    centre: Point3<f64>,
    world_from_cam: nalgebra::UnitQuaternion<f64>,
    cam_z_world: Vector3<f64>,
    curvature: Option<&'a [f64]>,
}

impl<'a> Rasteriser<'a> {
    /// `mean_curvature`, when given, has one value per mesh vertex (see `curvature`); a slice
    /// of the wrong length is ignored (fragments then carry `None`).
    pub fn new(
        mesh: &'a Mesh,
        bvh: &'a Bvh,
        k: &'a Intrinsics,
        pose: &Pose,
        mean_curvature: Option<&'a [f64]>,
    ) -> Self {
        let world_from_cam = pose.rotation.inverse();
        Self {
            mesh,
            bvh,
            k,
            pose: *pose,
            centre: pose.centre(),
            world_from_cam,
            cam_z_world: world_from_cam * Vector3::z(),
            curvature: mean_curvature.filter(|c| c.len() == mesh.positions().len()),
        }
    }

    /// The ray through image position `(px, py)` (pixel units; the centre of pixel `(x, y)` is
    /// `(x + 0.5, y + 0.5)`), world frame.
    fn ray(&self, px: f64, py: f64) -> Ray {
        Ray {
            origin: self.centre,
            dir: self.world_from_cam * self.k.ray(px, py),
        }
    }

    /// What the ray through image position `(px, py)` sees.
    pub fn fragment(&self, px: f64, py: f64) -> Option<Fragment> {
        let ray = self.ray(px, py);
        let hit = self.bvh.intersect(&ray, 0.0, f64::INFINITY)?;
        Some(self.fragment_at(&ray, &hit))
    }

    /// What the ray through `(px, py)` sees, knowing (from a z-buffer) that it is `face`: the
    /// ray against that face alone, or through the BVH when it misses it (an edge pixel).
    pub fn fragment_on(&self, face: u32, px: f64, py: f64) -> Option<Fragment> {
        let ray = self.ray(px, py);
        let corners = self.mesh.triangle(face as usize);
        match intersect_triangle(&corners, &ray, 0.0, f64::INFINITY) {
            Some((t, u, v)) => Some(self.fragment_at(&ray, &Hit { t, face, u, v })),
            None => {
                let hit = self.bvh.intersect(&ray, 0.0, f64::INFINITY)?;
                Some(self.fragment_at(&ray, &hit))
            }
        }
    }

    /// The visible face of every pixel (`zbuffer`); `None` when the view cannot be
    /// scan-converted (a vertex behind the camera): ray-cast it then.
    pub fn faces(&self) -> Option<FaceBuffer> {
        face_buffer(self.mesh, self.k, &self.pose)
    }

    fn fragment_at(&self, ray: &Ray, hit: &Hit) -> Fragment {
        let mesh = self.mesh;
        let f = hit.face as usize;
        let face = mesh.faces()[f];
        let bary = [1.0 - hit.u - hit.v, hit.u, hit.v];
        let position = ray.origin + ray.dir * hit.t;
        let vn = mesh.vertex_normals();
        let n: Vector3<f64> = (0..3).map(|i| vn[face[i] as usize] * bary[i]).sum();
        let len = n.norm();
        let normal = if len > 1e-12 {
            n / len
        } else {
            mesh.face_normals()[f]
        };
        let mean_curvature = self
            .curvature
            .map(|c| (0..3).map(|i| c[face[i] as usize] * bary[i]).sum::<f64>());
        Fragment {
            face: hit.face,
            bary,
            depth: (position - self.centre).dot(&self.cam_z_world),
            position,
            normal,
            mean_curvature,
        }
    }

    /// The whole image, rows in parallel: z-buffer visibility, exact rays (module header).
    pub fn gbuffer(&self) -> GBuffer {
        match self.faces() {
            Some(faces) => self.fill(|x, y| {
                let f = faces.face(x, y)?;
                self.fragment_on(f, x as f64 + 0.5, y as f64 + 0.5)
            }),
            None => self.gbuffer_ray_cast(),
        }
    }

    /// The whole image with one BVH ray per pixel (the reference [`Self::gbuffer`] matches).
    pub fn gbuffer_ray_cast(&self) -> GBuffer {
        self.fill(|x, y| self.fragment(x as f64 + 0.5, y as f64 + 0.5))
    }

    fn fill(&self, frag: impl Fn(usize, usize) -> Option<Fragment> + Sync) -> GBuffer {
        let (w, h) = (self.k.width, self.k.height);
        let mut frags = vec![None; w * h];
        if w > 0 {
            frags.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                for (x, out) in row.iter_mut().enumerate() {
                    *out = frag(x, y);
                }
            });
        }
        GBuffer {
            width: w,
            height: h,
            frags,
        }
    }
}

/// Renders the G-buffer of `mesh` (with its prebuilt `bvh`) seen by camera `k`, `pose`
/// (see [`Rasteriser`] for the curvature argument and per-pixel queries).
pub fn rasterise(
    mesh: &Mesh,
    bvh: &Bvh,
    k: &Intrinsics,
    pose: &Pose,
    mean_curvature: Option<&[f64]>,
) -> GBuffer {
    Rasteriser::new(mesh, bvh, k, pose, mean_curvature).gbuffer()
}
