//! `brdf-rig reconstruct JOB --out DIR`: recover a BRDF from a reconstruction job and write
//! `brdf.binary`, `report.json` and sphere renders. Thin: arguments become
//! `reconstruct::Settings`, the library does the work, progress goes to stderr.

use anyhow::Context;
use brdf_rig::reconstruct::carry::Carry;
use brdf_rig::reconstruct::confidence::Level;
use brdf_rig::reconstruct::core::{ModelSelection, TrialChoice};
use brdf_rig::reconstruct::fresnel::F0Rule;
use brdf_rig::reconstruct::ladder::{BasisRung, Family};
use brdf_rig::reconstruct::lambert_rung::LambertFit;
use brdf_rig::reconstruct::plausible::ThetaDShape;
use brdf_rig::reconstruct::trials::BasisFit;
use brdf_rig::reconstruct::{self, Job, Settings};
use clap::Args as ClapArgs;

use super::ranges::{Closed, Open, Unbounded, int_in, real_in};

/// Columns of the basis: 100 materials times 3 colour channels.
const MAX_COMPONENTS: usize = 300;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(ClapArgs, Debug)]
pub struct Args {
    /// The job file (TOML): mesh, COLMAP model, light images.
    pub job: PathBuf,
    /// Output folder (created): brdf.binary, report.json, sphere.exr, sphere.png.
    #[arg(long)]
    pub out: PathBuf,
    /// Random trials, the best chosen by cosine similarity with the captured images (1 to 1000).
    #[arg(long, default_value_t = 10, value_parser = int_in(1usize, 1000))]
    pub trials: usize,
    /// Sample pixels per trial (1 to 100000).
    #[arg(long, default_value_t = 80, value_parser = int_in(1usize, 100_000))]
    pub samples: usize,
    /// Fraction of the reliable pixels each trial draws, in (0, 1].
    #[arg(long, default_value_t = 0.5, value_parser = real_in(Open(0.0), Closed(1.0)))]
    pub subset: f64,
    /// Basis components, 1 to --basis-components; default: chosen by validation on held-back
    /// pixels.
    #[arg(long, value_parser = int_in(1usize, MAX_COMPONENTS))]
    pub components: Option<usize>,
    /// Ridge weight eta with --components (validation chooses it otherwise), in [0, 1e9].
    #[arg(long, default_value_t = 40.0, value_parser = real_in(Closed(0.0), Closed(1e9)))]
    pub eta: f64,
    /// Keep pixels whose |mean curvature| is at or below this quantile, in (0, 1].
    #[arg(
        long,
        default_value_t = 0.5,
        conflicts_with = "curvature_max",
        value_parser = real_in(Open(0.0), Closed(1.0))
    )]
    pub curvature_quantile: f64,
    /// Keep pixels whose |mean curvature| is at or below this (1 / mesh unit) instead, >= 0.
    #[arg(long, value_parser = real_in(Closed(0.0), Unbounded))]
    pub curvature_max: Option<f64>,
    /// Ablation: switch off assumption 1 (curvature).
    #[arg(long)]
    pub no_curvature: bool,
    /// Ablation: switch off assumption 2 (monotonicity, eq. 1).
    #[arg(long)]
    pub no_monotonicity: bool,
    /// Ablation: switch off assumption 3 (brightest pixel, n = h).
    #[arg(long)]
    pub no_brightest: bool,
    /// Materials to leave out of the basis (repeatable, or comma-separated), e.g. the one
    /// being evaluated.
    #[arg(long = "exclude", value_delimiter = ',')]
    pub exclude: Vec<String>,
    /// Folder of the neural MERL fits the basis is built from.
    #[arg(long, env = "BRDF_RIG_NBRDF_DIR")]
    pub nbrdf_dir: Option<PathBuf>,
    /// Basis cache folder, built on first use (default: $BRDF_RIG_CACHE or ~/.cache/brdf-rig).
    #[arg(long)]
    pub basis_cache: Option<PathBuf>,
    /// Pixel values at or above this are clipped (dropped), > 0; default: 1.0 for 16-bit files,
    /// the white level for camera RAW, none for EXR.
    #[arg(long, value_parser = real_in(Open(0.0), Unbounded))]
    pub saturation: Option<f64>,
    /// Basis grid stride along theta_h, theta_d, phi_d (coarser = faster, less exact), each 1
    /// to 90.
    #[arg(
        long,
        value_delimiter = ',',
        default_values_t = [1usize, 2, 2],
        value_parser = int_in(1usize, 90)
    )]
    pub basis_stride: Vec<usize>,
    /// Components kept in the basis (1 to 300: 100 materials x 3 colour channels).
    #[arg(long, default_value_t = 80, value_parser = int_in(1usize, MAX_COMPONENTS))]
    pub basis_components: usize,
    /// How the reported trial is chosen: `similarity` (the paper's eq. 3, cosine similarity with
    /// the images), `pixel-error` (lowest relative error over every observed pixel), `mean`
    /// (the mean of every trial's table) or `median` (its per-bin median).
    #[arg(long, value_parser = parse_choice, default_value = "similarity")]
    pub choose: TrialChoice,
    /// Which model to report: `auto` (the model ladder: the simplest model within noise of the
    /// best held-out image error), or one family: `lambert`, `lambert-ggx`, `basis`, `hybrid`.
    #[arg(long, value_parser = parse_model, default_value = "auto")]
    pub model: ModelSelection,
    /// Keep the fitted model where no pixel was observed, instead of shrinking it towards a
    /// Lambert + GGX fit of the same pixels (docs/reconstruction.md, plausibility).
    #[arg(long)]
    pub no_shrink: bool,
    /// What each basis fit is given: `rows` (every reliable pixel, the median of each basis
    /// row's pixels) or `samples` (the paper's: --samples pixels chosen for the basis's
    /// conditioning). docs/reconstruction.md, stage 3.
    #[arg(long, value_parser = parse_basis_fit, default_value = "rows")]
    pub basis_fit: BasisFit,
    /// Where no pixel observed a (theta_h, theta_d) cell, start from: `model` (the model's own
    /// extrapolation) or `transfer` (the model at the nearest observed theta_d of the same
    /// theta_h, carried along theta_d by the Lambert + GGX prior) or `transfer-basis` (carried
    /// by the basis's mean material). Each is kept within a factor 10 of the prior. docs/reconstruction.md, stage 6.
    #[arg(long, value_parser = parse_unobserved, default_value = "model")]
    pub unobserved: ThetaDShape,
    /// Where most of the result's rendered sphere comes from cells no pixel observed (one
    /// light by the camera), average the basis's table with Lambert + GGX's, geometrically,
    /// with Lambert + GGX's weight this strength times that share (0 to 1; 0 turns it off; 0.5
    /// before session 47). docs/reconstruction.md, stage 6.
    #[arg(long, default_value_t = 1.0, value_parser = real_in(Closed(0.0), Closed(1.0)))]
    pub hedge: f64,
    /// Where the model ladder chose the basis and a GGX peak on top of it scored within noise
    /// of it on the held-out images, average the two tables geometrically with this weight on
    /// the basis + peak (0 to 1; 0: the basis alone). docs/reconstruction.md, stage 6.
    #[arg(long, default_value_t = 0.5, value_parser = real_in(Closed(0.0), Closed(1.0)))]
    pub peak_average: f64,
    /// Study knob: where the model ladder chose the basis, average the basis rungs
    /// (components, ridge weight) the held-out images cannot tell from it into the written
    /// table (`true` or `false`; off by default: measured and not adopted, docs/evaluation.md
    /// section 1am).
    #[arg(long, default_value_t = reconstruct::core::CoreSettings::default().rung_average, action = clap::ArgAction::Set)]
    pub rung_average: bool,
    /// Carry each pixel to its basis row's centre before the written basis fit, its value
    /// times Lambert + GGX's ratio between the row's theta_d and phi_d and its own
    /// (`difference`, the default), or leave the pixels as they are (`off`). The model ladder
    /// decides on the pixels as they are either way. docs/reconstruction.md, stage 4;
    /// docs/evaluation.md sections 1s and 1ae.
    #[arg(long, value_parser = parse_carry, default_value = "difference")]
    pub carry: Carry,
    /// Which basis rung (k, eta) is written once the model ladder took the basis family:
    /// `simplest` (the simplest within noise of the best, the rule among the families),
    /// `lowest` (the lowest held-out error, the default) or `extrapolates` (of the rungs within
    /// noise of the lowest, the one that best predicts the pixels of the largest theta_d fitted
    /// to the others; a study knob, measured and not adopted: docs/materials.md, session 50).
    /// docs/reconstruction.md, stage 3.
    #[arg(long, value_parser = parse_basis_rung, default_value = "lowest")]
    pub basis_rung: BasisRung,
    /// How the reconstruction's Lambert + GGX (its ladder rung, the prior of unobserved cells,
    /// the hedge) sets Schlick's F0 where the pixels cannot tell it (one light beside the
    /// camera): `physical` (a dielectric's 0.04, raised to keep the lobe's weight at most 1,
    /// or 1 for a lobe as broad as a body's reflection; the default) or `free` (wherever the least-squares search stops, the rule before
    /// session 45). docs/reconstruction.md, stage 3; docs/evaluation.md section 1ah.
    #[arg(long = "lambert-ggx-f0", value_parser = parse_f0_rule, default_value = "physical")]
    pub lambert_ggx_f0: F0Rule,
    /// How the reconstruction's Lambert (its ladder rung, a written Lambert) fits its albedo:
    /// `median` (the pixels' reflectance's median, each weighted by cos theta_i: a pixel in a
    /// shadow the mesh does not cast moves it by one rank, not by its value; the default) or
    /// `least-squares` (the rule before session 47, and the baselines' fit).
    /// docs/reconstruction.md, stage 3; docs/evaluation.md section 1aj.
    #[arg(long = "lambert-fit", value_parser = parse_lambert_fit, default_value = "median")]
    pub lambert_fit: LambertFit,
    /// A simpler model family whose held-out error is within this fraction of the best's
    /// counts as within noise, besides one paired standard error (0 to 1; 0: the standard
    /// error alone, the rule before session 43). docs/reconstruction.md, stage 3;
    /// docs/evaluation.md 1af.
    #[arg(long, default_value_t = 0.01, value_parser = real_in(Closed(0.0), Closed(1.0)))]
    pub min_gain: f64,
    /// Study knob: deblur the written basis fit for normals off by this RMS tilt (degrees; one
    /// Van Cittert step, `reconstruct::deblur`); 0, the default, leaves it as fitted. The
    /// model ladder decides on the pixels as they are either way. docs/evaluation.md 1v.
    #[arg(long, default_value_t = 0.0, value_parser = real_in(Closed(0.0), Closed(20.0)))]
    pub deblur: f64,
    /// Study knob: where the written model is the basis's, average its grazing peak cells
    /// (theta_h below 10 degrees, theta_d 55 and above) geometrically with its value at theta_d
    /// 54 carried up by Lambert + GGX's shape, with this weight on the carried value (0 to 1;
    /// 0, the default: off). Measured, not adopted: docs/evaluation.md section 1x.
    #[arg(long, default_value_t = 0.0, value_parser = real_in(Closed(0.0), Closed(1.0)))]
    pub grazing_transfer: f64,
    /// Where the written model is the basis's, scale its peak cells (theta_h below this many
    /// degrees, fading to none at twice it) so that the light images' patch sums match, unless
    /// the images held out one at a time refute it (0 to 10; 0 turns it off).
    /// docs/reconstruction.md, stage 6; docs/evaluation.md sections 1ag and 1ai.
    #[arg(long, default_value_t = 1.5, value_parser = real_in(Closed(0.0), Closed(10.0)))]
    pub peak_energy: f64,
    /// Study knob: fit the peak's factor (`--peak-energy`) per band of theta_d, up to this many
    /// bands holding equal shares of the pixels' peak energy (0 to 8; 0 or 1: one factor, 0 by
    /// default). Measured, not adopted: docs/evaluation.md section 1an.
    #[arg(long, default_value_t = reconstruct::core::CoreSettings::default().peak_energy_bands, value_parser = int_in(0usize, 8))]
    pub peak_energy_bands: usize,
    #[command(flatten)]
    pub refine: RefineSwitch,
    /// What the refinement moves: `depth` (one displacement per vertex along its normal, the
    /// normals following from the displaced positions: a photogrammetry mesh's error is its
    /// depth noise) or `normals` (two free angles per vertex normal: also normals that are wrong
    /// independently of the positions). docs/normal-refinement.md, "Session 28".
    #[arg(long, value_enum, default_value = "depth")]
    pub refine_unknowns: RefineUnknownsArg,
    /// Study knob: leave out of the normal refinement the pixels near the boundary of two
    /// found materials whose colour is the other material's, as the fits do
    /// (`--foreign-colour-rings`). Measured and not adopted: docs/materials.md, "The colour
    /// rule in the normal refinement".
    #[arg(long)]
    pub refine_colour_rule: bool,
    /// Largest tilt the refinement may give a normal, degrees (0 to 60).
    #[arg(long, default_value_t = 20.0, value_parser = real_in(Closed(0.0), Closed(60.0)))]
    pub max_tilt: f64,
    /// Materials of the object: `one` (the paper's assumption) or `auto` (find them in the
    /// images, choose how many on held-out images, fit one BRDF each: materials/NAME.binary,
    /// materials.json, material_map.ply; docs/materials.md). Label masks in the job
    /// (`labels = ...`) fix materials where they label the object, with either: `one` then
    /// gives exactly the masks' materials, `auto` may add more.
    #[arg(long, value_enum, default_value = "one")]
    pub materials: MaterialsArg,
    /// With `--materials auto`: the largest number of materials tried (1 to 8).
    #[arg(long, default_value_t = 4, value_parser = int_in(1usize, 8))]
    pub max_materials: usize,
    /// With `--materials auto`: fit each material to every pixel of its label, those on faces
    /// across a boundary too (by default they are left out of every material's fit: they may
    /// mix two materials; docs/materials.md, "Boundary pixels").
    #[arg(long)]
    pub keep_boundary_pixels: bool,
    /// With `--materials auto`: also leave out of each material's fit the pixels of faces
    /// with a corner within this many rings of edges of the labels' boundary (0: only the
    /// faces across it; docs/materials.md, "Boundary pixels").
    #[arg(long, default_value_t = reconstruct::segment::SegmentSettings::default().boundary_rings, value_parser = int_in(0usize, 20))]
    pub boundary_rings: usize,
    /// With `--materials auto`: within this many rings of edges of the labels' boundary,
    /// leave out of a material's fit its pixels whose colour is nearer another material's
    /// (0: off; docs/materials.md, "Boundary pixels").
    #[arg(long, default_value_t = reconstruct::segment::SegmentSettings::default().foreign_colour_rings, value_parser = int_in(0usize, 20))]
    pub foreign_colour_rings: usize,
    /// Study knob, with `--materials auto`: passes that move each vertex on the labels'
    /// boundary to the neighbouring material its own pixels' colour and level are nearest (0,
    /// the default: off; measured and not adopted, docs/materials.md, "The labels' boundary
    /// moved by its own pixels").
    #[arg(long, default_value_t = reconstruct::segment::SegmentSettings::default().relabel_passes, value_parser = int_in(0usize, 10))]
    pub relabel_passes: usize,
    /// Observe every pixel: no reduction of redundant pixels (docs/reconstruction.md,
    /// "Cost at camera resolution"; slower and larger at camera resolutions).
    #[arg(long)]
    pub all_pixels: bool,
    /// Pixels kept at most per light image by the reduction.
    #[arg(long, default_value_t = 40_000, value_parser = int_in(1usize, 1_000_000_000))]
    pub pixel_budget: usize,
    /// Random seed of the trials.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Exit with status 3 (results still written) when the confidence is below this: low,
    /// medium or high. Default: never (the confidence is always printed and in report.json).
    #[arg(long, value_parser = parse_level)]
    pub min_confidence: Option<Level>,
}

/// Whether the mesh's normals are refined from the light images before the BRDF is fitted
/// (photometric stereo across views, checked on held-out images; docs/normal-refinement.md):
/// on by default since session 48 (docs/evaluation.md section 1ak), `--no-refine-normals` turns
/// it off. Shared by `reconstruct` and the benches that run it.
#[derive(ClapArgs, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RefineSwitch {
    /// Refine the mesh's normals from the light images, whatever their size (by default the
    /// refinement runs when the light images hold at most 48 megapixels in all, and is skipped
    /// with a warning above: it holds every image in memory). The object's materials are found first,
    /// whatever `--materials` says, and each gets its own reflectance table in the refinement
    /// (a warning says when several are found with `--materials one`). Writes
    /// mesh_refined.ply when the refinement is accepted.
    #[arg(long, overrides_with = "no_refine_normals")]
    pub refine_normals: bool,
    /// Fit the BRDF to the mesh's own normals, unrefined (the default before session 48;
    /// about twice as fast at the paper's scale: docs/benchmarks-reconstruct.md, "Session 48").
    #[arg(long, overrides_with = "refine_normals")]
    pub no_refine_normals: bool,
}

impl RefineSwitch {
    /// Refine? (unless `--no-refine-normals` came last)
    pub fn on(self) -> bool {
        !self.no_refine_normals
    }

    /// The pixel limit above which the refinement is skipped with a warning: the default's
    /// (`reconstruct::prepare::REFINE_AUTO_MAX_PIXELS`) unless `--refine-normals` asked for
    /// the refinement by name.
    pub fn max_pixels(self) -> Option<usize> {
        (!self.refine_normals).then_some(reconstruct::prepare::REFINE_AUTO_MAX_PIXELS)
    }
}

/// `--refine-unknowns`: what the normal refinement moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RefineUnknownsArg {
    Depth,
    Normals,
}

impl RefineUnknownsArg {
    pub fn name(self) -> &'static str {
        match self {
            Self::Depth => "depth",
            Self::Normals => "normals",
        }
    }

    /// The refinement a bench's `--refine-normals` (`refine`) with these unknowns asks for;
    /// `colour_rule`: `--refine-colour-rule`.
    pub fn settings(
        self,
        refine: bool,
        colour_rule: bool,
    ) -> Option<reconstruct::refine::RefineSettings> {
        refine.then(|| reconstruct::refine::RefineSettings {
            depth: self == Self::Depth,
            foreign_colours: colour_rule,
            ..Default::default()
        })
    }

    /// The flags as typed, for a bench's quoted command (only what is not the default:
    /// `--no-refine-normals`, `--refine-unknowns` other than depth, `--refine-colour-rule`).
    pub fn command_args(self, refine: bool, colour_rule: bool) -> String {
        let rule = if refine && colour_rule {
            " --refine-colour-rule"
        } else {
            ""
        };
        match (refine, self) {
            (false, _) => " --no-refine-normals".into(),
            (true, Self::Depth) => rule.into(),
            (true, u) => format!(" --refine-unknowns {}{rule}", u.name()),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MaterialsArg {
    One,
    Auto,
}

pub(crate) fn parse_choice(s: &str) -> Result<TrialChoice, String> {
    match s {
        "similarity" => Ok(TrialChoice::Similarity),
        "pixel-error" => Ok(TrialChoice::PixelError),
        "mean" => Ok(TrialChoice::Mean),
        "median" => Ok(TrialChoice::Median),
        _ => Err(format!(
            "{s:?}: expected similarity, pixel-error, mean or median"
        )),
    }
}

/// The word `parse_choice` reads for `c`.
pub(crate) fn choice_name(c: TrialChoice) -> &'static str {
    match c {
        TrialChoice::Similarity => "similarity",
        TrialChoice::PixelError => "pixel-error",
        TrialChoice::Mean => "mean",
        TrialChoice::Median => "median",
    }
}

pub(crate) fn parse_basis_fit(s: &str) -> Result<BasisFit, String> {
    [BasisFit::Rows, BasisFit::Samples]
        .into_iter()
        .find(|f| f.name() == s)
        .ok_or_else(|| format!("{s:?}: expected rows or samples"))
}

pub(crate) fn parse_unobserved(s: &str) -> Result<ThetaDShape, String> {
    [ThetaDShape::Model, ThetaDShape::Prior, ThetaDShape::Basis]
        .into_iter()
        .find(|u| u.name() == s)
        .ok_or_else(|| format!("{s:?}: expected model, transfer or transfer-basis"))
}

pub(crate) fn parse_carry(s: &str) -> Result<Carry, String> {
    Carry::parse(s).ok_or_else(|| format!("{s:?}: expected difference or off"))
}

pub(crate) fn parse_basis_rung(s: &str) -> Result<BasisRung, String> {
    BasisRung::parse(s).ok_or_else(|| format!("{s:?}: expected simplest, lowest or extrapolates"))
}

pub(crate) fn parse_f0_rule(s: &str) -> Result<F0Rule, String> {
    F0Rule::parse(s).ok_or_else(|| format!("{s:?}: expected physical or free"))
}

pub(crate) fn parse_lambert_fit(s: &str) -> Result<LambertFit, String> {
    LambertFit::parse(s).ok_or_else(|| format!("{s:?}: expected median or least-squares"))
}

fn parse_model(s: &str) -> Result<ModelSelection, String> {
    match s {
        "auto" => Ok(ModelSelection::Auto),
        "lambert" => Ok(ModelSelection::Only(Family::Lambert)),
        "lambert-ggx" => Ok(ModelSelection::Only(Family::LambertGgx)),
        "basis" => Ok(ModelSelection::Only(Family::Basis)),
        "hybrid" => Ok(ModelSelection::Only(Family::Hybrid)),
        _ => Err(format!(
            "{s:?}: expected auto, lambert, lambert-ggx, basis or hybrid"
        )),
    }
}

fn parse_level(s: &str) -> Result<Level, String> {
    match s {
        "low" => Ok(Level::Low),
        "medium" => Ok(Level::Medium),
        "high" => Ok(Level::High),
        _ => Err(format!("{s:?}: expected low, medium or high")),
    }
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if let Some(k) = args.components {
        anyhow::ensure!(
            k <= args.basis_components,
            "--components {k}: must be in [1, {}] (at most --basis-components)",
            args.basis_components
        );
    }
    let job = Job::from_file(&args.job)?;
    for w in &job.warnings {
        errln!("warning: {w}");
    }
    let mut settings = Settings::default();
    settings.core.trials.trials = args.trials;
    settings.core.trials.samples = args.samples;
    settings.core.trials.subset_fraction = args.subset;
    settings.core.trials.seed = args.seed;
    settings.core.fixed_k = args.components;
    settings.core.fixed_eta = args.eta;
    settings.core.choose = args.choose;
    settings.core.model = args.model;
    settings.core.plausible.shrink = !args.no_shrink;
    settings.core.trials.basis_fit = args.basis_fit;
    settings.core.plausible.theta_d_shape = args.unobserved;
    settings.core.hedge.strength = args.hedge;
    settings.core.peak_average = args.peak_average;
    settings.core.rung_average = args.rung_average;
    settings.core.carry = args.carry;
    settings.core.ladder.basis_rung = args.basis_rung;
    settings.core.ladder.lambert_ggx_f0 = args.lambert_ggx_f0;
    settings.core.ladder.lambert_fit = args.lambert_fit;
    settings.core.ladder.min_gain = args.min_gain;
    settings.core.deblur_deg = args.deblur;
    settings.core.grazing_transfer = args.grazing_transfer;
    settings.core.peak_energy_deg = args.peak_energy;
    settings.core.peak_energy_bands = args.peak_energy_bands;
    let r = &mut settings.core.reliable;
    r.use_curvature = !args.no_curvature;
    r.use_monotonicity = !args.no_monotonicity;
    r.use_brightest = !args.no_brightest;
    r.curvature_threshold = match args.curvature_max {
        Some(t) => reconstruct::reliable::CurvatureThreshold::Absolute(t),
        None => reconstruct::reliable::CurvatureThreshold::Quantile(args.curvature_quantile),
    };
    settings.basis.exclude = args.exclude;
    anyhow::ensure!(
        args.basis_stride.len() == 3,
        "--basis-stride takes three numbers (theta_h,theta_d,phi_d), got {:?}",
        args.basis_stride
    );
    if let [h, d, p] = args.basis_stride[..] {
        settings.basis.stride = brdf_rig::brdf::basis::GridStride {
            theta_h: h,
            theta_d: d,
            phi_d: p,
        };
    }
    settings.basis.basis_components = args.basis_components;
    if let Some(d) = args.nbrdf_dir {
        settings.nbrdf_dir = d;
    }
    if std::env::var_os("BRDF_RIG_BASIS_CACHE").is_some() && args.basis_cache.is_none() {
        errln!(
            "warning: BRDF_RIG_BASIS_CACHE is no longer read; the basis cache folder is \
             $BRDF_RIG_CACHE (or --basis-cache)"
        );
    }
    settings.basis_cache = args.basis_cache;
    settings.saturation = args.saturation;
    settings.observe.reduce = match (args.all_pixels, settings.observe.reduce) {
        (false, Some(r)) => Some(reconstruct::reduce::Reduction {
            budget: args.pixel_budget,
            ..r
        }),
        _ => None,
    };
    settings.refine_max_pixels = args.refine.max_pixels();
    if args.refine.on() {
        settings.refine = Some(reconstruct::refine::RefineSettings {
            max_tilt_deg: args.max_tilt,
            depth: args.refine_unknowns == RefineUnknownsArg::Depth,
            foreign_colours: args.refine_colour_rule,
            ..Default::default()
        });
    }
    if args.materials == MaterialsArg::Auto {
        settings.materials = Some(reconstruct::segment::SegmentSettings {
            max_materials: args.max_materials,
            fit_interior_only: !args.keep_boundary_pixels,
            boundary_rings: args.boundary_rings,
            foreign_colour_rings: args.foreign_colour_rings,
            relabel_passes: args.relabel_passes,
            ..Default::default()
        });
    }
    let started = std::time::Instant::now();
    let mut progress = |stage: &str| {
        errln!("[{:7.2} s] {stage}", started.elapsed().as_secs_f64());
    };
    let output = reconstruct::reconstruct(&job, &settings, &mut progress)
        .with_context(|| format!("reconstructing from {}", args.job.display()))?;
    reconstruct::output::write(&args.out, &output)
        .with_context(|| format!("writing results to {}", args.out.display()))?;
    for w in &output.report.warnings {
        errln!("warning: {w}");
    }
    let model = &output.report.model;
    errln!(
        "done in {:.2} s: {}{}; wrote {}",
        started.elapsed().as_secs_f64(),
        model.family,
        model.k.map_or(String::new(), |k| format!(" (k = {k})")),
        args.out.display()
    );
    errln!("model: {}", model.reason);
    if let Some(m) = &output.report.materials {
        errln!("materials: {} ({})", m.count, m.reason);
        for e in &m.materials {
            let given = e
                .mask_label
                .map_or(String::new(), |l| format!(" (mask label {l})"));
            let boundary = if e.boundary_pixels > 0 {
                format!(
                    " ({} on faces across a boundary or of another material's colour near it, left out of its fit)",
                    e.boundary_pixels
                )
            } else {
                String::new()
            };
            errln!(
                "  {}{given}: {} pixels{boundary}, {}, confidence {}; wrote {}",
                e.name,
                e.observed_pixels,
                e.model,
                e.confidence,
                args.out.join(&e.file).display()
            );
        }
    }
    if let Some(r) = &output.report.normals {
        errln!(
            "normals: {} ({}; mean tilt {:.2} deg, largest {:.2} deg over {} vertices{})",
            if r.accepted { "refined" } else { "kept" },
            r.reason,
            r.mean_tilt_deg,
            r.max_tilt_deg,
            r.vertices_refined,
            r.foreign_colour_text()
                .map_or(String::new(), |t| format!("; {t}"))
        );
    }
    let p = &output.report.plausibility;
    errln!(
        "plausibility: {:.0} % of the table from the prior, {} invalid bins replaced, largest \
         albedo {:.3} (before {:.3})",
        100.0 * p.prior_share,
        p.invalid_bins,
        p.max_albedo_after,
        p.max_albedo_before
    );
    if let Some(h) = &p.hedge {
        errln!("hedge: {}", h.describe());
    }
    if let Some(w) = p.grazing_transfer {
        errln!(
            "grazing peak: carried above theta_d 54 deg by Lambert + GGX's shape, weight {w:.2} \
             (--grazing-transfer)"
        );
    }
    if let Some(e) = &p.peak_energy {
        errln!("peak energy: {} (--peak-energy)", e.describe());
    }
    let confidence = &output.report.confidence;
    errln!("confidence: {}", confidence.level);
    for r in &confidence.reasons {
        errln!("  {r}");
    }
    if let Some(min) = args.min_confidence
        && confidence.level < min
    {
        errln!(
            "error: confidence {} is below --min-confidence {min}; the results are written but \
             should not be trusted",
            confidence.level
        );
        return Ok(ExitCode::from(3));
    }
    Ok(ExitCode::SUCCESS)
}
