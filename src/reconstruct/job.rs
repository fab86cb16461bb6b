//! The reconstruction job: a small TOML file, written by hand or by the capture and calibrate
//! steps, that names the mesh, the COLMAP model and the single-light images with their light
//! direction and irradiance.
//!
//! ```toml
//! mesh = "mesh.ply"              # PLY (ascii or binary) or OBJ, in the photogrammetry frame
//! cameras = "sparse"             # COLMAP model folder: cameras.txt + images.txt, or .bin
//! [[light_image]]
//! file = "light/view_00.exr"     # linear EXR, 16-bit TIFF/PNG (declared linear), or RAW
//! camera = "view_00.exr"         # this image's NAME in the COLMAP model
//! light_dir_camera = [x, y, z]   # unit vector towards the light, camera axes (x right, y down, z forward)
//! irradiance = [r, g, b]
//! mask = "masks/view_00.png"     # optional, non-zero = material
//! ```
//!
//! Conventions: relative paths are relative to the folder holding the job file; the light
//! direction points from the surface towards the light, in the camera axes of COLMAP (x right,
//! y down, z forward). Unknown keys are tolerated (later versions add keys) and reported as
//! warnings. This file only parses and checks the job text; loading the files it names lives in
//! [`crate::reconstruct::load`]. Pure except [`Job::from_file`], which reads the job file.

use nalgebra::Vector3;
use std::path::{Path, PathBuf};

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

const TOP_KEYS: [&str; 3] = ["mesh", "cameras", "light_image"];
const IMAGE_KEYS: [&str; 5] = ["file", "camera", "light_dir_camera", "irradiance", "mask"];
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
        let table: toml::Table = toml::from_str(text).map_err(|e| JobError::Toml {
            path: source.to_path_buf(),
            message: e.to_string().trim().to_string(),
        })?;
        let field_err = |field: &str, message: String| JobError::Field {
            path: source.to_path_buf(),
            field: field.to_string(),
            message,
        };
        let mut warnings = Vec::new();
        for key in table.keys() {
            if !TOP_KEYS.contains(&key.as_str()) {
                warnings.push(format!("{}: unknown key `{key}` ignored", source.display()));
            }
        }
        let mesh = base.join(get_str(&table, "mesh", "mesh").map_err(|m| field_err("mesh", m))?);
        let cameras =
            base.join(get_str(&table, "cameras", "cameras").map_err(|m| field_err("cameras", m))?);
        let entries = match table.get("light_image") {
            None => {
                return Err(field_err(
                    "light_image",
                    "missing: add at least one [[light_image]] table".into(),
                ));
            }
            Some(toml::Value::Array(a)) => a,
            Some(_) => {
                return Err(field_err(
                    "light_image",
                    "must be an array of tables ([[light_image]])".into(),
                ));
            }
        };
        if entries.is_empty() {
            return Err(field_err("light_image", "no light images listed".into()));
        }
        let mut light_images = Vec::with_capacity(entries.len());
        for (i, entry) in entries.iter().enumerate() {
            let prefix = format!("light_image[{i}]");
            let t = entry
                .as_table()
                .ok_or_else(|| field_err(&prefix, "must be a table".into()))?;
            for key in t.keys() {
                if !IMAGE_KEYS.contains(&key.as_str()) {
                    warnings.push(format!(
                        "{}: unknown key `{prefix}.{key}` ignored",
                        source.display()
                    ));
                }
            }
            let f = |k: &str| format!("{prefix}.{k}");
            let file =
                base.join(get_str(t, "file", &prefix).map_err(|m| field_err(&f("file"), m))?);
            let camera = get_str(t, "camera", &prefix)
                .map_err(|m| field_err(&f("camera"), m))?
                .to_string();
            let dir = get_vec3(t, "light_dir_camera")
                .map_err(|m| field_err(&f("light_dir_camera"), m))?;
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
            let irr = get_vec3(t, "irradiance").map_err(|m| field_err(&f("irradiance"), m))?;
            if irr.iter().any(|&e| e <= 0.0) {
                return Err(field_err(
                    &f("irradiance"),
                    format!(
                        "every channel must be positive (measured on the white reference), got [{}, {}, {}]",
                        irr.x, irr.y, irr.z
                    ),
                ));
            }
            let mask = match t.get("mask") {
                None => None,
                Some(toml::Value::String(s)) => Some(base.join(s)),
                Some(_) => return Err(field_err(&f("mask"), "must be a path string".into())),
            };
            light_images.push(LightImageSpec {
                file,
                camera,
                light_dir_camera: dir / norm,
                irradiance: [irr.x, irr.y, irr.z],
                mask,
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

    /// The job as TOML for a job file in the folder `base` (the inverse of [`Job::parse`]):
    /// a path inside `base` is written relative to it, any other path absolute, so the file
    /// means the same from any working folder.
    pub fn to_toml(&self, base: &Path) -> String {
        let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        let base = absolute(base);
        let rel = |p: &Path| {
            let p = absolute(p);
            p.strip_prefix(&base)
                .unwrap_or(&p)
                .to_string_lossy()
                .replace('\\', "/")
        };
        let mut s = format!(
            "mesh = {:?}\ncameras = {:?}\n",
            rel(&self.mesh),
            rel(&self.cameras)
        );
        for li in &self.light_images {
            s += &format!(
                "\n[[light_image]]\nfile = {:?}\ncamera = {:?}\nlight_dir_camera = [{:?}, {:?}, {:?}]\nirradiance = [{:?}, {:?}, {:?}]\n",
                rel(&li.file),
                li.camera,
                li.light_dir_camera.x,
                li.light_dir_camera.y,
                li.light_dir_camera.z,
                li.irradiance[0],
                li.irradiance[1],
                li.irradiance[2]
            );
            if let Some(m) = &li.mask {
                s += &format!("mask = {:?}\n", rel(m));
            }
        }
        s
    }
}

fn get_str<'a>(t: &'a toml::Table, key: &str, within: &str) -> Result<&'a str, String> {
    match t.get(key) {
        None => Err(format!("missing (required in {within})")),
        Some(toml::Value::String(s)) if !s.trim().is_empty() => Ok(s),
        Some(toml::Value::String(_)) => Err("must not be empty".into()),
        Some(v) => Err(format!("must be a string, got {}", v.type_str())),
    }
}

fn get_vec3(t: &toml::Table, key: &str) -> Result<Vector3<f64>, String> {
    let arr = match t.get(key) {
        None => return Err("missing".into()),
        Some(toml::Value::Array(a)) => a,
        Some(v) => {
            return Err(format!(
                "must be an array of 3 numbers, got {}",
                v.type_str()
            ));
        }
    };
    if arr.len() != 3 {
        return Err(format!("must have 3 numbers, has {}", arr.len()));
    }
    let mut out = [0.0; 3];
    for (o, v) in out.iter_mut().zip(arr) {
        *o = match v {
            toml::Value::Float(x) => *x,
            toml::Value::Integer(i) => *i as f64,
            other => return Err(format!("must hold numbers, found {}", other.type_str())),
        };
        if !o.is_finite() {
            return Err("must hold finite numbers".into());
        }
    }
    Ok(Vector3::from(out))
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
        assert_eq!(a.irradiance, [1.0, 2.0, 3.0]);
        assert_eq!(job.light_images[1].file, PathBuf::from("/abs/view_01.exr"));
        assert!((job.light_images[1].light_dir_camera.norm() - 1.0).abs() < 1e-12);
        assert_eq!(job.warnings.len(), 2, "{:?}", job.warnings);
        assert!(job.warnings[0].contains("future_key"));
        assert!(job.warnings[1].contains("renormalised"));
        // round trip through to_toml
        let again = Job::parse(
            &job.to_toml(Path::new("/data")),
            Path::new("/data/job.toml"),
            Path::new("/data"),
        )
        .unwrap();
        for (a, b) in again.light_images.iter().zip(&job.light_images) {
            assert_eq!(
                (&a.file, &a.camera, a.irradiance, &a.mask),
                (&b.file, &b.camera, b.irradiance, &b.mask)
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
        let bad_dir = GOOD.replace("[0.0, 0.0, -1.0]", "[0.0, 0.0, -2.0]");
        let e = err_of(&bad_dir);
        assert!(
            e.contains("light_image[0].light_dir_camera") && e.contains("unit"),
            "{e}"
        );
        let bad_irr = GOOD.replace("[1.0, 2, 3.0]", "[1.0, 0.0, 3.0]");
        assert!(err_of(&bad_irr).contains("light_image[0].irradiance"));
        let short = GOOD.replace("[1.0, 2, 3.0]", "[1.0, 2.0]");
        assert!(err_of(&short).contains("3 numbers"));
        let no_images = "mesh = \"m.ply\"\ncameras = \"s\"\n";
        assert!(err_of(no_images).contains("light_image"));
        let wrong_type = GOOD.replace("camera = \"view_00.exr\"", "camera = 7");
        assert!(err_of(&wrong_type).contains("light_image[0].camera"));
    }

    #[test]
    fn missing_file_is_named() {
        let e = Job::from_file(Path::new("/nonexistent/job.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/job.toml"), "{e}");
    }
}
