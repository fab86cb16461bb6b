//! Reading back the report sections whose types are declared, with `Serialize` only, in
//! `ladder.rs` and `refine.rs`: `Deserialize` for them, so `report_file::Report` embeds those
//! types as they are built and readers get them typed.
//!
//! Each impl goes through serde's remote derive: a mirror of the type's fields and variants,
//! with the same serde attributes. The mirror builds the real type field by field, so a field
//! added to or removed from the original is a compile error here, never a silent misread; a
//! variant added to one of the enums is one too ([`every_variant_is_mirrored`]).
//! When `ladder.rs` and `refine.rs` derive `Deserialize` themselves, this file goes (the two
//! impls would then conflict, which the compiler says).
//!
//! Pure: no I/O.

use super::fresnel::F0Rule;
use super::ladder::{
    BasisRung, ChoiceRule, Family, FoldScheme, HeldOutMetric, Ladder, LadderSettings, Rung,
};
use super::lambert_rung::LambertFit;
use super::refine::{IterationReport, RefineReport, RefineSettings, StartReport, TableBins};
use serde::{Deserialize, Deserializer};

/// `impl Deserialize for $ty` through its remote mirror `$mirror`.
macro_rules! through_mirror {
    ($($ty:ty => $mirror:ident),* $(,)?) => {$(
        impl<'de> Deserialize<'de> for $ty {
            fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                $mirror::deserialize(d)
            }
        }
    )*};
}

through_mirror! {
    Family => FamilyMirror,
    HeldOutMetric => HeldOutMetricMirror,
    ChoiceRule => ChoiceRuleMirror,
    LadderSettings => LadderSettingsMirror,
    FoldScheme => FoldSchemeMirror,
    Rung => RungMirror,
    Ladder => LadderMirror,
    RefineSettings => RefineSettingsMirror,
    IterationReport => IterationReportMirror,
    StartReport => StartReportMirror,
    RefineReport => RefineReportMirror,
    TableBins => TableBinsMirror,
}

/// Does nothing at run time: its exhaustive matches make a variant added to a mirrored enum a
/// compile error here (serde's remote derive would only fail to read it), so its mirror below
/// gets the variant too.
pub fn every_variant_is_mirrored(f: Family, m: HeldOutMetric, r: ChoiceRule, s: FoldScheme) {
    match f {
        Family::Lambert | Family::LambertGgx | Family::Basis | Family::Hybrid => {}
    }
    match m {
        HeldOutMetric::Linear
        | HeldOutMetric::Log
        | HeldOutMetric::Both
        | HeldOutMetric::Pareto
        | HeldOutMetric::Patches
        | HeldOutMetric::ParetoPatches
        | HeldOutMetric::Front => {}
    }
    match r {
        ChoiceRule::OneStandardError | ChoiceRule::Paired => {}
    }
    match s {
        FoldScheme::Images { .. } | FoldScheme::Blocks { .. } => {}
    }
}

#[derive(Deserialize)]
#[serde(remote = "Family", rename_all = "kebab-case")]
enum FamilyMirror {
    Lambert,
    LambertGgx,
    Basis,
    Hybrid,
}

#[derive(Deserialize)]
#[serde(remote = "HeldOutMetric", rename_all = "kebab-case")]
enum HeldOutMetricMirror {
    Linear,
    Log,
    Both,
    Pareto,
    Patches,
    ParetoPatches,
    Front,
}

#[derive(Deserialize)]
#[serde(remote = "ChoiceRule", rename_all = "kebab-case")]
enum ChoiceRuleMirror {
    OneStandardError,
    Paired,
}

#[derive(Deserialize)]
#[serde(remote = "LadderSettings")]
struct LadderSettingsMirror {
    folds: usize,
    min_images_for_image_folds: usize,
    block_px: Option<usize>,
    analytic_max_pixels: usize,
    analytic: bool,
    analytic_on_all_pixels: bool,
    hybrid: bool,
    rule: ChoiceRule,
    metric: HeldOutMetric,
    #[serde(default)]
    patch_px: Option<usize>,
    max_trial_disagreement: f64,
    #[serde(default)]
    min_gain: f64,
    #[serde(default)]
    analytic_margin: f64,
    /// Absent in reports written before it existed (the simplest basis rung within noise).
    #[serde(default)]
    basis_rung: BasisRung,
    /// Absent in reports written before it existed (the free fit's `F0`).
    #[serde(default)]
    lambert_ggx_f0: F0Rule,
    /// Absent in reports written before it existed (least squares).
    #[serde(default)]
    lambert_fit: LambertFit,
}

#[derive(Deserialize)]
#[serde(remote = "FoldScheme", tag = "kind", rename_all = "kebab-case")]
enum FoldSchemeMirror {
    Images { folds: usize },
    Blocks { folds: usize, block_px: usize },
}

#[derive(Deserialize)]
#[serde(remote = "Rung")]
struct RungMirror {
    family: Family,
    k: Option<usize>,
    eta: Option<f64>,
    parameters: usize,
    fold_errors: Vec<Option<f64>>,
    error: Option<f64>,
    standard_error: Option<f64>,
    fold_errors_log: Vec<Option<f64>>,
    error_log: Option<f64>,
    standard_error_log: Option<f64>,
    #[serde(default)]
    fold_errors_patch: Vec<Option<f64>>,
    #[serde(default)]
    error_patch: Option<f64>,
    #[serde(default)]
    standard_error_patch: Option<f64>,
    image_errors: Vec<Option<f64>>,
    #[serde(default)]
    extrapolation_error_log: Option<f64>,
}

#[derive(Deserialize)]
#[serde(remote = "Ladder")]
struct LadderMirror {
    scheme: FoldScheme,
    held_out_pixels: usize,
    rungs: Vec<Rung>,
    chosen: usize,
    reason: String,
}

#[derive(Deserialize)]
#[serde(remote = "RefineSettings")]
struct RefineSettingsMirror {
    max_iterations: usize,
    sweeps: usize,
    cg_iterations: usize,
    cg_tolerance: f64,
    step: f64,
    max_tilt_deg: f64,
    residual_sigma: f64,
    smooth_deg: f64,
    /// Absent in reports written before it existed (the offsets were smoothed then).
    #[serde(default)]
    smooth_normals: f64,
    anchor_deg: f64,
    min_pixels_per_vertex: usize,
    hold_out_every: usize,
    min_gain: f64,
    max_fit_pixels: usize,
    fit_min_cos: f64,
    move_min_cos: f64,
    max_pixels_per_face: usize,
    final_alternations: usize,
    /// Absent in reports written before it existed (no correction passes then).
    #[serde(default)]
    table_passes: usize,
    /// Absent in reports written before it existed (the table was 32 x 16 x 8 then).
    #[serde(default = "table_bins_before_session_40")]
    table_bins: TableBins,
    /// Absent in reports written before it existed (the one table above for every scene).
    #[serde(default = "table_bins_before_session_40")]
    sparse_table_bins: TableBins,
    /// Absent in reports written before it existed (no choice: 0).
    #[serde(default)]
    min_samples_per_cell: f64,
    /// Absent in reports written before it existed (the mesh's normals were the only start).
    #[serde(default)]
    start_smoothing: Vec<usize>,
    /// Absent in reports written before it existed (every surface pixel entered).
    #[serde(default)]
    edge_margin_px: usize,
    /// Absent in reports written before it existed (every pixel entered).
    #[serde(default)]
    foreign_colours: bool,
    /// Absent in reports written before it existed (the normals were the unknowns).
    #[serde(default)]
    depth: bool,
    /// Absent in reports written before it existed (unused without `depth`).
    #[serde(default)]
    depth_sigma_edges: f64,
    /// Absent in reports written before it existed (unused without `depth`).
    #[serde(default)]
    depth_sweeps: usize,
    /// Absent in reports written before it existed (unused without `depth`).
    #[serde(default)]
    depth_cg_iterations: usize,
}

#[derive(Deserialize)]
#[serde(remote = "TableBins")]
struct TableBinsMirror {
    theta_h: usize,
    theta_d: usize,
    phi_d: usize,
}

/// The refinement's table in the reports written before it was a setting.
fn table_bins_before_session_40() -> TableBins {
    TableBins {
        theta_h: 32,
        theta_d: 16,
        phi_d: 8,
    }
}

#[derive(Deserialize)]
#[serde(remote = "StartReport")]
struct StartReportMirror {
    smoothing_iterations: usize,
    train_error: f64,
    held_out_error: f64,
}

#[derive(Deserialize)]
#[serde(remote = "IterationReport")]
struct IterationReportMirror {
    iteration: usize,
    mean_tilt_deg: f64,
    max_tilt_deg: f64,
    train_error: f64,
    held_out_error: f64,
    seconds: f64,
}

#[derive(Deserialize)]
#[serde(remote = "RefineReport")]
struct RefineReportMirror {
    accepted: bool,
    reason: String,
    settings: RefineSettings,
    pixels: usize,
    pixels_offered: usize,
    held_out_images: Vec<usize>,
    vertices_refined: usize,
    /// Absent in reports written before starts were chosen.
    #[serde(default)]
    starts: Vec<StartReport>,
    #[serde(default)]
    chosen_start_smoothing: usize,
    iterations: Vec<IterationReport>,
    chosen_iterations: usize,
    mean_tilt_deg: f64,
    max_tilt_deg: f64,
    seconds: f64,
    /// Absent in reports written before a table per material: one table.
    #[serde(default = "one")]
    materials: usize,
    /// Absent in reports written before the table's shape was chosen: 32 x 16 x 8, unmeasured.
    #[serde(default = "table_bins_before_session_40")]
    table_bins: TableBins,
    #[serde(default)]
    table_samples_per_cell: Option<f64>,
    /// Absent in reports written before the colour rule reached the refinement: none.
    #[serde(default)]
    foreign_colour_pixels: usize,
}

fn one() -> usize {
    1
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    /// What the ladder's and the refinement's own `Serialize` writes reads back as the same
    /// value: the mirrors carry the same names and attributes.
    #[test]
    fn written_sections_read_back_equal() {
        fn round_trip<
            T: serde::Serialize + for<'de> Deserialize<'de> + PartialEq + std::fmt::Debug,
        >(
            x: &T,
        ) {
            let json = serde_json::to_string(x).unwrap();
            assert_eq!(&serde_json::from_str::<T>(&json).unwrap(), x, "{json}");
        }
        let rung = |family, k| Rung {
            family,
            k,
            eta: k.map(|_| 40.0),
            parameters: 8,
            fold_errors: vec![Some(0.2), None],
            error: Some(0.2),
            standard_error: None,
            fold_errors_log: vec![Some(0.1), None],
            error_log: Some(0.1),
            standard_error_log: Some(0.01),
            fold_errors_patch: Vec::new(),
            error_patch: None,
            standard_error_patch: None,
            image_errors: vec![None, Some(0.3)],
            extrapolation_error_log: k.map(|_| 0.15),
        };
        for scheme in [
            FoldScheme::Images { folds: 5 },
            FoldScheme::Blocks {
                folds: 3,
                block_px: 16,
            },
        ] {
            round_trip(&Ladder {
                scheme,
                held_out_pixels: 100,
                rungs: vec![
                    rung(Family::Lambert, None),
                    rung(Family::LambertGgx, None),
                    rung(Family::Basis, Some(6)),
                    rung(Family::Hybrid, Some(4)),
                ],
                chosen: 2,
                reason: "within noise".into(),
            });
        }
        round_trip(&LadderSettings::default());
        round_trip(&LadderSettings {
            rule: ChoiceRule::OneStandardError,
            metric: HeldOutMetric::Linear,
            analytic_margin: 0.25,
            basis_rung: BasisRung::Simplest,
            lambert_ggx_f0: F0Rule::Free,
            lambert_fit: LambertFit::LeastSquares,
            ..LadderSettings::default()
        });
        round_trip(&RefineReport {
            accepted: true,
            reason: "lowered the held-out error".into(),
            settings: RefineSettings::default(),
            pixels: 10,
            pixels_offered: 20,
            held_out_images: vec![1, 5],
            vertices_refined: 3,
            starts: vec![StartReport {
                smoothing_iterations: 4,
                train_error: 0.2,
                held_out_error: 0.3,
            }],
            chosen_start_smoothing: 4,
            iterations: vec![IterationReport {
                iteration: 0,
                mean_tilt_deg: 0.0,
                max_tilt_deg: 0.0,
                train_error: 0.3,
                held_out_error: 0.4,
                seconds: 1.0,
            }],
            chosen_iterations: 1,
            mean_tilt_deg: 1.5,
            max_tilt_deg: 9.0,
            seconds: 2.0,
            materials: 2,
            table_bins: table_bins_before_session_40(),
            table_samples_per_cell: Some(1.3),
            foreign_colour_pixels: 7,
        });
    }

    /// Settings written before session 42 read back as those runs were made: the simplest
    /// basis rung within noise, and the pixels not carried (today's defaults are the others);
    /// before session 47, the Lambert rung by least squares.
    #[test]
    fn older_settings_read_back_with_the_simplest_rung_and_no_carry() {
        use crate::reconstruct::carry::Carry;
        use crate::reconstruct::core::CoreSettings;
        let now = CoreSettings::default();
        assert_eq!(
            (now.ladder.basis_rung, now.carry, now.ladder.lambert_fit),
            (BasisRung::Lowest, Carry::Difference, LambertFit::Median)
        );
        let mut json = serde_json::to_value(&now).unwrap();
        let o = json.as_object_mut().unwrap();
        o.remove("carry");
        let ladder = o["ladder"].as_object_mut().unwrap();
        ladder.remove("basis_rung");
        ladder.remove("lambert_fit");
        let old: CoreSettings = serde_json::from_value(json).unwrap();
        assert_eq!(
            (old.ladder.basis_rung, old.carry, old.ladder.lambert_fit),
            (BasisRung::Simplest, Carry::Off, LambertFit::LeastSquares)
        );
    }

    /// A report written before the table's shape was a choice reads back with the one shape
    /// every refinement used then, and no density.
    #[test]
    fn an_older_refinement_reads_back_with_the_old_table() {
        let mut report = RefineReport {
            accepted: false,
            reason: "kept".into(),
            settings: RefineSettings::default(),
            pixels: 1,
            pixels_offered: 1,
            held_out_images: vec![],
            vertices_refined: 0,
            starts: vec![],
            chosen_start_smoothing: 0,
            iterations: vec![],
            chosen_iterations: 0,
            mean_tilt_deg: 0.0,
            max_tilt_deg: 0.0,
            seconds: 0.0,
            materials: 1,
            table_bins: RefineSettings::default().table_bins,
            table_samples_per_cell: Some(2.5),
            foreign_colour_pixels: 0,
        };
        let mut json = serde_json::to_value(&report).unwrap();
        let o = json.as_object_mut().unwrap();
        o.remove("table_bins");
        o.remove("table_samples_per_cell");
        let settings = o["settings"].as_object_mut().unwrap();
        for k in ["table_bins", "sparse_table_bins", "min_samples_per_cell"] {
            settings.remove(k);
        }
        let old: RefineReport = serde_json::from_value(json).unwrap();
        let before = table_bins_before_session_40();
        assert_eq!((old.table_bins, old.table_samples_per_cell), (before, None));
        assert_eq!(old.settings.table_bins, before);
        assert_eq!(old.settings.sparse_table_bins, before);
        report.table_bins = before;
        report.table_samples_per_cell = None;
        report.settings.table_bins = before;
        report.settings.sparse_table_bins = before;
        report.settings.min_samples_per_cell = 0.0;
        assert_eq!(old, report);
    }
}
