//! `brdf-rig bench materials`: the multi-material study (`eval::materials`), written as
//! materials.md and materials.json under `--out` after every object, so a long run cut short
//! still reports.

use std::path::PathBuf;
use std::time::Instant;

use super::accuracy::SceneOptions;
use super::{BenchError, Note, create_dir, write_file};
use crate::brdf::basis::BasisSettings;
use crate::eval::accuracy::Rig;
use crate::eval::materials::{self, MaterialsSpec, ObjectResult};
use crate::reconstruct::segment::SegmentSettings;

/// The options of `bench materials`.
#[derive(Clone, Debug)]
pub struct MaterialsBenchOptions {
    pub scene: SceneOptions,
    pub views: usize,
    /// Objects, each a list of material names.
    pub objects: Vec<Vec<String>>,
    pub seeds: u64,
    pub rigs: Vec<Rig>,
    pub max_materials: usize,
    /// Fit each material to the boundary faces' pixels too (`SegmentSettings::fit_interior_only`
    /// off).
    pub keep_boundary_pixels: bool,
    /// Rings of edges around the labels' boundary whose faces' pixels are left out of each
    /// material's fit too (`SegmentSettings::boundary_rings`).
    pub boundary_rings: usize,
    /// Rings of the labels' boundary within which pixels of another material's colour are
    /// left out (`SegmentSettings::foreign_colour_rings`).
    pub foreign_colour_rings: usize,
    /// Passes moving the labels' boundary by its vertices' own pixels
    /// (`SegmentSettings::relabel_passes`).
    pub relabel_passes: usize,
    /// Refine the normals from the images first (`reconstruct --refine-normals`).
    pub refine: Option<crate::reconstruct::refine::RefineSettings>,
    /// Times each object's reconstructions this many times, keeping the least
    /// (`MaterialsSpec::time_repeats`).
    pub time_repeats: usize,
    /// Also time the whole commands (`MaterialsSpec::time_command`).
    pub time_command: bool,
    /// Folder of materials.md and materials.json.
    pub out: PathBuf,
    /// The command as typed, quoted by the page.
    pub command: String,
}

/// Runs the study (see the module header); returns the page.
pub fn run(
    o: &MaterialsBenchOptions,
    note: &mut dyn FnMut(Note<'_>),
) -> Result<String, BenchError> {
    if o.views == 0 || o.objects.is_empty() {
        return Err(BenchError::Invalid(
            "--views must be at least 1 and --objects must name at least one object".into(),
        ));
    }
    let c = o.scene.resolve()?;
    for m in o.objects.iter().flatten() {
        if !c.materials.iter().any(|(n, _)| n == m) {
            return Err(BenchError::Invalid(format!(
                "--objects: {m:?} is not among the neural MERL fits"
            )));
        }
    }
    let stride = o.scene.stride;
    let spec = MaterialsSpec {
        objects: o.objects.clone(),
        mesh_names: c.meshes.iter().map(|(n, _)| n.clone()).collect(),
        meshes: c.meshes,
        views: o.views,
        width: o.scene.width,
        height: o.scene.height,
        basis: BasisSettings {
            stride,
            basis_components: o.scene.basis_components,
            exclude: Vec::new(),
        },
        core: c.core,
        segment: SegmentSettings {
            max_materials: o.max_materials,
            fit_interior_only: !o.keep_boundary_pixels,
            boundary_rings: o.boundary_rings,
            foreign_colour_rings: o.foreign_colour_rings,
            relabel_passes: o.relabel_passes,
            ..SegmentSettings::default()
        },
        seeds: o.seeds.max(1),
        rigs: o.rigs.clone(),
        bin_step: o.scene.bin_step,
        refine: o.refine.clone(),
        time_repeats: o.time_repeats.max(1),
        time_command: o.time_command,
        nbrdf_dir: o.scene.nbrdf_dir.clone(),
    };
    let machine = crate::eval::host::machine();
    create_dir(&o.out)?;
    let start = Instant::now();
    let write = |results: &[ObjectResult], secs: f64| -> Result<(), BenchError> {
        let mut md = materials::markdown(&spec, results, &o.command, &machine);
        md += &format!("\nTotal wall time: {secs:.0} s.\n");
        write_file(&o.out.join("materials.md"), md)?;
        let json = serde_json::json!({
            "note": "ground truth: neural fits of the MERL materials (Sztrajman et al. 2021), smooth approximations, not measured MERL data",
            "command": o.command,
            "machine": machine,
            "spec": spec,
            "objects": results,
            "seconds": secs,
        });
        write_file(
            &o.out.join("materials.json"),
            serde_json::to_string_pretty(&json)?,
        )
    };
    let mut done = Vec::new();
    let mut write_err = None;
    let note = std::cell::RefCell::new(note);
    let results = materials::run(
        &spec,
        &c.materials,
        &c.cache,
        c.scratch.path(),
        &mut |line| (note.borrow_mut())(Note::Step(line)),
        &mut |r| {
            done.push(r.clone());
            if let Err(e) = write(&done, start.elapsed().as_secs_f64()) {
                write_err = Some(e);
            }
        },
    )
    .map_err(|e| BenchError::step("running the materials study", e))?;
    if let Some(e) = write_err {
        return Err(e);
    }
    write(&results, start.elapsed().as_secs_f64())?;
    Ok(materials::markdown(&spec, &results, &o.command, &machine))
}
