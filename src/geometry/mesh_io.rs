//! Mesh import (PLY ascii/binary via ply-rs, OBJ via tobj) and PLY export (ascii or binary).
//!
//! Conventions: PLY vertices are the `x, y, z` properties of element `vertex` (any numeric type),
//! faces the list `vertex_indices` (or `vertex_index`) of element `face`; polygons with more
//! than three corners are fan-triangulated (also in OBJ, by tobj). Other elements and
//! properties (colours, normals in the file) are ignored: normals are recomputed from the
//! geometry so every source gives the same shading. Every error names the file; content errors
//! also name the element (see [`MeshError`]). Writers are atomic (temp file, fsync, rename).
//! Depends only on `mesh`, the label colours of `labels` (and `crate::atomic`'s write).

use super::labels::label_colour;
use super::mesh::{Mesh, MeshError, MeshReport};
use crate::atomic::write_atomic;
use nalgebra::Point3;
use ply_rs::parser::Parser;
use ply_rs::ply::{Property, PropertyAccess};
use std::path::{Path, PathBuf};
use thiserror::Error;

#[derive(Debug, Error)]
pub enum MeshIoError {
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
    #[error("{path}: malformed PLY: {message}")]
    Ply { path: PathBuf, message: String },
    #[error("{path}: malformed OBJ: {source}")]
    Obj {
        path: PathBuf,
        source: tobj::LoadError,
    },
    #[error("{path}: unknown mesh extension (expected .ply or .obj)")]
    UnknownFormat { path: PathBuf },
    #[error(transparent)]
    Content(#[from] MeshError),
}

/// PLY payload encoding for [`write_ply`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyEncoding {
    Ascii,
    BinaryLittleEndian,
}

/// Loads a `.ply` or `.obj` mesh (by extension, case-insensitive) and validates it.
pub fn load_mesh(path: &Path) -> Result<(Mesh, MeshReport), MeshIoError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("ply") => load_ply(path),
        Some("obj") => load_obj(path),
        _ => Err(MeshIoError::UnknownFormat {
            path: path.to_path_buf(),
        }),
    }
}

/// One PLY element as we keep it: coordinates of a vertex or the index list of a face.
/// Implementing `PropertyAccess` ourselves avoids a hash map per element (the bunny has 100k).
#[derive(Default)]
struct PlyElem {
    xyz: [Option<f64>; 3],
    indices: Option<Vec<i64>>,
    bad_list: bool,
}

impl PropertyAccess for PlyElem {
    fn new() -> Self {
        Self::default()
    }

    fn set_property(&mut self, name: String, p: Property) {
        let axis = match name.as_str() {
            "x" => Some(0),
            "y" => Some(1),
            "z" => Some(2),
            _ => None,
        };
        if let Some(a) = axis {
            self.xyz[a] = match p {
                Property::Float(v) => Some(v as f64),
                Property::Double(v) => Some(v),
                // some scanners store integer coordinates
                Property::Char(v) => Some(v as f64),
                Property::UChar(v) => Some(v as f64),
                Property::Short(v) => Some(v as f64),
                Property::UShort(v) => Some(v as f64),
                Property::Int(v) => Some(v as f64),
                Property::UInt(v) => Some(v as f64),
                _ => None,
            };
            return;
        }
        if name == "vertex_indices" || name == "vertex_index" {
            let list: Option<Vec<i64>> = match p {
                Property::ListChar(v) => Some(v.into_iter().map(i64::from).collect()),
                Property::ListUChar(v) => Some(v.into_iter().map(i64::from).collect()),
                Property::ListShort(v) => Some(v.into_iter().map(i64::from).collect()),
                Property::ListUShort(v) => Some(v.into_iter().map(i64::from).collect()),
                Property::ListInt(v) => Some(v.into_iter().map(i64::from).collect()),
                Property::ListUInt(v) => Some(v.into_iter().map(i64::from).collect()),
                _ => None,
            };
            self.bad_list = list.is_none();
            self.indices = list;
        }
    }
}

/// Loads a PLY mesh (ascii, binary little or big endian).
pub fn load_ply(path: &Path) -> Result<(Mesh, MeshReport), MeshIoError> {
    let file = std::fs::File::open(path).map_err(|source| MeshIoError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let mut reader = std::io::BufReader::new(file);
    let ply = Parser::<PlyElem>::new()
        .read_ply(&mut reader)
        .map_err(|e| ply_err(path, e.to_string()))?;
    let vertices = ply
        .payload
        .get("vertex")
        .ok_or_else(|| ply_err(path, "no `vertex` element".into()))?;
    let faces = ply
        .payload
        .get("face")
        .ok_or_else(|| ply_err(path, "no `face` element".into()))?;
    let mut positions = Vec::with_capacity(vertices.len());
    for (i, v) in vertices.iter().enumerate() {
        match v.xyz {
            [Some(x), Some(y), Some(z)] => positions.push(Point3::new(x, y, z)),
            _ => {
                return Err(ply_err(
                    path,
                    format!("vertex {i}: needs numeric properties x, y, z"),
                ));
            }
        }
    }
    let mut tris = Vec::with_capacity(faces.len());
    for (i, f) in faces.iter().enumerate() {
        let idx = match (&f.indices, f.bad_list) {
            (Some(idx), false) => idx,
            _ => {
                return Err(ply_err(
                    path,
                    format!("face {i}: needs an integer list `vertex_indices`"),
                ));
            }
        };
        if idx.len() < 3 {
            return Err(ply_err(
                path,
                format!("face {i}: has {} corners", idx.len()),
            ));
        }
        for k in 1..idx.len() - 1 {
            tris.push([idx[0], idx[k], idx[k + 1]]);
        }
    }
    Ok(Mesh::new(positions, tris, &path.display().to_string())?)
}

fn ply_err(path: &Path, message: String) -> MeshIoError {
    MeshIoError::Ply {
        path: path.to_path_buf(),
        message,
    }
}

/// Loads an OBJ mesh: all objects merged, polygons triangulated, texture and normal indices
/// ignored (no vertex is duplicated, so curvature sees the true connectivity). tobj keeps only
/// the vertices faces use, renumbered per object: vertex ids may differ from the file's.
pub fn load_obj(path: &Path) -> Result<(Mesh, MeshReport), MeshIoError> {
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _materials) = tobj::load_obj(path, &opts).map_err(|source| match source {
        tobj::LoadError::OpenFileFailed | tobj::LoadError::ReadError => MeshIoError::Read {
            path: path.to_path_buf(),
            source: std::io::Error::other(source.to_string()),
        },
        source => MeshIoError::Obj {
            path: path.to_path_buf(),
            source,
        },
    })?;
    // tobj gives each object (`o`/`g`) its own copy of the vertices it uses, so objects sharing
    // vertices in the file would come apart at their seams (split normals, broken curvature).
    // A vertex of a later object is welded to an earlier object's vertex with bit-identical
    // coordinates: that restores the file's sharing (both copies come from the same `v` line).
    let mut positions: Vec<Point3<f64>> = Vec::new();
    let mut faces = Vec::new();
    let mut seen: std::collections::HashMap<[u32; 3], i64> = std::collections::HashMap::new();
    for m in &models {
        let mut local = Vec::with_capacity(m.mesh.positions.len() / 3);
        let mut added = Vec::new();
        for p in m.mesh.positions.chunks_exact(3) {
            let key = [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()];
            let id = match seen.get(&key) {
                Some(&id) => id,
                None => {
                    positions.push(Point3::new(p[0] as f64, p[1] as f64, p[2] as f64));
                    let id = positions.len() as i64 - 1;
                    added.push((key, id));
                    id
                }
            };
            local.push(id);
        }
        // weld across objects only: vertices within one object stay as tobj numbered them
        seen.extend(added);
        for t in m.mesh.indices.chunks_exact(3) {
            let mut tri = [0i64; 3];
            for (k, &i) in t.iter().enumerate() {
                // tobj checks indices against the file; an index past this object's vertices
                // would be a tobj bug, reported like a bad file rather than a panic
                tri[k] = local.get(i as usize).copied().unwrap_or(i64::MAX);
            }
            faces.push(tri);
        }
    }
    Ok(Mesh::new(positions, faces, &path.display().to_string())?)
}

/// Writes `mesh` as PLY: float32 `x y z nx ny nz` per vertex, `uchar`-counted `int` face lists.
///
/// Hand-written rather than ply-rs's writer: ply-rs 0.1.3 writes the element count instead of
/// the list length in binary lists, producing files nobody (itself included) can read back.
pub fn write_ply(path: &Path, mesh: &Mesh, encoding: PlyEncoding) -> Result<(), MeshIoError> {
    write_ply_with(path, mesh, None, encoding)
}

/// As [`write_ply`], with a `uchar label` per vertex and its colour (`red green blue`, from
/// [`label_colour`]) so a mesh viewer shows the labels. Labels above 255 are written as 255;
/// `labels` shorter than the vertices leaves the rest at 0.
pub fn write_ply_labelled(
    path: &Path,
    mesh: &Mesh,
    labels: &[u32],
    encoding: PlyEncoding,
) -> Result<(), MeshIoError> {
    write_ply_with(path, mesh, Some(labels), encoding)
}

fn write_ply_with(
    path: &Path,
    mesh: &Mesh,
    labels: Option<&[u32]>,
    encoding: PlyEncoding,
) -> Result<(), MeshIoError> {
    let mut out = Vec::with_capacity(36 * mesh.positions().len() + 16 * mesh.faces().len() + 256);
    let format = match encoding {
        PlyEncoding::Ascii => "ascii",
        PlyEncoding::BinaryLittleEndian => "binary_little_endian",
    };
    let label_props = if labels.is_some() {
        "property uchar label\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
    } else {
        ""
    };
    let header = format!(
        "ply\nformat {format} 1.0\ncomment written by brdf-rig\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n{label_props}\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.positions().len(),
        mesh.faces().len()
    );
    out.extend_from_slice(header.as_bytes());
    let label_of = |i: usize| -> Option<[u8; 4]> {
        let l = labels?.get(i).copied().unwrap_or(0);
        let c = label_colour(l);
        Some([u8::try_from(l).unwrap_or(u8::MAX), c[0], c[1], c[2]])
    };
    let verts = mesh
        .positions()
        .iter()
        .zip(mesh.vertex_normals())
        .enumerate();
    match encoding {
        PlyEncoding::Ascii => {
            use std::fmt::Write as _;
            let mut text = String::new();
            for (i, (p, n)) in verts {
                // `{}` on f32 prints the shortest string that reads back to the same float
                let _ = write!(
                    text,
                    "{} {} {} {} {} {}",
                    p.x as f32, p.y as f32, p.z as f32, n.x as f32, n.y as f32, n.z as f32
                );
                if let Some(l) = label_of(i) {
                    let _ = write!(text, " {} {} {} {}", l[0], l[1], l[2], l[3]);
                }
                text.push('\n');
            }
            for f in mesh.faces() {
                let _ = writeln!(text, "3 {} {} {}", f[0], f[1], f[2]);
            }
            out.extend_from_slice(text.as_bytes());
        }
        PlyEncoding::BinaryLittleEndian => {
            for (i, (p, n)) in verts {
                for v in [p.x, p.y, p.z, n.x, n.y, n.z] {
                    out.extend_from_slice(&(v as f32).to_le_bytes());
                }
                if let Some(l) = label_of(i) {
                    out.extend_from_slice(&l);
                }
            }
            for f in mesh.faces() {
                out.push(3);
                for &i in f {
                    // vertex counts above i32::MAX cannot come from `Mesh` (u32 indices from
                    // files that PLY int lists could describe); saturate rather than wrap
                    out.extend_from_slice(&i32::try_from(i).unwrap_or(i32::MAX).to_le_bytes());
                }
            }
        }
    }
    write_atomic(path, &out).map_err(|source| MeshIoError::Write {
        path: path.to_path_buf(),
        source,
    })
}
