//! Geometry: cameras, mesh and camera import (PLY, OBJ, COLMAP), rasteriser, curvature.
//! Pure computation except the importers, which read files and name them in their errors.

pub mod camera;
pub mod mesh;
pub mod mesh_io;
