//! Rendering shared by the simulated camera and reconstruction: linear images, shading of a mesh
//! with a BRDF under a directional light, sphere previews. Pure: no files, ports or terminal.

pub mod image;
