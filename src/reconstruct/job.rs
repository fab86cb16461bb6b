//! The reconstruction job: a small TOML file, written by hand or by the capture and calibrate
//! steps, that names the mesh, the COLMAP model and the single-light images with their light
//! direction and irradiance.
//!
//! ```toml
//! format_version = 1             # optional; a file without it is version 1
//! mesh = "mesh.ply"              # PLY (ascii or binary) or OBJ, in the photogrammetry frame
//! cameras = "sparse"             # COLMAP model folder: cameras.txt + images.txt, or .bin
//! [[light_image]]
//! file = "light/view_00.exr"     # linear EXR, 16-bit TIFF/PNG (declared linear), or RAW
//! camera = "view_00.exr"         # this image's NAME in the COLMAP model
//! light_dir_camera = [x, y, z]   # unit vector towards the light, camera axes (x right, y down, z forward)
//! irradiance = [r, g, b]
//! mask = "masks/view_00.png"     # optional, non-zero = material
//! labels = "masks/labels_00.png" # optional: material labels, 0 = not given, v = material v
//! saturation = 245.0             # optional: channel values at or above this are clipped
//! ```
//!
//! Conventions: relative paths are relative to the folder holding the job file; the light
//! direction points from the surface towards the light, in the camera axes of COLMAP (x right,
//! y down, z forward). Unknown keys are tolerated (later versions add keys) and reported as
//! warnings. A `format_version` other than [`JOB_FORMAT_VERSION`] is an error naming the file.
//!
//! The two masks: `mask` removes pixels (0 = not the object; any non-zero value, soft masks
//! included, keeps the pixel). `labels` names materials (an 8- or 16-bit
//! grey image, `reconstruct::mask_labels`): 0 leaves a pixel to the automatic segmentation,
//! `v` in 1..=255 says it shows material `v`; the vertices the labelled pixels see are fixed to
//! that material (docs/materials.md, "Label masks"). Both have the light image's size; an image
//! may have either, both or neither. `labels` was added within version 1: a tool that predates
//! it warns that the key is unknown and ignores it.
//!
//! `saturation` is the image's clip level in its own values: a pixel with a channel at or above
//! it is clipped and not used (`brdf-rig calibrate` writes the level of each merged bracket,
//! where even its shortest exposure clipped: a float EXR file cannot say it itself). Absent:
//! the file format's own level, if it has one (integer files, RAW); `reconstruct --saturation`
//! overrides both. Added within version 1, like `labels`.
//!
//! This module owns the format: [`JobFile`] is the file as serde reads and writes it (with the
//! `toml` crate, so strings are escaped as TOML escapes them), [`Job`] the checked job with its
//! paths resolved. This file only parses and checks the job text; loading the files it names
//! lives in [`crate::reconstruct::load`]. Pure except [`Job::from_file`], which reads the job
//! file.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The job file's name where the calibrate step writes it (in the session folder).
pub const JOB_FILE: &str = "job.toml";
/// The version of the job format this tool reads and writes.
pub const JOB_FORMAT_VERSION: u32 = 1;

/// Errors in the job file itself; each names the job file and the field.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    #[error("cannot read job file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("job file {path} is not valid TOML: {message}")]
    Toml { path: PathBuf, message: String },
    #[error("job file {path}: `{field}`: {message}")]
    Field {
        path: PathBuf,
        field: String,
        message: String,
    },
    #[error(
        "job file {path}: format_version {found}, but this brdf-rig reads version {supported} \
         (written by another version of the tool? rewrite it by hand or re-run `brdf-rig \
         calibrate`)"
    )]
    Version {
        path: PathBuf,
        found: u32,
        supported: u32,
    },
}

/// The job file as written: what serde reads and writes. Paths are as in the file (relative to
/// its folder, or absolute).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JobFile {
    /// Absent in files written by hand before versions were recorded: read as version 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub format_version: Option<u32>,
    pub mesh: String,
    pub cameras: String,
    pub light_image: Vec<LightImageEntry>,
}

/// One `[[light_image]]` table of the job file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LightImageEntry {
    pub file: String,
    pub camera: String,
    pub light_dir_camera: [f64; 3],
    pub irradiance: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub labels: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub saturation: Option<f64>,
}

/// One single-light image of the job.
#[derive(Clone, Debug, PartialEq)]
pub struct LightImageSpec {
    /// Image file, resolved against the job folder.
    pub file: PathBuf,
    /// The image's NAME in the COLMAP model (whose pose is this image's pose).
    pub camera: String,
    /// Unit vector towards the light, camera axes.
    pub light_dir_camera: Vector3<f64>,
    /// Irradiance E per channel, in the unit of the image values (so r = I / (E cos theta_i)).
    pub irradiance: [f64; 3],
    /// Optional mask, resolved; non-zero = material.
    pub mask: Option<PathBuf>,
    /// Optional material label mask, resolved; 0 = no label given, `v` = material `v`.
    pub labels: Option<PathBuf>,
    /// Clip level in the image's values (a channel at or above it is clipped), when the job
    /// gives one (the merged bracket's, written by `brdf-rig calibrate`); positive, finite.
    pub saturation: Option<f64>,
}

/// A parsed and checked job; paths are resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    /// The job file (for error messages).
    pub source: PathBuf,
    pub mesh: PathBuf,
    pub cameras: PathBuf,
    pub light_images: Vec<LightImageSpec>,
    /// Non-fatal findings (unknown keys, a light direction that was renormalised).
    pub warnings: Vec<String>,
}

const TOP_KEYS: [&str; 4] = ["format_version", "mesh", "cameras", "light_image"];
const IMAGE_KEYS: [&str; 7] = [
    "file",
    "camera",
    "light_dir_camera",
    "irradiance",
    "mask",
    "labels",
    "saturation",
];
/// A light direction further than this from unit length is an error, closer is renormalised.
const UNIT_TOLERANCE: f64 = 0.05;

impl Job {
    /// Reads and parses a job file; relative paths resolve against its folder, made absolute,
    /// so every path of the job (and every path a report copies from it) means the same file
    /// from any working folder.
    pub fn from_file(path: &Path) -> Result<Self, JobError> {
        let text = std::fs::read_to_string(path).map_err(|source| JobError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let absolute = std::path::absolute(path).map_err(|source| JobError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let base = absolute.parent().unwrap_or(Path::new("/"));
        Self::parse(&text, path, base)
    }

    /// Parses job text; `source` names the file in errors, `base` resolves relative paths.
    pub fn parse(text: &str, source: &Path, base: &Path) -> Result<Self, JobError> {
        let toml_err = |e: toml::de::Error| JobError::Toml {
            path: source.to_path_buf(),
            message: e.to_string().trim().to_string(),
        };
        let field_err = |field: &str, message: String| JobError::Field {
            path: source.to_path_buf(),
            field: field.to_string(),
            message,
        };
        // Unknown keys are read from the plain table: serde would drop them silently.
        let table: toml::Table = toml::from_str(text).map_err(toml_err)?;
        let mut warnings = unknown_keys(&table, source);
        if let Some(v) = table
            .get("format_version")
            .and_then(toml::Value::as_integer)
            && v != i64::from(JOB_FORMAT_VERSION)
        {
            return Err(JobError::Version {
                path: source.to_path_buf(),
                found: u32::try_from(v).unwrap_or(u32::MAX),
                supported: JOB_FORMAT_VERSION,
            });
        }
        let file: JobFile = toml::Deserializer::parse(text)
            .map_err(toml_err)
            .and_then(|de| {
                serde_path_to_error::deserialize(de).map_err(|e| {
                    let field = e.path().to_string();
                    let message = e.inner().message().trim().to_string();
                    field_err(if field == "." { "(top level)" } else { &field }, message)
                })
            })?;
        if file.light_image.is_empty() {
            return Err(field_err("light_image", "no light images listed".into()));
        }
        let nonempty = |field: String, s: &str| {
            if s.trim().is_empty() {
                Err(field_err(&field, "must not be empty".into()))
            } else {
                Ok(base.join(s))
            }
        };
        let mesh = nonempty("mesh".into(), &file.mesh)?;
        let cameras = nonempty("cameras".into(), &file.cameras)?;
        let mut light_images = Vec::with_capacity(file.light_image.len());
        for (i, e) in file.light_image.iter().enumerate() {
            let f = |k: &str| format!("light_image[{i}].{k}");
            let path = nonempty(f("file"), &e.file)?;
            if e.camera.trim().is_empty() {
                return Err(field_err(&f("camera"), "must not be empty".into()));
            }
            let finite = |k: &str, v: &[f64; 3]| {
                if v.iter().all(|x| x.is_finite()) {
                    Ok(Vector3::from(*v))
                } else {
                    Err(field_err(&f(k), "must hold finite numbers".into()))
                }
            };
            let dir = finite("light_dir_camera", &e.light_dir_camera)?;
            let norm = dir.norm();
            if (norm - 1.0).abs() > UNIT_TOLERANCE {
                return Err(field_err(
                    &f("light_dir_camera"),
                    format!("must be a unit vector towards the light, its length is {norm:.4}"),
                ));
            }
            if (norm - 1.0).abs() > 1e-6 {
                warnings.push(format!(
                    "{}: `{}` has length {norm:.6}, renormalised",
                    source.display(),
                    f("light_dir_camera")
                ));
            }
            let irr = finite("irradiance", &e.irradiance)?;
            if irr.iter().any(|&e| e <= 0.0) {
                return Err(field_err(
                    &f("irradiance"),
                    format!(
                        "every channel must be positive (measured on the white reference), got [{}, {}, {}]",
                        irr.x, irr.y, irr.z
                    ),
                ));
            }
            let labels = match &e.labels {
                Some(l) => Some(nonempty(f("labels"), l)?),
                None => None,
            };
            if let Some(sat) = e.saturation
                && !(sat.is_finite() && sat > 0.0)
            {
                return Err(field_err(
                    &f("saturation"),
                    format!("must be a positive finite clip level, got {sat}"),
                ));
            }
            light_images.push(LightImageSpec {
                file: path,
                camera: e.camera.clone(),
                light_dir_camera: dir / norm,
                irradiance: e.irradiance,
                mask: e.mask.as_ref().map(|m| base.join(m)),
                labels,
                saturation: e.saturation,
            });
        }
        Ok(Self {
            source: source.to_path_buf(),
            mesh,
            cameras,
            light_images,
            warnings,
        })
    }

    /// The job in its file form for a job file in the folder `base` (the inverse of
    /// [`Job::parse`]): a path inside `base` is written relative to it, any other path
    /// absolute, so the file means the same from any working folder.
    pub fn to_file(&self, base: &Path) -> JobFile {
        let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        let base = absolute(base);
        let rel = |p: &Path| {
            let p = absolute(p);
            let s = p.strip_prefix(&base).unwrap_or(&p).to_string_lossy();
            // '/' works on every platform; on Unix a backslash is part of a name, not a separator
            if cfg!(windows) {
                s.replace('\\', "/")
            } else {
                s.into_owned()
            }
        };
        JobFile {
            format_version: Some(JOB_FORMAT_VERSION),
            mesh: rel(&self.mesh),
            cameras: rel(&self.cameras),
            light_image: self
                .light_images
                .iter()
                .map(|li| LightImageEntry {
                    file: rel(&li.file),
                    camera: li.camera.clone(),
                    light_dir_camera: li.light_dir_camera.into(),
                    irradiance: li.irradiance,
                    mask: li.mask.as_deref().map(&rel),
                    labels: li.labels.as_deref().map(&rel),
                    saturation: li.saturation,
                })
                .collect(),
        }
    }

    /// The job as TOML text for a job file in the folder `base` ([`Job::to_file`]).
    pub fn to_toml(&self, base: &Path) -> Result<String, toml::ser::Error> {
        toml::to_string(&self.to_file(base))
    }
}

/// Warnings for the keys of `table` that the format does not know (later versions add keys).
fn unknown_keys(table: &toml::Table, source: &Path) -> Vec<String> {
    let mut warnings = Vec::new();
    for key in table.keys() {
        if !TOP_KEYS.contains(&key.as_str()) {
            warnings.push(format!("{}: unknown key `{key}` ignored", source.display()));
        }
    }
    let images = table.get("light_image").and_then(toml::Value::as_array);
    for (i, entry) in images.into_iter().flatten().enumerate() {
        for key in entry.as_table().into_iter().flat_map(|t| t.keys()) {
            if !IMAGE_KEYS.contains(&key.as_str()) {
                warnings.push(format!(
                    "{}: unknown key `light_image[{i}].{key}` ignored",
                    source.display()
                ));
            }
        }
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
mesh = "mesh.ply"
cameras = "sparse"
future_key = 3
[[light_image]]
file = "light/view_00.exr"
camera = "view_00.exr"
light_dir_camera = [0.0, 0.0, -1.0]
irradiance = [1.0, 2, 3.0]
mask = "masks/view_00.png"
labels = "masks/labels_00.png"
saturation = 245.0
[[light_image]]
file = "/abs/view_01.exr"
camera = "view_01.exr"
light_dir_camera = [0.6, 0.0, -0.8001]
irradiance = [1.0, 1.0, 1.0]
"#;

    #[test]
    fn parses_resolves_paths_and_warns_on_unknown_keys() {
        let job = Job::parse(GOOD, Path::new("/data/job.toml"), Path::new("/data")).unwrap();
        assert_eq!(job.mesh, PathBuf::from("/data/mesh.ply"));
        assert_eq!(job.cameras, PathBuf::from("/data/sparse"));
        assert_eq!(job.light_images.len(), 2);
        let a = &job.light_images[0];
        assert_eq!(a.file, PathBuf::from("/data/light/view_00.exr"));
        assert_eq!(a.mask, Some(PathBuf::from("/data/masks/view_00.png")));
        assert_eq!(a.labels, Some(PathBuf::from("/data/masks/labels_00.png")));
        assert_eq!(job.light_images[1].labels, None);
        assert_eq!(a.saturation, Some(245.0));
        assert_eq!(job.light_images[1].saturation, None);
        assert_eq!(a.irradiance, [1.0, 2.0, 3.0]);
        assert_eq!(job.light_images[1].file, PathBuf::from("/abs/view_01.exr"));
        assert!((job.light_images[1].light_dir_camera.norm() - 1.0).abs() < 1e-12);
        assert_eq!(job.warnings.len(), 2, "{:?}", job.warnings);
        assert!(job.warnings[0].contains("future_key"));
        assert!(job.warnings[1].contains("renormalised"));
        // round trip through to_toml
        let again = Job::parse(
            &job.to_toml(Path::new("/data")).unwrap(),
            Path::new("/data/job.toml"),
            Path::new("/data"),
        )
        .unwrap();
        for (a, b) in again.light_images.iter().zip(&job.light_images) {
            assert_eq!(
                (
                    &a.file,
                    &a.camera,
                    a.irradiance,
                    &a.mask,
                    &a.labels,
                    a.saturation
                ),
                (
                    &b.file,
                    &b.camera,
                    b.irradiance,
                    &b.mask,
                    &b.labels,
                    b.saturation
                )
            );
            assert!((a.light_dir_camera - b.light_dir_camera).norm() < 1e-12);
        }
    }

    fn err_of(text: &str) -> String {
        Job::parse(text, Path::new("job.toml"), Path::new("."))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn errors_name_the_file_and_field() {
        let e = err_of("mesh = \"m.ply\"\n");
        assert!(e.contains("job.toml") && e.contains("`cameras`"), "{e}");
        let e = err_of("mesh = = 3");
        assert!(e.contains("not valid TOML"), "{e}");
        for bad in ["0.0", "-1.0", "nan", "inf"] {
            let e = err_of(&GOOD.replace("saturation = 245.0", &format!("saturation = {bad}")));
            assert!(
                e.contains("light_image[0].saturation") && e.contains("positive finite"),
                "{bad}: {e}"
            );
        }
        let bad_dir = GOOD.replace("[0.0, 0.0, -1.0]", "[0.0, 0.0, -2.0]");
        let e = err_of(&bad_dir);
        assert!(
            e.contains("light_image[0].light_dir_camera") && e.contains("unit"),
            "{e}"
        );
        let bad_irr = GOOD.replace("[1.0, 2, 3.0]", "[1.0, 0.0, 3.0]");
        assert!(err_of(&bad_irr).contains("light_image[0].irradiance"));
        let short = GOOD.replace("[1.0, 2, 3.0]", "[1.0, 2.0]");
        let e = err_of(&short);
        assert!(
            e.contains("light_image[0].irradiance") && e.contains("length 3"),
            "{e}"
        );
        let no_images = "mesh = \"m.ply\"\ncameras = \"s\"\n";
        assert!(err_of(no_images).contains("light_image"));
        let wrong_type = GOOD.replace("camera = \"view_00.exr\"", "camera = 7");
        assert!(err_of(&wrong_type).contains("light_image[0].camera"));
        let labels_number = GOOD.replace("labels = \"masks/labels_00.png\"", "labels = 2");
        let e = err_of(&labels_number);
        assert!(
            e.contains("job.toml") && e.contains("light_image[0].labels"),
            "{e}"
        );
        let labels_empty = GOOD.replace("labels = \"masks/labels_00.png\"", "labels = \" \"");
        let e = err_of(&labels_empty);
        assert!(
            e.contains("light_image[0].labels") && e.contains("empty"),
            "{e}"
        );
    }

    #[test]
    fn another_format_version_is_refused_naming_the_file() {
        let e = err_of(&format!("format_version = 2\n{GOOD}"));
        assert!(
            e.contains("job.toml") && e.contains("format_version 2") && e.contains("version 1"),
            "{e}"
        );
        let v1 = format!("format_version = 1\n{GOOD}");
        assert!(Job::parse(&v1, Path::new("job.toml"), Path::new("/d")).is_ok());
    }

    /// Strings TOML must escape (quotes, backslashes, control characters) survive a write and a
    /// read: the writer is the `toml` crate, not Rust's `{:?}` (which writes `\u{1}`, not TOML).
    #[test]
    fn names_toml_must_escape_round_trip() {
        let mut job = Job::parse(GOOD, Path::new("/data/job.toml"), Path::new("/data")).unwrap();
        let odd = "view \"1\"\\back\u{1}\u{7f}\u{e9}.exr";
        job.light_images[0].camera = odd.to_string();
        job.light_images[0].file = PathBuf::from(format!("/data/light/{odd}"));
        job.mesh = PathBuf::from("/elsewhere/mesh.ply");
        let text = job.to_toml(Path::new("/data")).unwrap();
        let again = Job::parse(&text, Path::new("/data/job.toml"), Path::new("/data")).unwrap();
        assert_eq!(again.light_images[0].camera, odd);
        assert_eq!(again.light_images[0].file, job.light_images[0].file);
        assert_eq!(again.mesh, PathBuf::from("/elsewhere/mesh.ply"));
        assert!(text.contains("file = \"light/"), "{text}");
        assert!(text.contains("format_version = 1"), "{text}");
    }

    #[test]
    fn missing_file_is_named() {
        let e = Job::from_file(Path::new("/nonexistent/job.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/job.toml"), "{e}");
    }
}
