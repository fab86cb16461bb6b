//! Rendering shared by the simulated camera and reconstruction: linear images, shading of a mesh
//! with a BRDF under a directional light and a uniform environment, and analytic scenes (sphere,
//! board) for previews and calibration. Pure: no files, ports or terminal.

pub mod analytic;
pub mod board;
pub mod frame;
pub mod image;
pub mod light;
pub mod shade;
pub mod sphere;
