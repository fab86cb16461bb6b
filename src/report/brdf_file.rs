//! A BRDF file a report draws: a MERL table (`.binary`, a reconstruction's result or one of its
//! materials) or a neural MERL fit (`.f32`, a `--compare` curve). Shared by `gather` (the result
//! and the curves it is compared with) and `materials` (each material's spheres); its own file so
//! neither imports the other. Reads files; renders nothing.

use crate::brdf::Brdf;
use crate::brdf::merl::MerlTable;
use crate::brdf::nbrdf::Nbrdf;
use std::path::Path;

/// Why a BRDF file could not be loaded (each cause names the file).
#[derive(Debug, thiserror::Error)]
pub enum LoadBrdfError {
    #[error(transparent)]
    Neural(#[from] crate::brdf::nbrdf::NbrdfError),
    #[error(transparent)]
    Merl(#[from] crate::brdf::merl::MerlError),
}

/// Loads a BRDF file: `.f32` is a neural MERL fit, anything else a MERL table.
pub fn load_brdf(path: &Path) -> Result<Box<dyn Brdf>, LoadBrdfError> {
    if is_neural(path) {
        Ok(Box::new(Nbrdf::load(path)?))
    } else {
        Ok(Box::new(MerlTable::read(path)?))
    }
}

/// Whether `path` is a neural MERL fit (an approximation, not measured data).
pub fn is_neural(path: &Path) -> bool {
    path.extension().is_some_and(|e| e == "f32")
}
