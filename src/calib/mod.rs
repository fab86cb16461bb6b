//! Calibration of the rig's light from images: its direction from a glossy black sphere
//! (`sphere`, combined over images in `light`), its irradiance from a white reference board
//! (`white`), and linear radiance from exposure brackets and non-linear cameras (`hdr`).
//!
//! Conventions: camera axes x right, y down, z forward (COLMAP, as `geometry::camera`); light
//! directions point from the object towards the light; angles in radians inside, degrees only
//! in reports and at the command line. Pure computation on `LinearImage`s: reading files and
//! writing session folders belong to the CLI and `capture`.

pub mod clip;
pub mod hdr;
pub mod light;
pub mod regions;
pub mod robust;
pub mod sphere;
pub mod white;
