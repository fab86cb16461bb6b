//! The meshes the evaluations run on, by name: `spot` (Keenan Crane's Spot) and `bunny` (the
//! Stanford Bunny) from the data folder, or any mesh file by its path.

use crate::data::data_dir;
use crate::geometry::mesh::Mesh;
use crate::geometry::mesh_io::{MeshIoError, load_mesh};
use std::path::PathBuf;

/// The mesh `name` names (`spot`, `bunny`, or a path) and its label in tables (the name, or
/// the file's stem).
pub fn load_named_mesh(name: &str) -> Result<(String, Mesh), MeshIoError> {
    let data = data_dir().join("meshes");
    let path = match name {
        "spot" => data.join("spot_triangulated.obj"),
        "bunny" => data.join("stanford-bunny.obj"),
        other => PathBuf::from(other),
    };
    let (mesh, _) = load_mesh(&path)?;
    let label = match name {
        "spot" | "bunny" => name.to_string(),
        _ => path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| name.to_string()),
    };
    Ok((label, mesh))
}
