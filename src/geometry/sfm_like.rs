//! An "SfM-like" mesh from a true mesh: what photogrammetry (SfM + MVS + surface
//! reconstruction) would hand us, for the simulated capture and for tests of how reconstruction
//! copes with wrong normals.
//!
//! Model, in order: (1) Taubin lambda|mu smoothing (Taubin 1995) with the uniform ("umbrella")
//! Laplacian, which rounds off curved detail, as MVS fusion and Poisson reconstruction do, so
//! normal errors grow with curvature (the premise of METHOD.md section 4, assumption 1) while
//! flat regions and overall volume are kept; (2) seeded Gaussian displacement of every vertex
//! along its (smoothed) normal, with standard deviation `noise_rel` times the mean edge length,
//! for MVS depth noise. Defaults: 10 iterations, lambda = 0.5, mu = -0.53 (pass band
//! k_PB ~ 0.1), noise 0.05 of the mean edge length. Topology is unchanged; boundary vertices
//! are smoothed like the others. Deterministic for a given seed (ChaCha8). Pure; depends only
//! on `mesh`.

use super::mesh::Mesh;
use super::taubin::taubin_smooth;
use nalgebra::Point3;
use rand::{Rng, SeedableRng};

/// Parameters of [`sfm_like`]; see the module header for what each models.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SfmLikeParams {
    /// Taubin iterations (each one lambda step and one mu step); 0 disables smoothing.
    pub iterations: usize,
    pub lambda: f64,
    pub mu: f64,
    /// Standard deviation of the normal displacement, as a fraction of the mean edge length.
    pub noise_rel: f64,
    pub seed: u64,
}

impl Default for SfmLikeParams {
    fn default() -> Self {
        Self {
            iterations: 10,
            lambda: 0.5,
            mu: -0.53,
            noise_rel: 0.05,
            seed: 0,
        }
    }
}

/// Mean length of the face edges (each interior edge counted twice; a scale, not a statistic).
pub fn mean_edge_length(mesh: &Mesh) -> f64 {
    crate::geometry::mesh::mean_edge_length(mesh.faces(), mesh.positions())
}

/// The SfM-like version of `truth` (same vertex count and faces).
pub fn sfm_like(truth: &Mesh, params: &SfmLikeParams) -> Mesh {
    let mut m = truth.clone();
    taubin_smooth(&mut m, params.iterations, params.lambda, params.mu);
    if params.noise_rel > 0.0 {
        let sigma = params.noise_rel * mean_edge_length(truth);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(params.seed);
        let p: Vec<Point3<f64>> = m
            .positions()
            .iter()
            .zip(m.vertex_normals())
            .map(|(p, n)| p + n * (sigma * standard_normal(&mut rng)))
            .collect();
        let _ = m.set_positions(p);
    }
    m
}

/// A standard normal sample (Box–Muller; rand 0.8 without rand_distr has none).
fn standard_normal(rng: &mut impl Rng) -> f64 {
    let u1: f64 = 1.0 - rng.r#gen::<f64>(); // (0, 1]: ln is finite
    let u2: f64 = rng.r#gen();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}
