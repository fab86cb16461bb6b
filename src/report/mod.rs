//! Reports: the paper's in-plane BRDF plot, SVG charts (plotters) and a self-contained HTML
//! page summarising a capture session or a reconstruction.
//!
//! `inplane` and `charts` are pure (data in, SVG strings out). `gather` (with `session` for the
//! capture, `images` for previews and sphere renders, `materials` for the per-material part)
//! reads what a folder holds, tolerantly: a missing piece is reported as "not available" with
//! the reason. `html` renders the page from that, purely. `avail` (a piece or why it is
//! missing), `brdf_file` (loading a result or a curve), `options` and `numbers` are the leaves
//! they share. Only the gathering (with `brdf_file`) and [`write_report`] touch files.

pub mod avail;
pub mod brdf_file;
pub mod charts;
pub mod gather;
pub mod headless;
pub mod html;
pub mod images;
pub mod inplane;
pub mod materials;
pub mod numbers;
pub mod options;
pub mod session;

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("{dir}: cannot read the folder")]
    ReadDir {
        dir: PathBuf,
        source: std::io::Error,
    },
    #[error("{dir}: not a folder (give a session folder or a reconstruction output folder)")]
    NotADir { dir: PathBuf },
    #[error(
        "{dir}: neither a session folder (manifest.json, journal.jsonl or session.json) nor a \
         reconstruction output (brdf.binary or report.json, here or in a subfolder)"
    )]
    NotAReportDir { dir: PathBuf },
    #[error("{path}: cannot write the report")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// The default place of the page: `DIR/report.html`.
pub fn default_output(dir: &Path) -> PathBuf {
    dir.join("report.html")
}

/// Gathers what `dir` holds, renders the page and writes it (atomically) to `out`, or to
/// `DIR/report.html`. Returns the path written and what the page shows.
pub fn write_report(
    dir: &Path,
    out: Option<&Path>,
    opts: &options::ReportOptions,
) -> Result<(PathBuf, gather::ReportData), ReportError> {
    let data = gather::gather(dir, opts)?;
    let page = html::render_html(&data);
    let path = out.map_or_else(|| default_output(dir), Path::to_path_buf);
    let werr = |source| ReportError::Write {
        path: path.clone(),
        source,
    };
    // with the permissions of any new file (`atomic`), so the lab can share the page
    crate::atomic::write_atomic(&path, page.as_bytes()).map_err(werr)?;
    Ok((path, data))
}
