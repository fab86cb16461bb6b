//! Geometry: reflection about a normal, cameras, meshes and their import/export (PLY, OBJ), COLMAP
//! models, the BVH, the rasteriser (z-buffer visibility, exact per-pixel rays), shadows,
//! curvature, Taubin smoothing, SfM-like meshes and per-face material labels.
//! Pure computation except the importers/exporters (`mesh_io`, `colmap`), which read and write
//! files and name them in their errors (writes go through `crate::atomic::write_atomic`). Must
//! not depend on `render`, `brdf` or anything at the edges (devices, capture, sim): those depend
//! on geometry, not the other way round.

pub mod bvh;
pub mod camera;
pub mod colmap;
pub mod curvature;
pub mod labels;
pub mod mesh;
pub mod mesh_io;
pub mod raster;
pub mod sfm_like;
pub mod shadow;
pub mod taubin;
pub mod zbuffer;

use nalgebra::Vector3;

/// Mirror `v` about the unit normal `n`: `2 (n.v) n - v` (the light direction that a mirror with
/// normal `n` reflects towards `v`).
pub fn reflect(n: &Vector3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
    n * (2.0 * n.dot(v)) - v
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn reflection_is_the_mirror_direction() {
        let n = Vector3::new(0.0, 0.0, -1.0);
        let v = Vector3::new(0.6, 0.0, -0.8);
        let l = reflect(&n, &v);
        assert!((l - Vector3::new(-0.6, 0.0, -0.8)).norm() < 1e-12);
        // half vector of l and v is n
        assert!(((l + v).normalize() - n).norm() < 1e-12);
    }
}
