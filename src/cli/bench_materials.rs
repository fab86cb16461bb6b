//! `brdf-rig bench materials`: objects of several materials (issue #17), written as
//! materials.md and materials.json under `--out`. Thin over `eval::bench::materials`: parses
//! the arguments into its options and prints.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::bail;
use clap::Args;

use super::bench_accuracy::EvalCommon;
use super::ranges::int_in;
use brdf_rig::eval::bench::materials::{self, MaterialsBenchOptions};
use brdf_rig::reconstruct::segment::SegmentSettings;

#[derive(Args, Debug)]
pub struct BenchMaterialsArgs {
    #[command(flatten)]
    pub common: EvalCommon,
    /// Objects, comma-separated, each its materials joined by `+` (neural MERL fit names; one
    /// name: a one-material object, whose count must stay 1).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "green-latex+pink-fabric,alum-bronze+blue-acrylic,fruitwood-241+pink-fabric2+green-latex,pink-fabric"
    )]
    pub objects: Vec<String>,
    /// Seeds per object (each moves the SfM-like noise and the trials' pixel draws).
    #[arg(long, default_value_t = 1, value_parser = int_in(1u64, 1000))]
    pub seeds: u64,
    /// Light rigs: spread (many theta_d) and/or one-light (fixed beside the camera).
    #[arg(long, value_delimiter = ',', default_value = "spread")]
    pub rigs: Vec<String>,
    /// The one-light rig's angle from the optical axis, degrees.
    #[arg(long, default_value_t = 30.0)]
    pub one_light_deg: f64,
    /// The largest number of materials the segmentation tries (1 to 8).
    #[arg(long, default_value_t = 4, value_parser = int_in(1usize, 8))]
    pub max_materials: usize,
    /// Fit each found material to every pixel of its label, the boundary faces' too
    /// (`reconstruct --keep-boundary-pixels`; by default they are left out).
    #[arg(long)]
    pub keep_boundary_pixels: bool,
    /// Also leave out the pixels of faces within this many rings of edges of the labels'
    /// boundary (`reconstruct --boundary-rings`; default: the library's).
    #[arg(long, value_parser = int_in(0usize, 20))]
    pub boundary_rings: Option<usize>,
    /// Within this many rings of the labels' boundary, leave out the pixels whose colour is
    /// nearer another material's (`reconstruct --foreign-colour-rings`; default: the
    /// library's).
    #[arg(long, value_parser = int_in(0usize, 20))]
    pub foreign_colour_rings: Option<usize>,
    /// Study knob: passes moving the labels' boundary by each boundary vertex's own pixels
    /// (`reconstruct --relabel-passes`; default: the library's, 0).
    #[arg(long, value_parser = int_in(0usize, 10))]
    pub relabel_passes: Option<usize>,
    /// Refine the SfM-like mesh's normals from the images before finding the materials, as
    /// `reconstruct` does by default (`--no-refine-normals`: not); the baselines are fitted to
    /// the unrefined pixels.
    #[command(flatten)]
    pub refine: super::reconstruct::RefineSwitch,
    /// When the normals are refined: what the refinement moves (`reconstruct --refine-unknowns`).
    #[arg(long, value_enum, default_value = "depth")]
    pub refine_unknowns: super::reconstruct::RefineUnknownsArg,
    /// Study knob: leave out of the normal refinement the pixels of another material's colour
    /// near the labels' boundary (`reconstruct --refine-colour-rule`).
    #[arg(long)]
    pub refine_colour_rule: bool,
    /// Time each object's two reconstructions (its materials, one material) this many times,
    /// in turn, and keep the least time of each: the time ratio of one run moves by 10-20 %
    /// with what else the machine does.
    #[arg(long, default_value_t = 1, value_parser = int_in(1usize, 20))]
    pub time_repeats: usize,
    /// Also time the whole `reconstruct` a user runs on each object, with `--materials auto`
    /// and with one material (the basis from the cache, the job from disk, every output file
    /// written), beside the cores' times; as many times as `--time-repeats`, the least of each.
    #[arg(long)]
    pub time_command: bool,
    /// Output folder for materials.md and materials.json.
    #[arg(long, default_value = "docs/eval/materials")]
    pub out: PathBuf,
}

pub fn run(a: BenchMaterialsArgs) -> anyhow::Result<ExitCode> {
    let scene = a.common.scene_options()?;
    let rigs = super::bench_accuracy::parse_rigs(&a.rigs, a.one_light_deg)?;
    let objects: Vec<Vec<String>> = a
        .objects
        .iter()
        .map(|o| o.split('+').map(|m| m.trim().to_string()).collect())
        .collect();
    if objects.iter().flatten().any(|m| m.is_empty()) {
        bail!("--objects: an empty material name (write e.g. green-latex+pink-fabric)");
    }
    let command = format!(
        "cargo run --release -- bench materials --objects {} {} --seeds {} --rigs {} --one-light-deg {} --max-materials {}{}{}{}{}{}{}{} --out {}",
        a.objects.join(","),
        a.common.command_args(),
        a.seeds,
        a.rigs.join(","),
        a.one_light_deg,
        a.max_materials,
        if a.keep_boundary_pixels {
            " --keep-boundary-pixels"
        } else {
            ""
        },
        a.boundary_rings
            .map(|r| format!(" --boundary-rings {r}"))
            .unwrap_or_default(),
        a.foreign_colour_rings
            .map(|r| format!(" --foreign-colour-rings {r}"))
            .unwrap_or_default(),
        a.relabel_passes
            .map(|r| format!(" --relabel-passes {r}"))
            .unwrap_or_default(),
        a.refine_unknowns
            .command_args(a.refine.on(), a.refine_colour_rule),
        if a.time_repeats > 1 {
            format!(" --time-repeats {}", a.time_repeats)
        } else {
            String::new()
        },
        if a.time_command {
            " --time-command"
        } else {
            ""
        },
        a.out.display()
    );
    let options = MaterialsBenchOptions {
        scene,
        views: a.common.views,
        objects,
        seeds: a.seeds,
        rigs,
        max_materials: a.max_materials,
        keep_boundary_pixels: a.keep_boundary_pixels,
        boundary_rings: a
            .boundary_rings
            .unwrap_or(SegmentSettings::default().boundary_rings),
        foreign_colour_rings: a
            .foreign_colour_rings
            .unwrap_or(SegmentSettings::default().foreign_colour_rings),
        relabel_passes: a
            .relabel_passes
            .unwrap_or(SegmentSettings::default().relabel_passes),
        refine: a
            .refine_unknowns
            .settings(a.refine.on(), a.refine_colour_rule),
        time_repeats: a.time_repeats,
        time_command: a.time_command,
        out: a.out.clone(),
        command,
    };
    let md = materials::run(&options, &mut super::bench_notes::printer())?;
    outln!("{md}");
    errln!("wrote {}/materials.md and materials.json", a.out.display());
    Ok(ExitCode::SUCCESS)
}
