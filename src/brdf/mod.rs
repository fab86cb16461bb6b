//! BRDFs: the MERL table and Rusinkiewicz coordinates, the neural MERL fits, the PCA basis,
//! optimal sampling, reconstruction, trial selection and analytic models. Pure: no files here
//! except in the loaders, which name the file in every error, and `basis_cache` (an I/O edge).
//!
//! One concept per file:
//! - `coords`: Rusinkiewicz angles, MERL bins and bin centres;
//! - `merl`: the MERL table (read, write, nearest-bin lookup);
//! - `nbrdf`: the neural fits of the 100 MERL materials (approximations, not measured data);
//! - `basis` / `basis_cache`: the PCA prior (Nielsen et al. 2015) and its disk cache;
//! - `sampling`: optimal sample bins by condition number;
//! - `rank_one`: the condition number of a matrix with one more row, for many rows at once;
//! - `ridge`: reconstruction from observations;
//! - `metrics`: relative, cosine-weighted and near-specular errors;
//! - `analytic`: Lambert and Lambert + GGX baselines with least-squares fits.
//!
//! Convention for every BRDF in this crate: directions are unit vectors in the local shading
//! frame (normal = +z), both pointing away from the surface (`wi` towards the light, `wo`
//! towards the viewer); the value is f_r in 1/sr, RGB, without the cosine factor.

use nalgebra::Vector3;

/// An isotropic (or not) BRDF evaluated in the local frame.
pub trait Brdf: Send + Sync {
    /// f_r(wi, wo) in 1/sr, RGB. Directions below the surface give zero.
    fn eval_local(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3];
}

pub mod analytic;
pub mod basis;
pub mod basis_cache;
pub mod coords;
pub mod merl;
pub mod metrics;
pub mod nbrdf;
pub mod rank_one;
pub mod ridge;
pub mod sampling;

/// A BRDF known at MERL bins (a table, a network, a reconstruction): what the basis is built
/// from and what the error metrics compare.
pub trait BinValues: Sync {
    /// f_r in 1/sr, RGB, at each flat MERL bin index (bins with no data give zero).
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]>;
}

/// A shared table (a result's table is held by its core, its material and the output).
impl<T: BinValues + Send> BinValues for std::sync::Arc<T> {
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        (**self).values_at(bins)
    }
}
