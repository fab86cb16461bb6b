//! The `brdf-rig bench ...` studies, one file per command: each takes a typed options struct,
//! runs, writes its pages (markdown, JSON, SVG charts) where the options say, and returns what
//! the command prints. The command line only parses arguments into the options and prints; it
//! also spells the command as typed (`command` in each options struct), which every page quotes.
//!
//! Notes for the person watching (progress, per-scene summaries) go through a [`Note`] callback:
//! the caller decides where they go (the CLI prints them on stderr, `Step`s with the elapsed
//! time). An I/O edge: writes the pages and scratch folders.

pub mod accuracy;
pub mod capture;
pub mod confidence;
pub mod external;
pub mod materials;
pub mod page;
pub mod reconstruct;
pub mod render;
pub mod rig;
pub mod sweeps;

use std::path::{Path, PathBuf};

use crate::brdf::basis_cache::BasisCacheError;
use crate::brdf::nbrdf::{self, Nbrdf, NbrdfError};
use crate::geometry::mesh_io::MeshIoError;

/// A note from a running study.
#[derive(Clone, Copy, Debug)]
pub enum Note<'a> {
    /// A step started (the CLI prefixes the elapsed time).
    Step(&'a str),
    /// A result or remark, shown as it is (may span lines; no trailing newline).
    Detail(&'a str),
}

/// Why a study stopped. Each names the file, folder, mesh or material concerned; the chain of
/// sources is what the command prints under "caused by".
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// A value given that cannot be used (an option, as the command line spells it; a
    /// material name), or a result that cannot be reported.
    #[error("{0}")]
    Invalid(String),
    #[error("creating {}", path.display())]
    CreateDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("writing {}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("reading {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{} is not JSON", path.display())]
    NotJson {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    #[error("creating a temporary folder")]
    TempDir(#[source] std::io::Error),
    #[error("loading mesh {name}")]
    Mesh {
        name: String,
        #[source]
        source: MeshIoError,
    },
    #[error("loading the neural MERL fits from {}", dir.display())]
    Materials {
        dir: PathBuf,
        #[source]
        source: NbrdfError,
    },
    /// What the study was doing when a step of the library failed.
    #[error("{what}")]
    Step {
        what: String,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
    #[error(transparent)]
    MeshFile(#[from] MeshIoError),
    #[error(transparent)]
    Nbrdf(#[from] NbrdfError),
    #[error(transparent)]
    Basis(#[from] BasisCacheError),
    #[error(transparent)]
    Eval(#[from] crate::eval::EvalError),
    #[error(transparent)]
    Chart(#[from] crate::report::charts::ChartError),
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    #[error(transparent)]
    Profile(#[from] crate::profile::ProfileError),
    #[error(transparent)]
    Capture(Box<crate::pipeline::capture_run::CaptureRunError>),
    #[error(transparent)]
    RunCapture(#[from] crate::capture::CaptureError),
    #[error(transparent)]
    Format(#[from] crate::format::FormatError),
    #[error(transparent)]
    Merl(#[from] crate::brdf::merl::MerlError),
    #[error(transparent)]
    Reconstruct(#[from] crate::reconstruct::prepare::ReconstructError),
    #[error(transparent)]
    Io(#[from] std::io::Error),
    #[error(transparent)]
    Fmt(#[from] std::fmt::Error),
}

impl From<crate::pipeline::capture_run::CaptureRunError> for BenchError {
    fn from(e: crate::pipeline::capture_run::CaptureRunError) -> Self {
        BenchError::Capture(Box::new(e))
    }
}

impl BenchError {
    /// `source`, with what the study was doing.
    pub fn step(
        what: impl Into<String>,
        source: impl Into<Box<dyn std::error::Error + Send + Sync + 'static>>,
    ) -> Self {
        BenchError::Step {
            what: what.into(),
            source: source.into(),
        }
    }
}

/// Writes `text` to `path`, naming the file on failure.
pub fn write_file(path: &Path, text: impl AsRef<[u8]>) -> Result<(), BenchError> {
    std::fs::write(path, text).map_err(|source| BenchError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// Creates the folder `path` (and its parents), naming it on failure.
pub fn create_dir(path: &Path) -> Result<(), BenchError> {
    std::fs::create_dir_all(path).map_err(|source| BenchError::CreateDir {
        path: path.to_path_buf(),
        source,
    })
}

/// A temporary folder, removed on drop.
pub fn temp_dir() -> Result<tempfile::TempDir, BenchError> {
    tempfile::tempdir().map_err(BenchError::TempDir)
}

/// The neural MERL fits in `dir` (`None`: the data folder's).
pub fn load_materials(dir: Option<&Path>) -> Result<Vec<(String, Nbrdf)>, BenchError> {
    let dir = dir.map_or_else(nbrdf::default_dir, Path::to_path_buf);
    nbrdf::load_dir(&dir).map_err(|source| BenchError::Materials { dir, source })
}

/// The scene folder: given, or a temporary one removed on drop.
pub enum Scratch {
    Given(PathBuf),
    Temp(tempfile::TempDir),
}

impl Scratch {
    /// The folder given (created), or a new temporary one.
    pub fn new(given: Option<&Path>) -> Result<Scratch, BenchError> {
        Ok(match given {
            Some(p) => {
                create_dir(p)?;
                Scratch::Given(p.to_path_buf())
            }
            None => Scratch::Temp(temp_dir()?),
        })
    }

    pub fn path(&self) -> &Path {
        match self {
            Scratch::Given(p) => p,
            Scratch::Temp(t) => t.path(),
        }
    }
}
