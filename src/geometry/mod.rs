//! Geometry: cameras, meshes and their import/export (PLY, OBJ), COLMAP models, the BVH, the
//! rasteriser (z-buffer visibility, exact per-pixel rays), shadows, curvature and SfM-like meshes.
//! Pure computation except the importers/exporters (`mesh_io`, `colmap`), which read and write
//! files and name them in their errors (writes go through `crate::atomic::write_atomic`). Must
//! not depend on `render`, `brdf` or anything at the edges (devices, capture, sim): those depend
//! on geometry, not the other way round.

pub mod bvh;
pub mod camera;
pub mod colmap;
pub mod curvature;
pub mod mesh;
pub mod mesh_io;
pub mod raster;
pub mod sfm_like;
pub mod shadow;
pub mod zbuffer;
