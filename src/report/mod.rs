//! Reports: the paper's in-plane BRDF plot, SVG charts (plotters) and a self-contained HTML
//! page summarising a capture session or a reconstruction.
//!
//! `inplane` and `charts` are pure (data in, SVG strings out). `html` gathers what a folder
//! holds (tolerantly: a missing piece is reported as "not available" with the reason) and
//! renders the page; only `html::gather` and [`write_report`] touch files.

pub mod charts;
pub mod inplane;
