//! Rendering shared by the simulated camera and reconstruction: linear images, shading of a mesh
//! with a BRDF under a directional light and a uniform environment, and analytic scenes (sphere,
//! board) for previews and calibration. Pure: no files, ports or terminal. Depends on `geometry`
//! (cameras, meshes, BVH) and the `Brdf` trait only; file formats live in `crate::imageio`.

pub mod board;
pub mod environment;
pub mod frame;
pub mod image;
pub mod light;
pub mod probe;
pub mod raytraced;
pub mod shade;
pub mod sphere;
