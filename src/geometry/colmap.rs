//! COLMAP sparse models: read `cameras.txt` + `images.txt` or `cameras.bin` + `images.bin`,
//! write the text form (with an empty `points3D.txt`), so poses from photogrammetry come in and
//! the simulated capture can write what photogrammetry would give.
//!
//! Conventions are COLMAP's and match `camera`: an image's `QW QX QY QZ TX TY TZ` is the
//! `camera_from_world` rotation (Hamilton quaternion, scalar first) and translation; pixel
//! centres at half-integers. Camera models mapped onto `Intrinsics`:
//! `SIMPLE_PINHOLE f cx cy`, `PINHOLE fx fy cx cy`, `SIMPLE_RADIAL f cx cy k`,
//! `RADIAL f cx cy k1 k2`, `OPENCV fx fy cx cy k1 k2 p1 p2` (COLMAP's radial terms are OpenCV's
//! k1, k2). Other models (fisheye, FULL_OPENCV, ...) are errors naming the line.
//! Binary layout (COLMAP `model.cc`, little endian): cameras: u64 count, then per camera u32 id,
//! i32 model id, u64 width, u64 height, f64 params; images: u64 count, then per image u32 id,
//! 4 f64 quaternion, 3 f64 translation, u32 camera id, NUL-terminated name, u64 point count,
//! per point f64 x, f64 y, u64 point3D id. 2D points are skipped (poses are all we need).
//! Every error names the file and the line (text) or byte offset (binary). Quaternions are
//! normalised on read (COLMAP writes unit quaternions to 17 digits; others may not). Depends
//! only on `camera` (and `crate::atomic`'s write).

use super::camera::{Intrinsics, Pose};
use crate::atomic::write_atomic;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use thiserror::Error;

#[derive(Debug, Error)]
pub enum ColmapError {
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A bad record of a text model, at its 1-based line.
    #[error("{path}:{line}: {record}")]
    Line {
        path: PathBuf,
        line: usize,
        record: RecordError,
    },
    /// A bad record of a binary model, at the byte where the record starts (or where the file
    /// ends).
    #[error("{path}: at byte {offset}: {record}")]
    Binary {
        path: PathBuf,
        offset: usize,
        record: RecordError,
    },
    #[error("{dir}: no COLMAP model (need cameras.txt + images.txt or cameras.bin + images.bin)")]
    NoModel { dir: PathBuf },
    #[error("camera {camera}: {message}")]
    Export { camera: u32, message: String },
}

/// What is wrong with one record (a line of `cameras.txt`/`images.txt`, an entry of the binary
/// files); [`ColmapError::Line`] and [`ColmapError::Binary`] say where it is.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum RecordError {
    #[error("expected {expected}, got `{got}`")]
    Fields { expected: &'static str, got: String },
    #[error("{field}: cannot parse `{text}`")]
    Number { field: &'static str, text: String },
    #[error("unsupported camera model `{0}`")]
    ModelName(String),
    #[error("camera {camera}: unsupported model id {model_id}")]
    ModelId { camera: u32, model_id: i32 },
    #[error("camera {camera}: {model} takes {want} parameters, got {got}")]
    ParamCount {
        camera: u32,
        model: &'static str,
        want: usize,
        got: usize,
    },
    #[error("camera {camera}: non-finite parameter in {params:?}")]
    NonFiniteParam { camera: u32, params: Vec<f64> },
    #[error("camera {camera}: focal length and size must be positive")]
    NotPositive { camera: u32 },
    #[error("camera {0} defined twice")]
    DuplicateCamera(u32),
    /// A pose of a text model (the line names the image).
    #[error(transparent)]
    Pose(#[from] PoseError),
    /// A pose of a binary model, with the id of its image.
    #[error("image {image}: {pose}")]
    ImagePose { image: u32, pose: PoseError },
    #[error("image {image} refers to unknown camera {camera}")]
    UnknownCamera { image: u32, camera: u32 },
    #[error("file ends inside {0}")]
    Truncated(&'static str),
    #[error("image name not NUL-terminated")]
    NameNotTerminated,
    #[error("image name is not UTF-8")]
    NameNotUtf8,
}

/// An image pose that is not a rotation and a translation.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum PoseError {
    /// QW QX QY QZ TX TY TZ as read.
    #[error("non-finite pose {0:?}")]
    NonFinite(Vec<f64>),
    #[error("zero quaternion")]
    ZeroQuaternion,
}

/// The COLMAP camera models we map onto `Intrinsics`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraModel {
    SimplePinhole,
    Pinhole,
    SimpleRadial,
    Radial,
    Opencv,
}

impl CameraModel {
    pub fn name(self) -> &'static str {
        match self {
            Self::SimplePinhole => "SIMPLE_PINHOLE",
            Self::Pinhole => "PINHOLE",
            Self::SimpleRadial => "SIMPLE_RADIAL",
            Self::Radial => "RADIAL",
            Self::Opencv => "OPENCV",
        }
    }

    fn from_name(s: &str) -> Option<Self> {
        Some(match s {
            "SIMPLE_PINHOLE" => Self::SimplePinhole,
            "PINHOLE" => Self::Pinhole,
            "SIMPLE_RADIAL" => Self::SimpleRadial,
            "RADIAL" => Self::Radial,
            "OPENCV" => Self::Opencv,
            _ => return None,
        })
    }

    /// COLMAP's numeric model id (binary files).
    pub fn id(self) -> i32 {
        match self {
            Self::SimplePinhole => 0,
            Self::Pinhole => 1,
            Self::SimpleRadial => 2,
            Self::Radial => 3,
            Self::Opencv => 4,
        }
    }

    fn from_id(id: i32) -> Option<Self> {
        Some(match id {
            0 => Self::SimplePinhole,
            1 => Self::Pinhole,
            2 => Self::SimpleRadial,
            3 => Self::Radial,
            4 => Self::Opencv,
            _ => return None,
        })
    }

    pub fn num_params(self) -> usize {
        match self {
            Self::SimplePinhole => 3,
            Self::Pinhole => 4,
            Self::SimpleRadial => 4,
            Self::Radial => 5,
            Self::Opencv => 8,
        }
    }

    /// The simplest model that expresses `k` exactly.
    pub fn simplest_for(k: &Intrinsics) -> Self {
        let square = k.fx == k.fy;
        let radial_only = k.p1 == 0.0 && k.p2 == 0.0;
        if !k.has_distortion() {
            if square {
                Self::SimplePinhole
            } else {
                Self::Pinhole
            }
        } else if square && radial_only && k.k2 == 0.0 {
            Self::SimpleRadial
        } else if square && radial_only {
            Self::Radial
        } else {
            Self::Opencv
        }
    }

    fn intrinsics(self, width: usize, height: usize, p: &[f64]) -> Intrinsics {
        let mut k = match self {
            Self::SimplePinhole | Self::SimpleRadial | Self::Radial => {
                Intrinsics::pinhole(width, height, p[0], p[0], p[1], p[2])
            }
            Self::Pinhole | Self::Opencv => {
                Intrinsics::pinhole(width, height, p[0], p[1], p[2], p[3])
            }
        };
        match self {
            Self::SimpleRadial => k.k1 = p[3],
            Self::Radial => {
                k.k1 = p[3];
                k.k2 = p[4];
            }
            Self::Opencv => {
                k.k1 = p[4];
                k.k2 = p[5];
                k.p1 = p[6];
                k.p2 = p[7];
            }
            _ => {}
        }
        k
    }

    /// The parameters of `k` in this model; `None` when the model cannot express `k`.
    fn params(self, k: &Intrinsics) -> Option<Vec<f64>> {
        let square = k.fx == k.fy;
        let no_tangential = k.p1 == 0.0 && k.p2 == 0.0;
        match self {
            Self::SimplePinhole => (square && !k.has_distortion()).then(|| vec![k.fx, k.cx, k.cy]),
            Self::Pinhole => (!k.has_distortion()).then(|| vec![k.fx, k.fy, k.cx, k.cy]),
            Self::SimpleRadial => {
                (square && no_tangential && k.k2 == 0.0).then(|| vec![k.fx, k.cx, k.cy, k.k1])
            }
            Self::Radial => (square && no_tangential).then(|| vec![k.fx, k.cx, k.cy, k.k1, k.k2]),
            Self::Opencv => Some(vec![k.fx, k.fy, k.cx, k.cy, k.k1, k.k2, k.p1, k.p2]),
        }
    }
}

/// One camera of the model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColmapCamera {
    pub id: u32,
    pub model: CameraModel,
    pub intrinsics: Intrinsics,
}

/// One registered image: its name (path relative to the image folder), camera and pose.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapImage {
    pub id: u32,
    pub camera_id: u32,
    pub name: String,
    pub pose: Pose,
}

/// Cameras by id and images in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColmapModel {
    pub cameras: BTreeMap<u32, ColmapCamera>,
    pub images: Vec<ColmapImage>,
}

impl ColmapModel {
    /// The camera intrinsics and pose of the image called `name`.
    pub fn view(&self, name: &str) -> Option<(&Intrinsics, &Pose)> {
        let img = self.images.iter().find(|i| i.name == name)?;
        let cam = self.cameras.get(&img.camera_id)?;
        Some((&cam.intrinsics, &img.pose))
    }
}

/// Reads the model in `dir`: the text files when both exist, else the binary ones.
pub fn read_model(dir: &Path) -> Result<ColmapModel, ColmapError> {
    if dir.join("cameras.txt").is_file() && dir.join("images.txt").is_file() {
        read_text(dir)
    } else if dir.join("cameras.bin").is_file() && dir.join("images.bin").is_file() {
        read_binary(dir)
    } else {
        Err(ColmapError::NoModel {
            dir: dir.to_path_buf(),
        })
    }
}

fn read_to_string(path: &Path) -> Result<String, ColmapError> {
    std::fs::read_to_string(path).map_err(|source| ColmapError::Read {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads `cameras.txt` and `images.txt` from `dir`.
pub fn read_text(dir: &Path) -> Result<ColmapModel, ColmapError> {
    let cam_path = dir.join("cameras.txt");
    let text = read_to_string(&cam_path)?;
    let mut cameras = BTreeMap::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let err = |record: RecordError| ColmapError::Line {
            path: cam_path.clone(),
            line: i + 1,
            record,
        };
        let tok: Vec<&str> = line.split_whitespace().collect();
        if tok.len() < 4 {
            return Err(err(RecordError::Fields {
                expected: "CAMERA_ID MODEL WIDTH HEIGHT PARAMS",
                got: line.to_owned(),
            }));
        }
        let id: u32 = parse(tok[0], "CAMERA_ID").map_err(&err)?;
        let model = CameraModel::from_name(tok[1])
            .ok_or_else(|| err(RecordError::ModelName(tok[1].to_owned())))?;
        let width: usize = parse(tok[2], "WIDTH").map_err(&err)?;
        let height: usize = parse(tok[3], "HEIGHT").map_err(&err)?;
        let params: Vec<f64> = tok[4..]
            .iter()
            .map(|t| parse::<f64>(t, "parameter"))
            .collect::<Result<_, _>>()
            .map_err(&err)?;
        let cam = make_camera(id, model, width, height, &params).map_err(&err)?;
        if cameras.insert(id, cam).is_some() {
            return Err(err(RecordError::DuplicateCamera(id)));
        }
    }

    let img_path = dir.join("images.txt");
    let text = read_to_string(&img_path)?;
    let mut images = Vec::new();
    let mut lines = text.lines().enumerate();
    while let Some((i, raw)) = lines.next() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let err = |record: RecordError| ColmapError::Line {
            path: img_path.clone(),
            line: i + 1,
            record,
        };
        let tok: Vec<&str> = line.split_whitespace().collect();
        if tok.len() < 10 {
            return Err(err(RecordError::Fields {
                expected: "IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME",
                got: line.to_owned(),
            }));
        }
        let id: u32 = parse(tok[0], "IMAGE_ID").map_err(&err)?;
        let mut v = [0.0; 7];
        for (k, t) in tok[1..8].iter().enumerate() {
            v[k] = parse(t, ["QW", "QX", "QY", "QZ", "TX", "TY", "TZ"][k]).map_err(&err)?;
        }
        let camera_id: u32 = parse(tok[8], "CAMERA_ID").map_err(&err)?;
        let name = tok[9..].join(" ");
        let pose = make_pose(&v).map_err(|e| err(e.into()))?;
        if !cameras.contains_key(&camera_id) {
            return Err(err(RecordError::UnknownCamera {
                image: id,
                camera: camera_id,
            }));
        }
        images.push(ColmapImage {
            id,
            camera_id,
            name,
            pose,
        });
        // the POINTS2D line follows (possibly empty); its content is not needed
        lines.next();
    }
    Ok(ColmapModel { cameras, images })
}

fn parse<T: std::str::FromStr>(s: &str, field: &'static str) -> Result<T, RecordError> {
    s.parse().map_err(|_| RecordError::Number {
        field,
        text: s.to_owned(),
    })
}

fn make_camera(
    id: u32,
    model: CameraModel,
    width: usize,
    height: usize,
    params: &[f64],
) -> Result<ColmapCamera, RecordError> {
    if params.len() != model.num_params() {
        return Err(RecordError::ParamCount {
            camera: id,
            model: model.name(),
            want: model.num_params(),
            got: params.len(),
        });
    }
    if params.iter().any(|p| !p.is_finite()) {
        return Err(RecordError::NonFiniteParam {
            camera: id,
            params: params.to_vec(),
        });
    }
    let k = model.intrinsics(width, height, params);
    if k.fx <= 0.0 || k.fy <= 0.0 || width == 0 || height == 0 {
        return Err(RecordError::NotPositive { camera: id });
    }
    Ok(ColmapCamera {
        id,
        model,
        intrinsics: k,
    })
}

fn make_pose(v: &[f64; 7]) -> Result<Pose, PoseError> {
    if v.iter().any(|x| !x.is_finite()) {
        return Err(PoseError::NonFinite(v.to_vec()));
    }
    let q = Quaternion::new(v[0], v[1], v[2], v[3]);
    if q.norm() < 1e-9 {
        return Err(PoseError::ZeroQuaternion);
    }
    Ok(Pose {
        rotation: UnitQuaternion::from_quaternion(q),
        translation: Vector3::new(v[4], v[5], v[6]),
    })
}

/// A bounds-checked little-endian reader naming the byte offset in its errors.
struct BinReader<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    pos: usize,
}

impl BinReader<'_> {
    fn err(&self, offset: usize, record: RecordError) -> ColmapError {
        ColmapError::Binary {
            path: self.path.to_path_buf(),
            offset,
            record,
        }
    }

    fn take<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], ColmapError> {
        let end = self.pos.checked_add(N).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err(self.err(self.pos, RecordError::Truncated(what)));
        };
        let mut out = [0u8; N];
        out.copy_from_slice(&self.bytes[self.pos..end]);
        self.pos = end;
        Ok(out)
    }

    fn u32(&mut self, what: &'static str) -> Result<u32, ColmapError> {
        Ok(u32::from_le_bytes(self.take(what)?))
    }
    fn i32(&mut self, what: &'static str) -> Result<i32, ColmapError> {
        Ok(i32::from_le_bytes(self.take(what)?))
    }
    fn u64(&mut self, what: &'static str) -> Result<u64, ColmapError> {
        Ok(u64::from_le_bytes(self.take(what)?))
    }
    fn f64(&mut self, what: &'static str) -> Result<f64, ColmapError> {
        Ok(f64::from_le_bytes(self.take(what)?))
    }

    fn skip(&mut self, n: u64, what: &'static str) -> Result<(), ColmapError> {
        let end = usize::try_from(n)
            .ok()
            .and_then(|n| self.pos.checked_add(n))
            .filter(|&e| e <= self.bytes.len());
        match end {
            Some(e) => {
                self.pos = e;
                Ok(())
            }
            None => Err(self.err(self.pos, RecordError::Truncated(what))),
        }
    }

    fn cstring(&mut self) -> Result<String, ColmapError> {
        let start = self.pos;
        let Some(len) = self.bytes[start..].iter().position(|&b| b == 0) else {
            return Err(self.err(start, RecordError::NameNotTerminated));
        };
        self.pos = start + len + 1;
        String::from_utf8(self.bytes[start..start + len].to_vec())
            .map_err(|_| self.err(start, RecordError::NameNotUtf8))
    }
}

fn read_bytes(path: &Path) -> Result<Vec<u8>, ColmapError> {
    std::fs::read(path).map_err(|source| ColmapError::Read {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads `cameras.bin` and `images.bin` from `dir`.
pub fn read_binary(dir: &Path) -> Result<ColmapModel, ColmapError> {
    let cam_path = dir.join("cameras.bin");
    let bytes = read_bytes(&cam_path)?;
    let mut r = BinReader {
        path: &cam_path,
        bytes: &bytes,
        pos: 0,
    };
    let n = r.u64("the camera count")?;
    let mut cameras = BTreeMap::new();
    for _ in 0..n {
        let at = r.pos;
        let id = r.u32("a camera id")?;
        let model_id = r.i32("a model id")?;
        let model = CameraModel::from_id(model_id).ok_or_else(|| {
            r.err(
                at,
                RecordError::ModelId {
                    camera: id,
                    model_id,
                },
            )
        })?;
        let width = r.u64("a width")?;
        let height = r.u64("a height")?;
        let mut params = Vec::with_capacity(model.num_params());
        for _ in 0..model.num_params() {
            params.push(r.f64("camera parameters")?);
        }
        let cam = make_camera(id, model, width as usize, height as usize, &params)
            .map_err(|m| r.err(at, m))?;
        cameras.insert(id, cam);
    }

    let img_path = dir.join("images.bin");
    let bytes = read_bytes(&img_path)?;
    let mut r = BinReader {
        path: &img_path,
        bytes: &bytes,
        pos: 0,
    };
    let n = r.u64("the image count")?;
    let mut images = Vec::new();
    for _ in 0..n {
        let at = r.pos;
        let id = r.u32("an image id")?;
        let mut v = [0.0; 7];
        for x in &mut v {
            *x = r.f64("a pose")?;
        }
        let camera_id = r.u32("a camera id")?;
        let name = r.cstring()?;
        let points = r.u64("the 2D point count")?;
        r.skip(points.saturating_mul(24), "the 2D points")?;
        let pose =
            make_pose(&v).map_err(|pose| r.err(at, RecordError::ImagePose { image: id, pose }))?;
        if !cameras.contains_key(&camera_id) {
            return Err(r.err(
                at,
                RecordError::UnknownCamera {
                    image: id,
                    camera: camera_id,
                },
            ));
        }
        images.push(ColmapImage {
            id,
            camera_id,
            name,
            pose,
        });
    }
    Ok(ColmapModel { cameras, images })
}

/// Writes `cameras.txt`, `images.txt` (no 2D points) and an empty `points3D.txt` into `dir`
/// (which must exist), each atomically. Numbers are written in Rust's shortest round-trip form,
/// so reading back gives the same `f64`s.
pub fn write_text(dir: &Path, model: &ColmapModel) -> Result<(), ColmapError> {
    use std::fmt::Write as _;
    let mut cams = String::from(
        "# Camera list with one line of data per camera:\n\
         #   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n",
    );
    let _ = writeln!(cams, "# Number of cameras: {}", model.cameras.len());
    for cam in model.cameras.values() {
        let params = cam
            .model
            .params(&cam.intrinsics)
            .ok_or_else(|| ColmapError::Export {
                camera: cam.id,
                message: format!(
                    "model {} cannot express {:?}",
                    cam.model.name(),
                    cam.intrinsics
                ),
            })?;
        let k = &cam.intrinsics;
        let _ = write!(
            cams,
            "{} {} {} {}",
            cam.id,
            cam.model.name(),
            k.width,
            k.height
        );
        for p in params {
            let _ = write!(cams, " {p:?}");
        }
        cams.push('\n');
    }
    let mut imgs = String::from(
        "# Image list with two lines of data per image:\n\
         #   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n\
         #   POINTS2D[] as (X, Y, POINT3D_ID)\n",
    );
    let _ = writeln!(
        imgs,
        "# Number of images: {}, mean observations per image: 0",
        model.images.len()
    );
    for img in &model.images {
        if img.name.is_empty() || img.name.chars().any(char::is_whitespace) {
            return Err(ColmapError::Export {
                camera: img.camera_id,
                message: format!(
                    "image {}: name `{}` is empty or has whitespace",
                    img.id, img.name
                ),
            });
        }
        let q = img.pose.rotation.quaternion();
        let t = img.pose.translation;
        let _ = writeln!(
            imgs,
            "{} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {} {}\n",
            img.id, q.w, q.i, q.j, q.k, t.x, t.y, t.z, img.camera_id, img.name
        );
    }
    let points = "# 3D point list with one line of data per point:\n\
                  #   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n\
                  # Number of points: 0, mean track length: 0\n";
    for (name, text) in [
        ("cameras.txt", cams.as_str()),
        ("images.txt", imgs.as_str()),
        ("points3D.txt", points),
    ] {
        let path = dir.join(name);
        write_atomic(&path, text.as_bytes())
            .map_err(|source| ColmapError::Write { path, source })?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bad_text_record_names_its_line_and_field() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("cameras.txt"),
            "# a comment\n1 PINHOLE 64 48 50 50 32 24\n2 PINHOLE wide 48 50 50 32 24\n",
        )
        .unwrap();
        std::fs::write(dir.path().join("images.txt"), "").unwrap();
        let e = read_text(dir.path()).unwrap_err();
        let ColmapError::Line { line, record, .. } = &e else {
            panic!("{e}");
        };
        assert_eq!(*line, 3);
        assert_eq!(
            *record,
            RecordError::Number {
                field: "WIDTH",
                text: "wide".into()
            }
        );
        assert!(
            e.to_string()
                .ends_with("cameras.txt:3: WIDTH: cannot parse `wide`"),
            "{e}"
        );
    }

    #[test]
    fn a_bad_binary_pose_names_its_image() {
        let e = RecordError::ImagePose {
            image: 7,
            pose: PoseError::ZeroQuaternion,
        };
        assert_eq!(e.to_string(), "image 7: zero quaternion");
    }
}
