//! Geometry: cameras, mesh and camera import (PLY, OBJ, COLMAP), rasteriser, curvature.
//! Pure computation except the importers, which read files and name them in their errors.

pub mod bvh;
pub mod camera;
pub mod colmap;
pub mod curvature;
pub mod mesh;
pub mod mesh_io;
pub mod raster;
pub mod shadow;
