//! Geometry from files: meshes (PLY/OBJ), COLMAP models, and the rasteriser on real meshes.

use crate::util::shared_data;
use brdf_rig::geometry::mesh::MeshError;
use brdf_rig::geometry::mesh_io::{MeshIoError, PlyEncoding, load_mesh, write_ply};

fn meshes() -> std::path::PathBuf {
    shared_data().join("meshes")
}

#[test]
fn loads_spot_and_bunny_with_counts_from_the_data_readme() {
    let (spot, r) = load_mesh(&meshes().join("spot_triangulated.obj")).unwrap();
    assert_eq!(spot.positions().len(), 2930);
    assert_eq!(spot.faces().len() + r.degenerate_faces_dropped, 5856);
    let path = meshes().join("stanford-bunny.obj");
    let (bunny, r) = load_mesh(&path).unwrap();
    // the file has 35,947 `v` lines, some unused by any face; OBJ import keeps the used ones
    let text = std::fs::read_to_string(&path).unwrap();
    let mut used = std::collections::HashSet::new();
    for l in text.lines().filter(|l| l.starts_with("f ")) {
        for t in l.split_whitespace().skip(1) {
            used.insert(t.split('/').next().unwrap().to_string());
        }
    }
    assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), 35947);
    assert_eq!(bunny.positions().len(), used.len());
    assert_eq!(bunny.faces().len() + r.degenerate_faces_dropped, 69451);
    // Spot is closed: outward normals mean the signed volume (divergence theorem) is positive.
    let vol: f64 = (0..spot.faces().len())
        .map(|f| {
            let [a, b, c] = spot.triangle(f);
            a.coords.dot(&b.coords.cross(&c.coords)) / 6.0
        })
        .sum();
    assert!(vol > 0.0, "spot volume {vol}");
}

#[test]
fn ply_round_trip_ascii_and_binary() {
    let dir = tempfile::tempdir().unwrap();
    let (spot, _) = load_mesh(&meshes().join("spot_triangulated.obj")).unwrap();
    for enc in [PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian] {
        let p = dir.path().join(format!("spot-{enc:?}.PLY"));
        write_ply(&p, &spot, enc).unwrap();
        let (back, r) = load_mesh(&p).unwrap();
        assert_eq!(r.degenerate_faces_dropped, 0);
        assert_eq!(back.faces(), spot.faces());
        for (a, b) in back.positions().iter().zip(spot.positions()) {
            // float32 storage: relative 1e-7 of coordinates of order 1
            assert!((a - b).norm() < 1e-6);
        }
    }
    // no temp files left behind by the atomic writer
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}

#[test]
fn quads_are_triangulated_and_big_endian_binary_reads() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("quad.ply");
    let mut bytes = b"ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n".to_vec();
    for v in [
        [0.0f64, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ] {
        for c in v {
            bytes.extend_from_slice(&c.to_be_bytes());
        }
    }
    bytes.push(4);
    for i in 0u32..4 {
        bytes.extend_from_slice(&i.to_be_bytes());
    }
    std::fs::write(&p, bytes).unwrap();
    let (m, _) = load_mesh(&p).unwrap();
    assert_eq!(m.faces(), &[[0, 1, 2], [0, 2, 3]]);
    for n in m.vertex_normals() {
        assert!((n.z - 1.0).abs() < 1e-12);
    }
}

fn write(dir: &std::path::Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const PLY_HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n";

#[test]
fn malformed_meshes_are_errors_naming_file_and_element() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // index out of range in the second face
    let p = write(
        d,
        "oob.ply",
        &format!("{PLY_HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 9\n"),
    );
    let e = load_mesh(&p).unwrap_err();
    assert!(
        matches!(
            &e,
            MeshIoError::Content(MeshError::IndexOutOfRange {
                face: 1,
                index: 9,
                ..
            })
        ),
        "{e}"
    );
    assert!(e.to_string().contains("oob.ply"));
    // "nan" in ascii PLY is a syntax error (line named); in binary it is a NaN vertex
    let p = write(
        d,
        "nan.ply",
        &format!("{PLY_HEAD}0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n3 0 2 1\n"),
    );
    let e = load_mesh(&p).unwrap_err();
    assert!(
        matches!(&e, MeshIoError::Ply { .. }) && e.to_string().contains("Line 11"),
        "{e}"
    );
    let p = d.join("nan-bin.ply");
    let mut bytes = PLY_HEAD
        .replace("ascii", "binary_little_endian")
        .into_bytes();
    for v in [0.0f32, 0.0, 0.0, 1.0, f32::NAN, 0.0, 0.0, 1.0, 0.0] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for f in [[0i32, 1, 2], [0, 2, 1]] {
        bytes.push(3);
        for i in f {
            bytes.extend_from_slice(&i.to_le_bytes());
        }
    }
    std::fs::write(&p, bytes).unwrap();
    let e = load_mesh(&p).unwrap_err();
    assert!(
        matches!(
            &e,
            MeshIoError::Content(MeshError::NonFiniteVertex { vertex: 1, .. })
        ),
        "{e}"
    );
    // truncated payload and garbage
    let p = write(d, "short.ply", &format!("{PLY_HEAD}0 0 0\n1 0 0\n"));
    assert!(matches!(
        load_mesh(&p).unwrap_err(),
        MeshIoError::Ply { .. }
    ));
    let p = write(d, "junk.ply", "not a ply at all\n");
    let e = load_mesh(&p).unwrap_err();
    assert!(e.to_string().contains("junk.ply"), "{e}");
    // degenerate faces are dropped and counted, not fatal
    let p = write(
        d,
        "deg.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 1 1 3\n",
    );
    let (m, r) = load_mesh(&p).unwrap();
    assert_eq!((m.faces().len(), r.degenerate_faces_dropped), (1, 2));
    // OBJ out of range, OBJ infinite vertex, missing file, unknown extension
    let p = write(d, "oob.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
    let e = load_mesh(&p).unwrap_err();
    assert!(e.to_string().contains("oob.obj"), "{e}");
    let p = write(d, "inf.obj", "v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n");
    let e = load_mesh(&p).unwrap_err();
    assert!(
        matches!(
            &e,
            MeshIoError::Content(MeshError::NonFiniteVertex { vertex: 2, .. })
        ),
        "{e}"
    );
    let e = load_mesh(&d.join("missing.ply")).unwrap_err();
    assert!(matches!(e, MeshIoError::Read { .. }));
    assert!(matches!(
        load_mesh(&d.join("x.stl")).unwrap_err(),
        MeshIoError::UnknownFormat { .. }
    ));
}
