//! A job's files loaded and observed: load the mesh, cameras and images, rasterise and observe
//! every light image (optionally refining the normals first), and read (or build) the basis;
//! `run` chains this with the pure core. Touches files (as `output` and `report_file` do);
//! every error names the file and the field.
//!
//! Images are streamed: [`prepare`] reads one light image (and its pixel and label masks),
//! observes it (`sweep`: z-buffer, reduction, shadow rays for the kept pixels; the label
//! mask's votes from the same z-buffer, `mask_labels`), keeps its thumbnail for the comparison
//! and lets it go before reading the next, so memory follows the observations, not the
//! sensor. The normal refinement, which works on every pixel of every view, holds the images
//! instead ([`load_scene`], [`observe_scene_with`]).

use super::compare::Thumbnail;
use super::core::{CoreError, CoreSettings};
use super::job::{Job, JobError};
use super::mask_labels::{LabelImage, LabelMaskError, LabelVotes};
use super::nielsen::NielsenSettings;
use super::observe::{
    DropCounts, ImageCounts, Observation, ObserveSettings, SurfacePixel, ViewInput,
    inside_lit_surface, observe_view,
};
use super::reduce::reduce;
use super::refine::{
    MeshNormals, RefinePixel, RefineReport, RefineSettings, StartNormals, refine_normals,
    seen_vertices, without_foreign_colours,
};
use super::segment::{ForeignColours, SegmentSettings, segment_with_labels};
use super::sweep::{ViewSweep, sweep_view};
use crate::brdf::basis::{Basis, BasisSettings};
use crate::brdf::basis_cache::{self, BasisCacheError, CacheStatus};
use crate::brdf::nbrdf::{self, NbrdfError};
use crate::geometry::bvh::Bvh;
use crate::geometry::camera::{Intrinsics, Pose};
use crate::geometry::colmap::{ColmapError, read_model};
use crate::geometry::curvature::principal_curvatures;
use crate::geometry::mesh::{Mesh, MeshReport};
use crate::geometry::mesh_io::{MeshIoError, load_mesh};
use crate::geometry::raster::{GBuffer, Rasteriser, rasterise};
use crate::geometry::shadow::shadow_mask;
use crate::geometry::taubin::smoothed_normals_each;
use crate::imageio::{self, ImageIoError};
use crate::render::image::LinearImage;
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
    /// With `refine`: skip it, with a warning, when the light images hold more pixels than this
    /// in all (it holds every image in memory: 7.4 GiB at peak for eleven 24-megapixel images,
    /// docs/benchmarks-reconstruct.md "Session 48"); `None`: no limit (`reconstruct
    /// --refine-normals` given). Default [`REFINE_AUTO_MAX_PIXELS`].
    pub refine_max_pixels: Option<usize>,
    /// Find the object's materials and fit one BRDF each (`reconstruct::materials`); `None` =
    /// one material, as the paper assumes, unless the job's label masks give materials: then
    /// exactly those (`run::finish`).
    pub materials: Option<super::segment::SegmentSettings>,
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
            refine_max_pixels: Some(REFINE_AUTO_MAX_PIXELS),
            materials: None,
        }
    }
}

/// The most pixels, over all light images, that the normal refinement runs on unless asked
/// for by name (`--refine-normals`): 48 megapixels (eleven photographs of 4.4 megapixels), so
/// that the default stays within issue #14's 2 GiB. Measured (`bench reconstruct`, session 48):
/// eleven 1920x1440 images (30 megapixels) 1164 MiB at peak refined, 831 MiB not; eleven
/// 6000x4000 (264 megapixels) 7433 MiB refined, 878 MiB not.
pub const REFINE_AUTO_MAX_PIXELS: usize = 48_000_000;

/// The refinement `settings` asks for, or why it is skipped: the light images of `scene` hold
/// more pixels than `settings.refine_max_pixels` (the warning to give).
fn refinement_within_limit<'a>(
    settings: &'a Settings,
    scene: &Scene,
) -> Result<Option<&'a RefineSettings>, String> {
    let Some(refine) = settings.refine.as_ref() else {
        return Ok(None);
    };
    let pixels: usize = scene
        .views
        .iter()
        .map(|v| v.intrinsics.width.saturating_mul(v.intrinsics.height))
        .fold(0usize, usize::saturating_add);
    match settings.refine_max_pixels {
        Some(limit) if pixels > limit => Err(format!(
            "normals not refined: the light images hold {:.0} megapixels, more than the {:.0} \
             the refinement runs on by default (it holds every image in memory); \
             `--refine-normals` refines anyway, `--no-refine-normals` silences this",
            pixels as f64 / 1e6,
            limit as f64 / 1e6
        )),
        _ => Ok(Some(refine)),
    }
}

/// Reads every light image (and its masks) of a scene loaded without them.
fn hold_images(job: &Job, scene: &mut Scene, settings: &Settings) -> Result<(), ReconstructError> {
    for view in &mut scene.views {
        let p = load_view_pixels(job, view.index, &view.intrinsics, settings)?;
        view.image = Some(p.image);
        view.mask = p.mask;
        view.labels = p.labels;
        view.saturation = p.saturation;
    }
    Ok(())
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
    #[error("job {job}: `light_image[{index}].mask`: {path}: {problem}")]
    Mask {
        job: PathBuf,
        index: usize,
        path: PathBuf,
        problem: MaskError,
    },
    #[error("job {job}: `light_image[{index}].labels`: {path}: {problem}")]
    Labels {
        job: PathBuf,
        index: usize,
        path: PathBuf,
        problem: LabelMaskError,
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
    #[error("job {job}: {name}: {source}")]
    Material {
        job: PathBuf,
        name: String,
        source: CoreError,
    },
}

/// One light image, loaded and checked.
pub struct View {
    pub index: usize,
    pub file: PathBuf,
    pub intrinsics: Intrinsics,
    pub pose: Pose,
    /// The pixels, when held (`load_scene`); `None` when streamed (`load_scene_streamed`):
    /// read from `file` while observing, then let go.
    pub image: Option<LinearImage>,
    /// The mask, when held (and the job names one).
    pub mask: Option<Vec<bool>>,
    /// The mask file the job names, if any.
    pub mask_file: Option<PathBuf>,
    /// The material label mask, when held (and the job names one).
    pub labels: Option<LabelImage>,
    /// The label mask file the job names, if any.
    pub labels_file: Option<PathBuf>,
    pub light_world: nalgebra::Vector3<f64>,
    pub irradiance: [f64; 3],
    /// Clip level of this image, if any (known once the image has been read).
    pub saturation: Option<f64>,
}

/// A job with its files loaded.
pub struct Scene {
    pub mesh: Mesh,
    pub mesh_report: MeshReport,
    pub views: Vec<View>,
    pub warnings: Vec<String>,
}

/// Loads the mesh, the COLMAP model, the images and masks of a job, checking that they agree;
/// every image is held.
pub fn load_scene(job: &Job, settings: &Settings) -> Result<Scene, ReconstructError> {
    load_scene_with(job, settings, true)
}

/// Loads the mesh and the COLMAP model of a job and checks that every light image has a
/// camera; the images and masks are read later, one at a time ([`observe_scene_streamed`]).
pub fn load_scene_streamed(job: &Job, settings: &Settings) -> Result<Scene, ReconstructError> {
    load_scene_with(job, settings, false)
}

/// The pixels of one light image, checked against its camera.
struct ViewPixels {
    image: LinearImage,
    mask: Option<Vec<bool>>,
    labels: Option<LabelImage>,
    /// Clip level.
    saturation: Option<f64>,
}

/// Reads light image `index` of `job` (and its masks), checking its size against `intrinsics`.
fn load_view_pixels(
    job: &Job,
    index: usize,
    intrinsics: &Intrinsics,
    settings: &Settings,
) -> Result<ViewPixels, ReconstructError> {
    let spec = &job.light_images[index];
    let imageio::DecodedImage { image, samples } =
        imageio::read_image(&spec.file, settings.png_scale, imageio::Transfer::Linear).map_err(
            |source| ReconstructError::Image {
                job: job.source.clone(),
                index,
                source,
            },
        )?;
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
    let mask =
        match &spec.mask {
            None => None,
            Some(path) => Some(read_mask(path, image.width(), image.height()).map_err(
                |problem| ReconstructError::Mask {
                    job: job.source.clone(),
                    index,
                    path: path.clone(),
                    problem,
                },
            )?),
        };
    let labels = match &spec.labels {
        None => None,
        Some(path) => Some(read_labels(path, image.width(), image.height()).map_err(
            |problem| ReconstructError::Labels {
                job: job.source.clone(),
                index,
                path: path.clone(),
                problem,
            },
        )?),
    };
    // `--saturation`, else the job's level (a merged bracket's), else the file format's
    let saturation = settings
        .saturation
        .or(spec.saturation)
        .or(samples.clip_level(settings.png_scale).map(f64::from));
    Ok(ViewPixels {
        image,
        mask,
        labels,
        saturation,
    })
}

fn load_scene_with(job: &Job, settings: &Settings, hold: bool) -> Result<Scene, ReconstructError> {
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
        views.push(View {
            index,
            file: spec.file.clone(),
            intrinsics,
            pose,
            image: None,
            mask: None,
            mask_file: spec.mask.clone(),
            labels: None,
            labels_file: spec.labels.clone(),
            light_world: pose.dir_to_world(&spec.light_dir_camera),
            irradiance: spec.irradiance,
            saturation: None,
        });
    }
    let mut scene = Scene {
        mesh,
        mesh_report,
        views,
        warnings,
    };
    if hold {
        hold_images(job, &mut scene, settings)?;
    }
    Ok(scene)
}

/// What is wrong with a mask file ([`ReconstructError::Mask`] names the job, image and file).
#[derive(Debug, thiserror::Error)]
pub enum MaskError {
    #[error(transparent)]
    Read(Box<image::ImageError>),
    #[error("is {got_w}x{got_h} but its image is {want_w}x{want_h}")]
    Size {
        got_w: usize,
        got_h: usize,
        want_w: usize,
        want_h: usize,
    },
}

/// A mask image: any format `image` reads; non-zero in any channel = material.
fn read_mask(path: &Path, width: usize, height: usize) -> Result<Vec<bool>, MaskError> {
    let img = image::open(path).map_err(|e| MaskError::Read(Box::new(e)))?;
    if (img.width() as usize, img.height() as usize) != (width, height) {
        return Err(MaskError::Size {
            got_w: img.width() as usize,
            got_h: img.height() as usize,
            want_w: width,
            want_h: height,
        });
    }
    let luma = img.to_luma16();
    Ok(luma.pixels().map(|p| p.0[0] > 0).collect())
}

/// A material label mask (`reconstruct::mask_labels`): an 8- or 16-bit grey image of the
/// light image's size; JPEG is refused (lossy: the values change near every edge).
fn read_labels(path: &Path, width: usize, height: usize) -> Result<LabelImage, LabelMaskError> {
    let read = |e: image::ImageError| LabelMaskError::Read(Box::new(e));
    let reader = image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| read(image::ImageError::IoError(e)))?;
    if reader.format() == Some(image::ImageFormat::Jpeg) {
        return Err(LabelMaskError::Lossy);
    }
    let img = reader.decode().map_err(read)?;
    LabelImage::decode(&img, width, height)
}

/// Observations of every view.
pub struct Observed {
    pub observations: Vec<Observation>,
    pub images: Vec<ImageCounts>,
    pub dropped: DropCounts,
    /// Per view (as `images`): the photo downsampled for the comparison panel; `None` for a
    /// view whose image was not at hand.
    pub thumbnails: Vec<Option<Thumbnail>>,
    /// The votes of the pixels the job's label masks label, for the vertices of the faces
    /// they see (`mask_labels`); empty when the job has none.
    pub label_votes: LabelVotes,
}

impl Observed {
    fn new(capacity: usize) -> Self {
        Self {
            observations: Vec::new(),
            images: Vec::with_capacity(capacity),
            dropped: DropCounts::default(),
            thumbnails: Vec::with_capacity(capacity),
            label_votes: LabelVotes::default(),
        }
    }

    fn push(&mut self, file: &Path, sweep: ViewSweep, thumbnail: Option<Thumbnail>) {
        self.dropped.add(&sweep.dropped);
        self.images.push(ImageCounts {
            file: file.to_path_buf(),
            covered: sweep.covered,
            observed: sweep.observations.len(),
            dropped: sweep.dropped,
        });
        self.thumbnails.push(thumbnail);
        self.observations.extend(sweep.observations);
    }
}

/// The surface pixels of a G-buffer with their shadow flags.
fn surface_pixels(gbuf: &GBuffer, lit: &[Option<bool>]) -> Vec<SurfacePixel> {
    let w = gbuf.width();
    gbuf.fragments()
        .iter()
        .zip(lit)
        .enumerate()
        .filter_map(|(i, (f, lit))| {
            let f = f.as_ref()?;
            Some(SurfacePixel {
                x: (i % w) as u32,
                y: (i / w) as u32,
                position: f.position,
                normal: f.normal,
                mean_curvature: f.mean_curvature.unwrap_or(f64::NAN),
                face: f.face,
                lit: lit.unwrap_or(false),
            })
        })
        .collect()
}

/// A G-buffer view's observations (every pixel's, from `observe_view`) reduced as `s` says.
fn reduced(
    obs: Vec<Observation>,
    mut dropped: DropCounts,
    surface: &[SurfacePixel],
    gbuf: &GBuffer,
    s: &ObserveSettings,
) -> ViewSweep {
    let observations = match &s.reduce {
        Some(red) => {
            let (kept, n) = reduce(obs, gbuf.width(), gbuf.height(), red);
            dropped.redundant += n;
            kept
        }
        None => obs,
    };
    ViewSweep {
        observations,
        dropped,
        covered: surface.len(),
    }
}

/// What every view's observation needs of the mesh, built once.
struct MeshAids {
    bvh: Bvh,
    curvature: Vec<f64>,
}

impl MeshAids {
    fn new(mesh: &Mesh) -> Self {
        Self {
            bvh: Bvh::build(mesh),
            curvature: principal_curvatures(mesh).mean,
        }
    }
}

/// One light image's pixels as [`observe_one`] reads them.
struct ViewPixelsRef<'a> {
    image: &'a LinearImage,
    mask: Option<&'a [bool]>,
    labels: Option<&'a LabelImage>,
    saturation: Option<f64>,
}

impl ViewPixels {
    fn as_ref(&self) -> ViewPixelsRef<'_> {
        ViewPixelsRef {
            image: &self.image,
            mask: self.mask.as_deref(),
            labels: self.labels.as_ref(),
            saturation: self.saturation,
        }
    }
}

impl View {
    /// The pixels this view holds (`None` when streamed).
    fn held(&self) -> Option<ViewPixelsRef<'_>> {
        Some(ViewPixelsRef {
            image: self.image.as_ref()?,
            mask: self.mask.as_deref(),
            labels: self.labels.as_ref(),
            saturation: self.saturation,
        })
    }
}

/// Observes one view from its pixels (`sweep`; a view the z-buffer cannot take is ray-cast
/// with a shadow ray per pixel, then reduced) and takes its thumbnail; a labelled pixel votes
/// into `votes` for the corners of the face it sees (`mask_labels`).
fn observe_one(
    mesh: &Mesh,
    aids: &MeshAids,
    view: &View,
    px: ViewPixelsRef<'_>,
    settings: &ObserveSettings,
    votes: &mut LabelVotes,
) -> (ViewSweep, Thumbnail) {
    let r = Rasteriser::new(
        mesh,
        &aids.bvh,
        &view.intrinsics,
        &view.pose,
        Some(&aids.curvature),
    );
    let centre = view.pose.centre();
    let input = ViewInput {
        image_index: view.index,
        image: px.image,
        mask: px.mask,
        camera_centre: centre,
        light_world: view.light_world,
        irradiance: view.irradiance,
    };
    let s = ObserveSettings {
        saturation: settings.saturation.or(px.saturation),
        ..*settings
    };
    let sweep = match r.faces() {
        Some(faces) => {
            if let Some(labels) = px.labels {
                votes.add_view(mesh, labels, px.mask, |x, y| faces.face(x, y));
            }
            sweep_view(mesh, &aids.bvh, &r, &faces, &input, &s)
        }
        None => {
            let gbuf = r.gbuffer_ray_cast();
            if let Some(labels) = px.labels {
                votes.add_view(mesh, labels, px.mask, |x, y| gbuf.get(x, y).map(|f| f.face));
            }
            let lit = shadow_mask(mesh, &aids.bvh, &gbuf, &centre, &view.light_world);
            let surface = surface_pixels(&gbuf, &lit);
            let (obs, dropped) = observe_view(&input, &surface, &s);
            reduced(obs, dropped, &surface, &gbuf, &s)
        }
    };
    (sweep, Thumbnail::of(px.image, COMPARISON_WIDTH))
}

/// Rasterises the mesh from every light camera (z-buffer, per-vertex mean curvature, shadow
/// rays for the kept pixels) and turns the pixels of the held images into observations
/// (reduced as `settings.reduce` says). A view whose image is not held (a streamed scene:
/// use [`observe_scene_streamed`]) contributes nothing.
pub fn observe_scene(scene: &Scene, settings: &ObserveSettings) -> Observed {
    let aids = MeshAids::new(&scene.mesh);
    let mut observed = Observed::new(scene.views.len());
    for view in &scene.views {
        match view.held() {
            Some(px) => {
                let (sweep, thumb) = observe_one(
                    &scene.mesh,
                    &aids,
                    view,
                    px,
                    settings,
                    &mut observed.label_votes,
                );
                observed.push(&view.file, sweep, Some(thumb));
            }
            None => observed.push(&view.file, ViewSweep::default(), None),
        }
    }
    observed
}

/// [`observe_scene`] reading every image that is not held from its file (and its mask), one
/// at a time, and letting it go once observed. `progress` hears of each image.
pub fn observe_scene_streamed(
    job: &Job,
    scene: &Scene,
    settings: &Settings,
    progress: &mut dyn FnMut(&str),
) -> Result<Observed, ReconstructError> {
    let aids = MeshAids::new(&scene.mesh);
    let mut observed = Observed::new(scene.views.len());
    for view in &scene.views {
        progress(&format!(
            "observing light image {} of {} ({})",
            view.index + 1,
            scene.views.len(),
            view.file.display()
        ));
        let loaded;
        let px = match view.held() {
            Some(px) => px,
            None => {
                loaded = load_view_pixels(job, view.index, &view.intrinsics, settings)?;
                loaded.as_ref()
            }
        };
        let (sweep, thumb) = observe_one(
            &scene.mesh,
            &aids,
            view,
            px,
            &settings.observe,
            &mut observed.label_votes,
        );
        observed.push(&view.file, sweep, Some(thumb));
    }
    Ok(observed)
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
    let aids = MeshAids::new(&scene.mesh);
    let mut observed = Observed::new(scene.views.len());
    for view in &scene.views {
        let Some(image) = &view.image else {
            observed.push(&view.file, ViewSweep::default(), None);
            continue;
        };
        let gbuf = rasterise(
            &scene.mesh,
            &aids.bvh,
            &view.intrinsics,
            &view.pose,
            Some(&aids.curvature),
        );
        let centre = view.pose.centre();
        let lit = shadow_mask(&scene.mesh, &aids.bvh, &gbuf, &centre, &view.light_world);
        let surface = surface_pixels(&gbuf, &lit);
        let input = ViewInput {
            image_index: view.index,
            image,
            mask: view.mask.as_deref(),
            camera_centre: centre,
            light_world: view.light_world,
            irradiance: view.irradiance,
        };
        let s = ObserveSettings {
            saturation: settings.saturation.or(view.saturation),
            ..*settings
        };
        let (obs, dropped) = observe_view(&input, &surface, &s);
        each(&ViewPass {
            gbuffer: &gbuf,
            input: &input,
            surface: &surface,
            settings: &s,
        });
        let sweep = reduced(obs, dropped, &surface, &gbuf, &s);
        if let Some(labels) = &view.labels {
            observed
                .label_votes
                .add_view(&scene.mesh, labels, view.mask.as_deref(), |x, y| {
                    gbuf.get(x, y).map(|f| f.face)
                });
        }
        observed.push(
            &view.file,
            sweep,
            Some(Thumbnail::of(image, COMPARISON_WIDTH)),
        );
    }
    observed
}

/// The pixels the normal refinement works on: every observation of every view at least
/// `edge_margin` pixels inside the lit surface (`observe::inside_lit_surface`), with no
/// grazing threshold beyond the horizon (a refined normal may turn a grazing pixel towards
/// the light), tied to the face and barycentrics it was rasterised from.
pub fn refine_pixels(
    scene: &Scene,
    settings: &ObserveSettings,
    edge_margin: usize,
) -> Vec<RefinePixel> {
    observe_scene_and_pixels(scene, settings, edge_margin).1
}

/// [`observe_scene`] and [`refine_pixels`] from one rasterisation of every view.
pub fn observe_scene_and_pixels(
    scene: &Scene,
    settings: &ObserveSettings,
    edge_margin: usize,
) -> (Observed, Vec<RefinePixel>) {
    let mut pixels = Vec::new();
    let observed = observe_scene_with(scene, settings, |pass| {
        let loose = ObserveSettings {
            min_cos: 0.0,
            ..*pass.settings
        };
        let inside: Vec<SurfacePixel> = pass
            .surface
            .iter()
            .zip(inside_lit_surface(pass.surface, edge_margin))
            .filter(|(_, k)| *k)
            .map(|(s, _)| *s)
            .collect();
        let (obs, _) = observe_view(pass.input, &inside, &loose);
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
    // the normal refinement works on every pixel of every view: it holds the images, unless
    // they are too many pixels for it by default
    let mut scene = load_scene_streamed(job, settings)?;
    let refine = match refinement_within_limit(settings, &scene) {
        Ok(r) => r,
        Err(warning) => {
            progress(&warning);
            scene.warnings.push(warning);
            None
        }
    };
    if refine.is_some() {
        hold_images(job, &mut scene, settings)?;
    }
    timings.push(("load".to_string(), t.elapsed().as_secs_f64()));
    let t = Instant::now();
    progress("rasterising and observing");
    let (observed, pixels) = match refine {
        Some(r) => {
            let (o, p) = observe_scene_and_pixels(&scene, &settings.observe, r.edge_margin_px);
            (o, Some(p))
        }
        None => (
            observe_scene_streamed(job, &scene, settings, progress)?,
            None,
        ),
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
    let labelled: Vec<String> = job
        .light_images
        .iter()
        .enumerate()
        .filter(|(_, li)| li.labels.is_some())
        .map(|(i, _)| i.to_string())
        .collect();
    if !labelled.is_empty() && observed.label_votes.is_empty() {
        scene.warnings.push(format!(
            "{}: the label masks of light images {} label no observed pixel: they give no \
             material (check that the labels, 1 to 255, are drawn on the object where it is \
             lit and not masked out)",
            job.source.display(),
            labelled.join(", ")
        ));
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
    if let Some(refine) = refine {
        let t = Instant::now();
        let labels = material_labels(
            &prepared.scene.mesh,
            &prepared.observed,
            settings.materials,
            progress,
        );
        let found = labels.vertex.iter().max().map_or(1, |m| m + 1);
        prepared.timings.push((
            format!("materials for the refinement ({found})"),
            t.elapsed().as_secs_f64(),
        ));
        if found > 1 && settings.materials.is_none() && prepared.observed.label_votes.is_empty() {
            prepared.scene.warnings.push(format!(
                "the images look like {found} materials: the normal refinement fitted a \
                 reflectance table to each, but the result is one BRDF for the whole object \
                 (--materials auto fits one per material)"
            ));
        }
        let _seen = refine_prepared(
            &mut prepared,
            pixels,
            &settings.observe,
            refine,
            &labels,
            progress,
        );
    }
    Ok(prepared)
}

/// The segmentation a job gets: `materials` (`--materials auto`) when asked; else, when the
/// job's label masks fix some vertices, exactly the masks' materials; else none (one
/// material).
pub fn segmentation_for(
    materials: Option<SegmentSettings>,
    has_fixed_labels: bool,
) -> Option<SegmentSettings> {
    match (materials, has_fixed_labels) {
        (Some(seg), _) => Some(seg),
        (None, true) => Some(SegmentSettings {
            max_materials: 1,
            ..SegmentSettings::default()
        }),
        (None, false) => None,
    }
}

/// The materials of the mesh's vertices as the normal refinement needs them (one reflectance
/// table each): the segmentation of [`segmentation_for`] on the observations of the unrefined
/// normals (its features do not depend on the normals' error); when the job asked for one
/// material and has no label masks, the default segmentation all the same: with one table for
/// an object of several materials the refinement bends the normals to absorb their difference
/// (docs/materials.md, "With `--refine-normals`"), and a one-material object is found to be one
/// (the count's rule, docs/materials.md "How many"). Its labels are empty when one material is found. The
/// materials reported are found again after the refinement (or not at all, when one was asked).
pub fn material_labels(
    mesh: &Mesh,
    observed: &Observed,
    materials: Option<SegmentSettings>,
    progress: &mut dyn FnMut(&str),
) -> RefineLabels {
    let fixed = observed.label_votes.fixed(mesh.positions().len());
    let seg = segmentation_for(materials, fixed.is_some()).unwrap_or_default();
    progress("normal refinement: finding the materials first (a reflectance table each)");
    let found = segment_with_labels(
        mesh,
        &observed.observations,
        &seg,
        fixed.as_ref().map_or(&[][..], |f| &f.vertex[..]),
    );
    if found.count > 1 {
        RefineLabels {
            vertex: found.vertex_labels,
            chromaticity: found.chromaticity,
            foreign_colour_rings: seg.foreign_colour_rings,
        }
    } else {
        RefineLabels::default()
    }
}

/// The materials found before the normal refinement ([`material_labels`]): one label per
/// vertex (empty: one material), and what the colour rule near their boundary needs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RefineLabels {
    pub vertex: Vec<u32>,
    /// Per material: its pixels' mean chromaticity (r, g, b shares).
    pub chromaticity: Vec<[f64; 3]>,
    /// The segmentation's `SegmentSettings::foreign_colour_rings` (0: the rule is off).
    pub foreign_colour_rings: usize,
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
    labels: &RefineLabels,
    progress: &mut dyn FnMut(&str),
) -> Vec<bool> {
    let t = Instant::now();
    let scene = &mut prepared.scene;
    let pixels = pixels.unwrap_or_else(|| {
        progress("normal refinement: gathering pixels");
        refine_pixels(scene, observe, settings.edge_margin_px)
    });
    let seen = seen_vertices(scene.mesh.faces(), &pixels, scene.mesh.positions().len());
    // With the colour rule (a study knob, off by default): near the labels' boundary, a pixel
    // of another material's colour pulls its labelled material's table, and the normals fitted
    // through it, towards the other material (docs/materials.md, session 52).
    let rule = settings
        .foreign_colours
        .then(|| {
            ForeignColours::new(
                &scene.mesh,
                &labels.vertex,
                &labels.chromaticity,
                labels.foreign_colour_rings,
            )
        })
        .flatten();
    let (pixels, foreign_colour_pixels) = match &rule {
        Some(rule) => without_foreign_colours(scene.mesh.faces(), pixels, &labels.vertex, rule),
        None => (pixels, 0),
    };
    let neighbours = scene.mesh.vertex_neighbours();
    let ks: Vec<usize> = settings
        .start_smoothing
        .iter()
        .copied()
        .filter(|&k| k > 0)
        .collect();
    let starts: Vec<StartNormals> = ks
        .iter()
        .zip(smoothed_normals_each(&scene.mesh, &ks))
        .map(|(&k, normals)| StartNormals {
            smoothing_iterations: k,
            normals,
        })
        .collect();
    let mut refinement = refine_normals(
        &MeshNormals {
            faces: scene.mesh.faces(),
            positions: scene.mesh.positions(),
            normals: scene.mesh.vertex_normals(),
            neighbours: &neighbours,
            starts: &starts,
            labels: &labels.vertex,
        },
        &pixels,
        settings,
        progress,
    );
    refinement.report.foreign_colour_pixels = foreign_colour_pixels;
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

/// Width of one panel of a comparison image, pixels.
const COMPARISON_WIDTH: usize = 320;
