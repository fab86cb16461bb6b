//! Visibility of a directional light from surface points (cast shadows), through the BVH.
//!
//! A shadow ray starts at the surface point pushed off along the geometric face normal, on the
//! side the viewer sees (a face whose plane separates viewer and light shadows itself; a lit
//! face does not hit itself through rounding), by `offset`: [`default_offset`] is 1e-6 of the
//! mesh's bounding-box diagonal, far above f64 rounding and far below any feature of a scanned
//! object. The light is at infinity: the ray has no far end. Pure; depends on `mesh`, `bvh`,
//! `raster`.

use super::bvh::{Bvh, Ray};
use super::mesh::Mesh;
use super::raster::GBuffer;
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// The ray offset used by [`shadow_mask`]: 1e-6 of the bounding-box diagonal.
pub fn default_offset(mesh: &Mesh) -> f64 {
    1e-6 * mesh.diagonal()
}

/// Whether the light in unit direction `to_light` (world, towards the light) reaches `point`,
/// seen from direction `to_viewer`, on a face with unit geometric normal `face_normal`.
///
/// The side of the face the viewer sees is the front, whatever the winding (SfM meshes are not
/// reliably oriented): a light on the other side of the face's plane leaves the point dark.
pub fn light_visible(
    bvh: &Bvh,
    point: &Point3<f64>,
    face_normal: &Vector3<f64>,
    to_light: &Vector3<f64>,
    to_viewer: &Vector3<f64>,
    offset: f64,
) -> bool {
    let front = if face_normal.dot(to_viewer) >= 0.0 {
        *face_normal
    } else {
        -face_normal
    };
    if front.dot(to_light) <= 0.0 {
        return false;
    }
    let ray = Ray {
        origin: point + front * offset,
        dir: *to_light,
    };
    !bvh.occluded(&ray, 0.0, f64::INFINITY)
}

/// Per pixel of `gbuf` (row-major): `Some(true)` lit, `Some(false)` in shadow (cast or turned
/// away from the light), `None` where the mesh is not seen.
pub fn shadow_mask(
    mesh: &Mesh,
    bvh: &Bvh,
    gbuf: &GBuffer,
    camera_centre: &Point3<f64>,
    to_light: &Vector3<f64>,
) -> Vec<Option<bool>> {
    let l = to_light.normalize();
    let off = default_offset(mesh);
    gbuf.fragments()
        .par_iter()
        .map(|f| {
            f.as_ref().map(|f| {
                let fnorm = &mesh.face_normals()[f.face as usize];
                let v = camera_centre - f.position;
                light_visible(bvh, &f.position, fnorm, &l, &v, off)
            })
        })
        .collect()
}
