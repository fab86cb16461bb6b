//! The whole reconstruction of a job: load its files, rasterise and observe every light image,
//! build (or read from the cache) the basis, then run the pure core. The only part of
//! `reconstruct` besides `output` that touches files; every error names the file and the field.

use super::compare::{Comparison, compare_image};
use super::core::{CoreError, CoreOutput, CoreSettings, reconstruct_observations};
use super::job::{Job, JobError};
use super::nielsen::{NielsenPrior, NielsenSettings};
use super::observe::{
    DropCounts, Observation, ObserveSettings, SurfacePixel, ViewInput, observe_view,
};
use super::refine::{
    MeshNormals, RefinePixel, RefineReport, RefineSettings, refine_normals, seen_vertices,
};
use crate::brdf::basis::{Basis, BasisSettings};
use crate::brdf::basis_cache::{self, BasisCacheError, CacheStatus};
use crate::brdf::merl::MerlTable;
use crate::brdf::nbrdf::{self, NbrdfError};
use crate::geometry::bvh::Bvh;
use crate::geometry::camera::{Intrinsics, Pose};
use crate::geometry::colmap::{ColmapError, read_model};
use crate::geometry::curvature::principal_curvatures;
use crate::geometry::mesh::{Mesh, MeshReport};
use crate::geometry::mesh_io::{MeshIoError, load_mesh};
use crate::geometry::raster::{GBuffer, rasterise};
use crate::geometry::shadow::shadow_mask;
use crate::imageio::{self, ImageIoError};
use crate::render::image::LinearImage;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Everything that steers a reconstruction.
#[derive(Clone, Debug)]
pub struct Settings {
    pub observe: ObserveSettings,
    pub core: CoreSettings,
    pub nielsen: NielsenSettings,
    pub basis: BasisSettings,
    /// Neural MERL fits the basis is built from.
    pub nbrdf_dir: PathBuf,
    /// Basis cache folder; `None` = `basis_cache::default_cache_dir()`.
    pub basis_cache: Option<PathBuf>,
    /// 16-bit PNG/TIFF: a stored `q` is radiance `q / 65535 * png_scale`; camera RAW: times
    /// `png_scale` (the white level reads 1 in green before it).
    pub png_scale: f32,
    /// Clip level; `None` = what the file says (`imageio::Samples::clip_level`): `png_scale`
    /// for 16-bit files (the largest storable value), the white level for RAW, none for EXR
    /// and float TIFF.
    pub saturation: Option<f64>,
    /// Refine the mesh's normals from the images first (`reconstruct::refine`); `None` = off.
    pub refine: Option<RefineSettings>,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            observe: ObserveSettings::default(),
            core: CoreSettings::default(),
            nielsen: NielsenSettings::default(),
            basis: BasisSettings::default(),
            nbrdf_dir: nbrdf::default_dir(),
            basis_cache: None,
            png_scale: 1.0,
            saturation: None,
            refine: None,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ReconstructError {
    #[error(transparent)]
    Job(#[from] JobError),
    #[error("job {job}: `mesh`: {source}")]
    Mesh { job: PathBuf, source: MeshIoError },
    #[error("job {job}: `cameras`: {source}")]
    Cameras { job: PathBuf, source: ColmapError },
    #[error(
        "job {job}: `light_image[{index}].camera`: no image named {name:?} in the COLMAP model {cameras} (it has {known})"
    )]
    UnknownCamera {
        job: PathBuf,
        index: usize,
        name: String,
        cameras: PathBuf,
        known: String,
    },
    #[error("job {job}: `light_image[{index}].file`: {source}")]
    Image {
        job: PathBuf,
        index: usize,
        source: ImageIoError,
    },
    #[error(
        "job {job}: `light_image[{index}]`: {path} is {got_w}x{got_h} but its COLMAP camera {camera:?} is {want_w}x{want_h}"
    )]
    SizeMismatch {
        job: PathBuf,
        index: usize,
        path: PathBuf,
        camera: String,
        got_w: usize,
        got_h: usize,
        want_w: usize,
        want_h: usize,
    },
    #[error("job {job}: `light_image[{index}].mask`: {path}: {message}")]
    Mask {
        job: PathBuf,
        index: usize,
        path: PathBuf,
        message: String,
    },
    #[error(
        "job {job}: no usable pixel in any light image (mesh seen on {covered} pixels; dropped: {drops:?}); check the light directions, masks and exposure"
    )]
    NoLitPixels {
        job: PathBuf,
        covered: usize,
        drops: DropCounts,
    },
    #[error("loading the neural MERL fits for the basis: {0}")]
    Nbrdf(#[from] NbrdfError),
    #[error("basis: {0}")]
    Basis(#[from] BasisCacheError),
    #[error("job {job}: {source}")]
    Core { job: PathBuf, source: CoreError },
}

/// One light image, loaded and checked.
pub struct View {
    pub index: usize,
    pub file: PathBuf,
    pub intrinsics: Intrinsics,
    pub pose: Pose,
    pub image: LinearImage,
    pub mask: Option<Vec<bool>>,
    pub light_world: nalgebra::Vector3<f64>,
    pub irradiance: [f64; 3],
    /// Clip level of this image, if any.
    pub saturation: Option<f64>,
}

/// A job with its files loaded.
pub struct Scene {
    pub mesh: Mesh,
    pub mesh_report: MeshReport,
    pub views: Vec<View>,
    pub warnings: Vec<String>,
}

/// Per-image pixel counts.
#[derive(Clone, Debug, Serialize)]
pub struct ImageCounts {
    pub file: PathBuf,
    /// Pixels where the mesh is seen.
    pub covered: usize,
    pub observed: usize,
    pub dropped: DropCounts,
}

/// Loads the mesh, the COLMAP model, the images and masks of a job, checking that they agree.
pub fn load_scene(job: &Job, settings: &Settings) -> Result<Scene, ReconstructError> {
    let mut warnings = job.warnings.clone();
    let (mesh, mesh_report) = load_mesh(&job.mesh).map_err(|source| ReconstructError::Mesh {
        job: job.source.clone(),
        source,
    })?;
    if mesh_report.degenerate_faces_dropped > 0 {
        warnings.push(format!(
            "{}: {} degenerate faces dropped",
            job.mesh.display(),
            mesh_report.degenerate_faces_dropped
        ));
    }
    let cameras = read_model(&job.cameras).map_err(|source| ReconstructError::Cameras {
        job: job.source.clone(),
        source,
    })?;
    let mut views = Vec::with_capacity(job.light_images.len());
    for (index, spec) in job.light_images.iter().enumerate() {
        let Some((&intrinsics, &pose)) = cameras.view(&spec.camera) else {
            let mut names: Vec<&str> = cameras.images.iter().map(|i| i.name.as_str()).collect();
            names.sort_unstable();
            let known = if names.len() > 8 {
                format!("{} images: {}, ...", names.len(), names[..8].join(", "))
            } else {
                names.join(", ")
            };
            return Err(ReconstructError::UnknownCamera {
                job: job.source.clone(),
                index,
                name: spec.camera.clone(),
                cameras: job.cameras.clone(),
                known,
            });
        };
        let imageio::DecodedImage { image, samples } =
            imageio::read_image(&spec.file, settings.png_scale, imageio::Transfer::Linear)
                .map_err(|source| ReconstructError::Image {
                    job: job.source.clone(),
                    index,
                    source,
                })?;
        if (image.width(), image.height()) != (intrinsics.width, intrinsics.height) {
            return Err(ReconstructError::SizeMismatch {
                job: job.source.clone(),
                index,
                path: spec.file.clone(),
                camera: spec.camera.clone(),
                got_w: image.width(),
                got_h: image.height(),
                want_w: intrinsics.width,
                want_h: intrinsics.height,
            });
        }
        let mask = match &spec.mask {
            None => None,
            Some(path) => Some(read_mask(path, image.width(), image.height()).map_err(
                |message| ReconstructError::Mask {
                    job: job.source.clone(),
                    index,
                    path: path.clone(),
                    message,
                },
            )?),
        };
        let saturation = settings
            .saturation
            .or(samples.clip_level(settings.png_scale).map(f64::from));
        views.push(View {
            index,
            file: spec.file.clone(),
            intrinsics,
            pose,
            image,
            mask,
            light_world: pose.dir_to_world(&spec.light_dir_camera),
            irradiance: spec.irradiance,
            saturation,
        });
    }
    Ok(Scene {
        mesh,
        mesh_report,
        views,
        warnings,
    })
}

/// A mask image: any format `image` reads; non-zero in any channel = material.
fn read_mask(path: &Path, width: usize, height: usize) -> Result<Vec<bool>, String> {
    let img = image::open(path).map_err(|e| e.to_string())?;
    if (img.width() as usize, img.height() as usize) != (width, height) {
        return Err(format!(
            "is {}x{} but its image is {width}x{height}",
            img.width(),
            img.height()
        ));
    }
    let luma = img.to_luma16();
    Ok(luma.pixels().map(|p| p.0[0] > 0).collect())
}

/// Observations of every view.
pub struct Observed {
    pub observations: Vec<Observation>,
    pub images: Vec<ImageCounts>,
    pub dropped: DropCounts,
}

/// Rasterises the mesh from every light camera (with per-vertex mean curvature and shadow
/// rays) and turns pixels into observations.
pub fn observe_scene(scene: &Scene, settings: &ObserveSettings) -> Observed {
    observe_scene_with(scene, settings, |_| {})
}

/// One view as [`observe_scene_with`] hands it on.
pub struct ViewPass<'a> {
    pub gbuffer: &'a GBuffer,
    pub input: &'a ViewInput<'a>,
    pub surface: &'a [SurfacePixel],
    /// The observation settings of this view (its clip level filled in).
    pub settings: &'a ObserveSettings,
}

/// [`observe_scene`], handing every view's G-buffer, surface pixels and settings to `each`
/// (the normal refinement gathers its pixels in the same pass: one rasterisation).
pub fn observe_scene_with(
    scene: &Scene,
    settings: &ObserveSettings,
    mut each: impl FnMut(&ViewPass<'_>),
) -> Observed {
    let bvh = Bvh::build(&scene.mesh);
    let curvature = principal_curvatures(&scene.mesh);
    let mut observations = Vec::new();
    let mut images = Vec::with_capacity(scene.views.len());
    let mut dropped = DropCounts::default();
    for view in &scene.views {
        let gbuf = rasterise(
            &scene.mesh,
            &bvh,
            &view.intrinsics,
            &view.pose,
            Some(&curvature.mean),
        );
        let centre = view.pose.centre();
        let lit = shadow_mask(&scene.mesh, &bvh, &gbuf, &centre, &view.light_world);
        let w = gbuf.width();
        let surface: Vec<SurfacePixel> = gbuf
            .fragments()
            .iter()
            .zip(&lit)
            .enumerate()
            .filter_map(|(i, (f, lit))| {
                let f = f.as_ref()?;
                Some(SurfacePixel {
                    x: (i % w) as u32,
                    y: (i / w) as u32,
                    position: f.position,
                    normal: f.normal,
                    mean_curvature: f.mean_curvature.unwrap_or(f64::NAN),
                    lit: lit.unwrap_or(false),
                })
            })
            .collect();
        let input = ViewInput {
            image_index: view.index,
            image: &view.image,
            mask: view.mask.as_deref(),
            camera_centre: centre,
            light_world: view.light_world,
            irradiance: view.irradiance,
        };
        let s = ObserveSettings {
            saturation: settings.saturation.or(view.saturation),
            ..*settings
        };
        let (obs, drops) = observe_view(&input, &surface, &s);
        each(&ViewPass {
            gbuffer: &gbuf,
            input: &input,
            surface: &surface,
            settings: &s,
        });
        dropped.add(&drops);
        images.push(ImageCounts {
            file: view.file.clone(),
            covered: surface.len(),
            observed: obs.len(),
            dropped: drops,
        });
        observations.extend(obs);
    }
    Observed {
        observations,
        images,
        dropped,
    }
}

/// The pixels the normal refinement works on: every observation of every view, with no
/// grazing threshold beyond the horizon (a refined normal may turn a grazing pixel towards
/// the light), tied to the face and barycentrics it was rasterised from.
pub fn refine_pixels(scene: &Scene, settings: &ObserveSettings) -> Vec<RefinePixel> {
    observe_scene_and_pixels(scene, settings).1
}

/// [`observe_scene`] and [`refine_pixels`] from one rasterisation of every view.
pub fn observe_scene_and_pixels(
    scene: &Scene,
    settings: &ObserveSettings,
) -> (Observed, Vec<RefinePixel>) {
    let mut pixels = Vec::new();
    let observed = observe_scene_with(scene, settings, |pass| {
        let loose = ObserveSettings {
            min_cos: 0.0,
            ..*pass.settings
        };
        let (obs, _) = observe_view(pass.input, pass.surface, &loose);
        pixels.extend(obs.iter().filter_map(|o| {
            let f = pass.gbuffer.get(o.x as usize, o.y as usize)?;
            Some(RefinePixel::new(o, f.face, f.bary, f.normal))
        }));
    });
    (observed, pixels)
}

/// The basis for the settings: from the cache, or built from the neural fits and cached.
pub fn load_basis(settings: &Settings) -> Result<(Basis, CacheStatus), ReconstructError> {
    let materials = nbrdf::load_dir(&settings.nbrdf_dir)?;
    let dir = settings
        .basis_cache
        .clone()
        .unwrap_or_else(basis_cache::default_cache_dir);
    Ok(basis_cache::load_or_build(
        &settings.basis,
        &materials,
        &dir,
    )?)
}

/// The result of a reconstruction, before anything is written.
pub struct Output {
    pub table: MerlTable,
    pub core: CoreOutput,
    pub observed: Observed,
    pub report: super::output::Report,
    /// Per light image: the photo beside its re-render (written by `output::write`).
    pub comparisons: Vec<Comparison>,
    /// The mesh with its refined normals, when a normal refinement was accepted
    /// (`mesh_refined.ply`).
    pub refined_mesh: Option<Mesh>,
}

/// Peak resident memory of this process (VmHWM), bytes; `None` where /proc is unavailable.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// A job loaded and observed: what every reconstruction of it starts from.
pub struct Prepared {
    /// The scene as reconstructed: its mesh carries the refined normals when a refinement was
    /// accepted.
    pub scene: Scene,
    pub observed: Observed,
    /// What the normal refinement did, when it ran.
    pub refinement: Option<RefineReport>,
    /// (stage, seconds)
    pub timings: Vec<(String, f64)>,
}

/// Loads and observes a job; fails on a bad job before any expensive work (the basis).
pub fn prepare(
    job: &Job,
    settings: &Settings,
    progress: &mut dyn FnMut(&str),
) -> Result<Prepared, ReconstructError> {
    let mut timings = Vec::new();
    let t = Instant::now();
    progress("loading mesh, cameras, images");
    let mut scene = load_scene(job, settings)?;
    timings.push(("load".to_string(), t.elapsed().as_secs_f64()));
    let t = Instant::now();
    progress("rasterising and observing");
    let (observed, pixels) = match settings.refine {
        Some(_) => {
            let (o, p) = observe_scene_and_pixels(&scene, &settings.observe);
            (o, Some(p))
        }
        None => (observe_scene(&scene, &settings.observe), None),
    };
    timings.push(("observe".to_string(), t.elapsed().as_secs_f64()));
    // An image that gives no observation is worth a warning: a wrong light direction (the
    // light behind every surface), a black, NaN or negative image, a wrong mask.
    for (i, c) in observed.images.iter().enumerate() {
        if c.observed == 0 {
            scene.warnings.push(format!(
                "light image {i} ({}) contributes nothing: no usable pixel (mesh seen on {} \
                 pixels; dropped: {:?}); check its light direction, mask and exposure",
                c.file.display(),
                c.covered,
                c.dropped
            ));
        }
    }
    if observed.observations.is_empty() {
        return Err(ReconstructError::NoLitPixels {
            job: job.source.clone(),
            covered: observed.images.iter().map(|i| i.covered).sum(),
            drops: observed.dropped,
        });
    }
    let mut prepared = Prepared {
        scene,
        observed,
        refinement: None,
        timings,
    };
    if let Some(refine) = &settings.refine {
        let _seen = refine_prepared(&mut prepared, pixels, &settings.observe, refine, progress);
    }
    Ok(prepared)
}

/// Refines the normals of a prepared scene from its images; when the refinement is accepted,
/// the mesh takes the refined normals and the images are observed again with them. Returns
/// which vertices some pixel shows. `pixels`: the refinement's pixels when the observation
/// pass gathered them ([`observe_scene_and_pixels`]), else they are gathered here.
pub fn refine_prepared(
    prepared: &mut Prepared,
    pixels: Option<Vec<RefinePixel>>,
    observe: &ObserveSettings,
    settings: &RefineSettings,
    progress: &mut dyn FnMut(&str),
) -> Vec<bool> {
    let t = Instant::now();
    let scene = &mut prepared.scene;
    let pixels = pixels.unwrap_or_else(|| {
        progress("normal refinement: gathering pixels");
        refine_pixels(scene, observe)
    });
    let seen = seen_vertices(scene.mesh.faces(), &pixels, scene.mesh.positions().len());
    let neighbours = scene.mesh.vertex_neighbours();
    let refinement = refine_normals(
        &MeshNormals {
            faces: scene.mesh.faces(),
            normals: scene.mesh.vertex_normals(),
            neighbours: &neighbours,
        },
        &pixels,
        settings,
        progress,
    );
    prepared
        .timings
        .push(("refine normals".to_string(), t.elapsed().as_secs_f64()));
    if refinement.report.accepted && scene.mesh.set_vertex_normals(refinement.normals) {
        let t = Instant::now();
        progress("observing again with the refined normals");
        prepared.observed = observe_scene(scene, observe);
        prepared
            .timings
            .push(("observe (refined)".to_string(), t.elapsed().as_secs_f64()));
    }
    prepared.refinement = Some(refinement.report);
    seen
}

/// Reconstructs the BRDF of a job: loads and checks the job, then the basis (cache or build).
pub fn reconstruct(
    job: &Job,
    settings: &Settings,
    progress: &mut dyn FnMut(&str),
) -> Result<Output, ReconstructError> {
    let mut prepared = prepare(job, settings, progress)?;
    let t = Instant::now();
    progress("basis (cache or build)");
    let (basis, status) = load_basis(settings)?;
    prepared
        .timings
        .push(("basis".to_string(), t.elapsed().as_secs_f64()));
    let mut out = finish(job, settings, &basis, prepared, progress)?;
    out.report.basis.cache = Some(match status {
        CacheStatus::Hit(p) => format!("hit {}", p.display()),
        CacheStatus::Built(p) => format!("built {}", p.display()),
        CacheStatus::Rebuilt { path, reason } => format!("rebuilt {} ({reason})", path.display()),
    });
    Ok(out)
}

/// Reconstructs with a basis already in memory (benchmarks and ablations share one).
pub fn reconstruct_with_basis(
    job: &Job,
    settings: &Settings,
    basis: &Basis,
    progress: &mut dyn FnMut(&str),
) -> Result<Output, ReconstructError> {
    let prepared = prepare(job, settings, progress)?;
    finish(job, settings, basis, prepared, progress)
}

/// The core on a prepared job, then the MERL table and the report.
pub fn finish(
    job: &Job,
    settings: &Settings,
    basis: &Basis,
    prepared: Prepared,
    progress: &mut dyn FnMut(&str),
) -> Result<Output, ReconstructError> {
    let Prepared {
        scene,
        observed,
        refinement,
        mut timings,
    } = prepared;
    let prior = NielsenPrior {
        basis,
        settings: settings.nielsen,
    };
    let core = reconstruct_observations(&observed.observations, &prior, &settings.core, progress)
        .map_err(|source| ReconstructError::Core {
        job: job.source.clone(),
        source,
    })?;
    timings.extend(core.timings.iter().cloned());
    let table = core.table.clone();
    let t = Instant::now();
    progress("photo against re-render, per light image");
    let comparisons = comparisons(&scene, &observed, &table);
    timings.push(("compare".to_string(), t.elapsed().as_secs_f64()));
    let report = super::output::Report::new(
        job,
        settings,
        basis,
        &scene,
        &observed,
        &core,
        &comparisons,
        refinement,
        timings,
    );
    let refined_mesh = report
        .normals
        .as_ref()
        .is_some_and(|r| r.accepted)
        .then_some(scene.mesh);
    Ok(Output {
        table,
        refined_mesh,
        core,
        observed,
        report,
        comparisons,
    })
}

/// Width of one panel of a comparison image, pixels.
const COMPARISON_WIDTH: usize = 320;

/// Every light image beside its re-render (`compare`).
fn comparisons(scene: &Scene, observed: &Observed, table: &MerlTable) -> Vec<Comparison> {
    scene
        .views
        .iter()
        .map(|v| {
            let obs: Vec<&Observation> = observed
                .observations
                .iter()
                .filter(|o| o.image == v.index)
                .collect();
            compare_image(v.index, &v.image, &obs, table, COMPARISON_WIDTH)
        })
        .collect()
}
