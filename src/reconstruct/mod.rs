//! Reconstruction of an isotropic BRDF from a mesh, camera poses and single-light images
//! (METHOD.md sections 2-6; the paper: Ono et al., NAIST).
//!
//! The flow, one file per concept:
//! - [`job`]: the job file (mesh, COLMAP model, light images with light direction and irradiance);
//! - [`observe`]: per pixel directions, reflectance, Rusinkiewicz angles and MERL bin;
//!   [`sweep`] makes them for a whole view from its z-buffer, [`reduce`] thins out redundant
//!   pixels (per MERL bin and image region);
//! - [`reliable`]: the three assumptions (curvature, monotonicity, brightest pixel);
//! - [`prior`]: what a BRDF prior offers (sample selection, ridge fit), [`nielsen`] the real one;
//! - [`components`]: the number of basis components, by validation on held-back pixels;
//! - [`trials`]: random trials, chosen by cosine similarity with the captured images;
//! - [`refine`]: optional: the mesh's normals refined from the images before all of the above;
//! - [`segment`], [`mask_labels`], [`materials`]: objects of several materials (issue #17):
//!   found in the images, fixed where the job's label masks give them, one BRDF each.
//!
//! [`core`] chains the pure steps on observations; [`prepare`] loads a job's files and
//! observes them; [`run`] runs everything on a job; [`output`] fills the report and writes the
//! results; [`report_file`] owns the format of `report.json` (read back by the HTML report).
//! Only `prepare`, `output` and `report_file` touch files. Simulated job folders are written
//! by `sim::job_scene`, outside the method.
//!
//! Entry points: [`reconstruct`] (job + settings, builds or reads the cached basis),
//! [`reconstruct_with_basis`] (a basis in memory, for studies), [`output::write`].

pub mod baselines;
pub mod carry;
pub mod compare;
pub mod components;
pub mod confidence;
pub mod core;
pub mod deblur;
pub mod extrapolation;
pub mod fresnel;
pub mod grazing;
pub mod hedge;
pub mod job;
pub mod ladder;
pub mod lambert_rung;
pub mod mask_labels;
pub mod materials;
pub mod nielsen;
pub mod observation;
pub mod observe;
pub mod output;
pub mod overrides;
pub mod peak_bands;
pub mod peak_energy;
pub mod plausible;
pub mod prepare;
pub mod prior;
pub mod read_back;
pub mod reduce;
pub mod refine;
pub mod reliable;
pub mod report_file;
pub mod run;
pub mod segment;
pub mod shared_shape;
pub mod sweep;
pub mod trials;

pub use core::{CoreOutput, CoreSettings, reconstruct_observations};
pub use job::{Job, JobError, LightImageSpec};
pub use output::Output;
pub use prepare::{ReconstructError, Settings};
pub use run::{reconstruct, reconstruct_with_basis};
