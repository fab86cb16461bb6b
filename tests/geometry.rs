//! Geometry from files: meshes (PLY/OBJ), COLMAP models, and the rasteriser on real meshes.

use crate::util::shared_data;
use brdf_rig::geometry::mesh::MeshError;
use brdf_rig::geometry::mesh_io::{
    MeshIoError, PlyEncoding, load_mesh, write_ply, write_ply_labelled,
};

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
fn labelled_ply_reads_back_with_its_labels() {
    let dir = tempfile::tempdir().unwrap();
    let (spot, _) = load_mesh(&meshes().join("spot_triangulated.obj")).unwrap();
    let labels: Vec<u32> = (0..spot.positions().len())
        .map(|i| (i % 3) as u32)
        .collect();
    for enc in [PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian] {
        let p = dir.path().join(format!("map-{enc:?}.ply"));
        write_ply_labelled(&p, &spot, &labels, enc).unwrap();
        // our reader ignores the extra properties
        let (back, _) = load_mesh(&p).unwrap();
        assert_eq!(back.faces(), spot.faces());
        // a peer reader (ply-rs's parser) sees the labels
        let mut f = std::io::BufReader::new(std::fs::File::open(&p).unwrap());
        let ply = ply_rs::parser::Parser::<ply_rs::ply::DefaultElement>::new()
            .read_ply(&mut f)
            .unwrap();
        let verts = &ply.payload["vertex"];
        assert_eq!(verts.len(), labels.len());
        for (v, &l) in verts.iter().zip(&labels) {
            assert_eq!(v["label"], ply_rs::ply::Property::UChar(l as u8));
        }
    }
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
    // integer coordinates (some scanners) and a `vertex_index` list with extra properties
    let p = write(
        dir.path(),
        "int.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty int x\nproperty short y\n\
         property uchar z\nproperty uchar red\nelement face 1\n\
         property list uchar ushort vertex_index\nproperty int flags\nend_header\n\
         0 0 0 255\n2 0 0 255\n0 3 1 255\n3 0 1 2 7\n",
    );
    let (m, _) = load_mesh(&p).unwrap();
    assert_eq!(m.positions()[2], Point3::new(0.0, 3.0, 1.0));
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

// ---------------------------------------------------------------------------------------------
// Analytic meshes shared with the render tests

use brdf_rig::geometry::bvh::Bvh;
use brdf_rig::geometry::camera::{Intrinsics, Pose};
use brdf_rig::geometry::mesh::Mesh;
use brdf_rig::geometry::raster::{Rasteriser, rasterise};
use brdf_rig::geometry::shadow::shadow_mask;
use nalgebra::{Point3, Vector3};

/// An axis-aligned square `[x0, x1] x [y0, y1]` at height `z`, facing +z, as an n x n grid.
pub fn grid(
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
    z: f64,
    n: usize,
) -> (Vec<Point3<f64>>, Vec<[i64; 3]>) {
    let mut p = Vec::new();
    let mut f = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (s, t) = (i as f64 / n as f64, j as f64 / n as f64);
            p.push(Point3::new(x0 + s * (x1 - x0), y0 + t * (y1 - y0), z));
        }
    }
    let id = |i: usize, j: usize| (j * (n + 1) + i) as i64;
    for j in 0..n {
        for i in 0..n {
            f.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            f.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    (p, f)
}

/// A UV sphere of radius `r` (`geometry::mesh::uv_sphere`).
pub fn uv_sphere(r: f64, rings: usize, segments: usize) -> Mesh {
    brdf_rig::geometry::mesh::uv_sphere(r, rings, segments).unwrap()
}

#[test]
fn rasterised_square_covers_exactly_its_projection_at_its_depth() {
    // square [-0.5, 0.5]^2 at z = 0, camera 4 units up the z axis looking down
    let (p, f) = grid(-0.5, 0.5, -0.5, 0.5, 0.0, 4);
    let (mesh, _) = Mesh::new(p, f, "<grid>").unwrap();
    let bvh = Bvh::build(&mesh);
    let k = Intrinsics::pinhole(96, 72, 80.0, 80.0, 48.0, 36.0);
    let pose = Pose::look_at(Point3::new(0.0, 0.0, 4.0), Point3::origin(), Vector3::y());
    let g = rasterise(&mesh, &bvh, &k, &pose, None);
    // the square's half width in pixels: fx * 0.5 / 4 = 10
    let mut checked = 0;
    for y in 0..72 {
        for x in 0..96 {
            let (dx, dy) = ((x as f64 + 0.5 - 48.0).abs(), (y as f64 + 0.5 - 36.0).abs());
            let inside = dx < 10.0 && dy < 10.0;
            let frag = g.get(x, y);
            assert_eq!(frag.is_some(), inside, "pixel {x},{y}");
            if let Some(fr) = frag {
                checked += 1;
                assert!((fr.depth - 4.0).abs() < 1e-12);
                assert!(fr.position.z.abs() < 1e-12);
                assert!((fr.normal - Vector3::z()).norm() < 1e-12);
                assert!((fr.bary.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            }
        }
    }
    assert_eq!(checked, 400);
    assert_eq!(g.covered(), 400);
    // single sub-pixel queries agree with the G-buffer and land where they were asked
    let r = Rasteriser::new(&mesh, &bvh, &k, &pose, None);
    assert_eq!(r.fragment(50.5, 30.5).as_ref(), g.get(50, 30));
    let f = r.fragment(52.3, 31.9).unwrap();
    let (px, py) = k.project(&pose.camera_from_world(&f.position)).unwrap();
    assert!((px - 52.3).abs() < 1e-9 && (py - 31.9).abs() < 1e-9);
    assert!(r.fragment(10.0, 10.0).is_none());
}

#[test]
fn bunny_fragments_reproject_to_their_pixel_centres_even_with_distortion() {
    let (bunny, _) = load_mesh(&meshes().join("stanford-bunny.obj")).unwrap();
    let bvh = Bvh::build(&bunny);
    let (lo, hi) = bunny.bounds();
    let c = Point3::from((lo.coords + hi.coords) / 2.0);
    let eye = c + Vector3::new(0.3, 0.1, 0.6) * (bunny.diagonal() * 2.0);
    let pose = Pose::look_at(eye, c, Vector3::y());
    let mut k = Intrinsics::pinhole(96, 72, 110.0, 110.0, 47.0, 37.0);
    k.k1 = -0.08;
    k.p2 = 0.002;
    let g = rasterise(&bunny, &bvh, &k, &pose, None);
    assert!(g.covered() > 500, "bunny covers {} pixels", g.covered());
    for y in 0..72 {
        for x in 0..96 {
            if let Some(fr) = g.get(x, y) {
                let pc = pose.camera_from_world(&fr.position);
                let (px, py) = k.project(&pc).unwrap();
                assert!((px - x as f64 - 0.5).abs() < 1e-6 && (py - y as f64 - 0.5).abs() < 1e-6);
                assert!((pc.z - fr.depth).abs() < 1e-9);
                // the hit lies on its face (barycentric blend of the corners)
                let t = bunny.triangle(fr.face as usize);
                let q: Vector3<f64> = (0..3).map(|i| t[i].coords * fr.bary[i]).sum();
                assert!((q - fr.position.coords).norm() < 1e-9);
            }
        }
    }
}

#[test]
fn an_occluder_casts_its_footprint_as_shadow() {
    // floor [-2, 2]^2 at z = 0, occluder [-0.5, 0.5]^2 at z = 1, light straight above
    let (mut p, mut f) = grid(-2.0, 2.0, -2.0, 2.0, 0.0, 8);
    let (p2, f2) = grid(-0.5, 0.5, -0.5, 0.5, 1.0, 2);
    let base = p.len() as i64;
    p.extend(p2);
    f.extend(f2.into_iter().map(|t| t.map(|i| i + base)));
    let (mesh, _) = Mesh::new(p, f, "<floor>").unwrap();
    let bvh = Bvh::build(&mesh);
    // oblique camera so the floor under the occluder is partly visible
    let eye = Point3::new(3.0, 0.5, 3.0);
    let pose = Pose::look_at(eye, Point3::origin(), Vector3::z());
    let k = Intrinsics::pinhole(96, 72, 60.0, 60.0, 48.0, 36.0);
    let g = rasterise(&mesh, &bvh, &k, &pose, None);
    let up = Vector3::z();
    let mask = shadow_mask(&mesh, &bvh, &g, &eye, &up);
    let (mut lit, mut dark) = (0, 0);
    for (frag, m) in g.fragments().iter().zip(&mask) {
        let Some(fr) = frag else { continue };
        let m = m.unwrap();
        let q = fr.position;
        if q.z > 0.5 {
            assert!(m, "occluder top is lit");
            continue;
        }
        let margin = (q.x.abs().max(q.y.abs()) - 0.5).abs();
        if margin < 0.02 {
            continue; // pixel centres too close to the footprint's edge to call
        }
        let under = q.x.abs() < 0.5 && q.y.abs() < 0.5;
        assert_eq!(m, !under, "floor point {q:?}");
        if m { lit += 1 } else { dark += 1 }
    }
    assert!(lit > 100 && dark > 20, "lit {lit} dark {dark}");
    // a light below the floor: every floor pixel is turned away from it
    let mask = shadow_mask(&mesh, &bvh, &g, &eye, &-up);
    assert!(mask.iter().flatten().all(|m| !m));
}

use brdf_rig::geometry::curvature::principal_curvatures;

/// An open cylinder of radius `r` along z, `rings` x `segments` quads over length `len`, each
/// vertex moved along the surface by up to `jitter` of a cell (seeded), so the tessellation is
/// irregular but every vertex lies exactly on the cylinder.
pub fn cylinder(r: f64, len: f64, rings: usize, segments: usize, jitter: f64) -> Mesh {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let mut p = Vec::new();
    for i in 0..=rings {
        for j in 0..segments {
            let dj = jitter * rng.gen_range(-1.0..1.0);
            let di = if i == 0 || i == rings {
                0.0
            } else {
                jitter * rng.gen_range(-1.0..1.0)
            };
            let ph = std::f64::consts::TAU * (j as f64 + dj) / segments as f64;
            let z = len * ((i as f64 + di) / rings as f64 - 0.5);
            p.push(Point3::new(r * ph.cos(), r * ph.sin(), z));
        }
    }
    let id = |i: usize, j: usize| (i * segments + j % segments) as i64;
    let mut f = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            f.push([id(i, j), id(i, j + 1), id(i + 1, j + 1)]);
            f.push([id(i, j), id(i + 1, j + 1), id(i + 1, j)]);
        }
    }
    Mesh::new(p, f, "<cylinder>").unwrap().0
}

#[test]
fn curvature_of_a_sphere_is_one_over_r_everywhere() {
    // tolerance 2%: the estimator's error on a regular tessellation of this density
    let r = 2.0;
    let s = uv_sphere(r, 40, 80);
    let c = principal_curvatures(&s);
    for i in 0..s.positions().len() {
        assert!(
            (c.mean[i] * r - 1.0).abs() < 0.02,
            "vertex {i}: H = {}",
            c.mean[i]
        );
        assert!((c.k_max[i] * r - 1.0).abs() < 0.02 && (c.k_min[i] * r - 1.0).abs() < 0.02);
    }
}

/// Worst and RMS relative error of `H 2r` and worst `|k_min| r` and `1 - |dir_min . z|` over the
/// cylinder's vertices away from its open ends (one-sided neighbourhoods there), and mean `H 2r`.
fn cylinder_errors(cyl: &Mesh, r: f64) -> (f64, f64, f64, f64, f64) {
    let c = principal_curvatures(cyl);
    let inner: Vec<usize> = (0..cyl.positions().len())
        .filter(|&i| cyl.positions()[i].z.abs() <= 1.7)
        .collect();
    assert!(inner.len() > 1000);
    let rel: Vec<f64> = inner.iter().map(|&i| c.mean[i] * 2.0 * r - 1.0).collect();
    let worst = rel.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let rms = (rel.iter().map(|e| e * e).sum::<f64>() / rel.len() as f64).sqrt();
    let mean = 1.0 + rel.iter().sum::<f64>() / rel.len() as f64;
    let kmin = inner
        .iter()
        .fold(0.0f64, |m, &i| m.max(c.k_min[i].abs() * r));
    let dir = inner
        .iter()
        .fold(0.0f64, |m, &i| m.max(1.0 - c.dir_min[i].z.abs()));
    (worst, rms, mean, kmin, dir)
}

#[test]
fn curvature_of_a_cylinder_is_one_over_2r_with_the_axis_as_minimum_direction() {
    let r = 0.5;
    // regular tessellation: symmetric neighbourhoods make the estimate exact to rounding
    let (worst, _, _, kmin, dir) = cylinder_errors(&cylinder(r, 4.0, 80, 64, 0.0), r);
    assert!(
        worst < 1e-9 && kmin < 1e-9 && dir < 1e-9,
        "{worst} {kmin} {dir}"
    );
    // irregular (vertices moved up to 0.2 cell along the surface): measured worst 8.5%, RMS
    // 2.1%, mean +0.01%. Tolerances: worst 10%, RMS 3%, mean 0.5% (no bias), k_min r 0.07,
    // principal direction within 0.005 of the axis in 1 - cos
    let cyl = cylinder(r, 4.0, 80, 64, 0.2);
    let (worst, rms, mean, kmin, dir) = cylinder_errors(&cyl, r);
    assert!(worst < 0.10 && rms < 0.03, "worst {worst}, rms {rms}");
    assert!((mean - 1.0).abs() < 0.005, "mean H 2r = {mean}");
    assert!(
        kmin < 0.07 && dir < 0.005,
        "k_min r {kmin}, direction {dir}"
    );
    // reversing the winding flips the normals and the sign
    let c = principal_curvatures(&cyl);
    let faces: Vec<[i64; 3]> = cyl
        .faces()
        .iter()
        .map(|f| [f[0] as i64, f[2] as i64, f[1] as i64])
        .collect();
    let (flipped, _) = Mesh::new(cyl.positions().to_vec(), faces, "<flipped>").unwrap();
    let cf = principal_curvatures(&flipped);
    for i in (0..cyl.positions().len()).step_by(97) {
        assert!((cf.mean[i] + c.mean[i]).abs() < 1e-9);
    }
}

// ---------------------------------------------------------------------------------------------
// COLMAP models

use brdf_rig::geometry::colmap::{
    CameraModel, ColmapCamera, ColmapError, ColmapImage, ColmapModel, read_model, write_text,
};
use nalgebra::UnitQuaternion;

fn sample_model() -> ColmapModel {
    let mut m = ColmapModel::default();
    let mut k = Intrinsics::pinhole(640, 480, 500.25, 500.25, 320.5, 239.75);
    for (id, model) in [
        (1, CameraModel::SimplePinhole),
        (2, CameraModel::Pinhole),
        (3, CameraModel::SimpleRadial),
        (4, CameraModel::Radial),
        (5, CameraModel::Opencv),
    ] {
        match model {
            CameraModel::Pinhole => k.fy = 501.125,
            CameraModel::SimpleRadial => {
                k.fy = k.fx;
                k.k1 = -0.0123;
            }
            CameraModel::Radial => k.k2 = 0.0045,
            CameraModel::Opencv => {
                k.fy = 498.0;
                k.p1 = 1e-4;
                k.p2 = -2e-4;
            }
            CameraModel::SimplePinhole => {}
        }
        assert_eq!(CameraModel::simplest_for(&k), model);
        m.cameras.insert(
            id,
            ColmapCamera {
                id,
                model,
                intrinsics: k,
            },
        );
    }
    for i in 0..7u32 {
        let a = i as f64 * 0.7;
        let rotation = UnitQuaternion::from_euler_angles(0.1 * a, a, -0.3 * a);
        m.images.push(ColmapImage {
            id: 10 + i,
            camera_id: 1 + i % 5,
            name: format!("light/view_{i:03}.exr"),
            pose: Pose {
                rotation,
                translation: Vector3::new(a.sin(), 0.25 * a, 3.0 + a.cos()),
            },
        });
    }
    m
}

fn assert_models_equal(a: &ColmapModel, b: &ColmapModel) {
    assert_eq!(a.cameras, b.cameras);
    assert_eq!(a.images.len(), b.images.len());
    for (x, y) in a.images.iter().zip(&b.images) {
        assert_eq!((x.id, x.camera_id, &x.name), (y.id, y.camera_id, &y.name));
        assert!(x.pose.rotation.angle_to(&y.pose.rotation) < 1e-12);
        assert_eq!(x.pose.translation, y.pose.translation);
    }
}

#[test]
fn colmap_text_round_trip_keeps_every_model_and_pose() {
    let dir = tempfile::tempdir().unwrap();
    let m = sample_model();
    write_text(dir.path(), &m).unwrap();
    assert!(dir.path().join("points3D.txt").is_file());
    let back = read_model(dir.path()).unwrap();
    assert_models_equal(&m, &back);
    let (k, pose) = back.view("light/view_003.exr").unwrap();
    assert_eq!(k, &m.cameras[&4].intrinsics);
    assert_eq!(pose.translation, m.images[3].pose.translation);
    assert!(back.view("nope.exr").is_none());
}

#[test]
fn colmap_simple_radial_projects_as_colmap_defines_it() {
    // COLMAP SIMPLE_RADIAL: u = x/z, v = y/z, d = 1 + k (u^2 + v^2), pixel = f d (u, v) + c
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("cameras.txt"),
        "# c\n7 SIMPLE_RADIAL 100 80 90 50.5 40.25 -0.2\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("images.txt"),
        "# i\n1 1 0 0 0 0.5 -0.25 2 7 a.png\n1.0 2.0 -1\n",
    )
    .unwrap();
    let m = read_model(dir.path()).unwrap();
    let (k, pose) = m.view("a.png").unwrap();
    let pw = Point3::new(0.3, 0.2, 1.0);
    let pc = Vector3::new(0.3 + 0.5, 0.2 - 0.25, 1.0 + 2.0);
    assert!((pose.camera_from_world(&pw) - pc).norm() < 1e-15);
    let (u, v) = (pc.x / pc.z, pc.y / pc.z);
    let d = 1.0 - 0.2 * (u * u + v * v);
    let (px, py) = k.project(&pc).unwrap();
    assert!(
        (px - (90.0 * d * u + 50.5)).abs() < 1e-12 && (py - (90.0 * d * v + 40.25)).abs() < 1e-12
    );
}

/// Writes the binary model the way COLMAP's `WriteCamerasBinary`/`WriteImagesBinary` do.
fn write_colmap_binary(dir: &std::path::Path, m: &ColmapModel) {
    let mut c = Vec::new();
    c.extend_from_slice(&(m.cameras.len() as u64).to_le_bytes());
    for cam in m.cameras.values() {
        let k = &cam.intrinsics;
        c.extend_from_slice(&cam.id.to_le_bytes());
        c.extend_from_slice(&cam.model.id().to_le_bytes());
        c.extend_from_slice(&(k.width as u64).to_le_bytes());
        c.extend_from_slice(&(k.height as u64).to_le_bytes());
        let p: Vec<f64> = match cam.model {
            CameraModel::SimplePinhole => vec![k.fx, k.cx, k.cy],
            CameraModel::Pinhole => vec![k.fx, k.fy, k.cx, k.cy],
            CameraModel::SimpleRadial => vec![k.fx, k.cx, k.cy, k.k1],
            CameraModel::Radial => vec![k.fx, k.cx, k.cy, k.k1, k.k2],
            CameraModel::Opencv => vec![k.fx, k.fy, k.cx, k.cy, k.k1, k.k2, k.p1, k.p2],
        };
        for v in p {
            c.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(dir.join("cameras.bin"), c).unwrap();
    let mut b = Vec::new();
    b.extend_from_slice(&(m.images.len() as u64).to_le_bytes());
    for img in &m.images {
        b.extend_from_slice(&img.id.to_le_bytes());
        let q = img.pose.rotation.quaternion();
        let t = img.pose.translation;
        for v in [q.w, q.i, q.j, q.k, t.x, t.y, t.z] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&img.camera_id.to_le_bytes());
        b.extend_from_slice(img.name.as_bytes());
        b.push(0);
        // two 2D points, one without a 3D point (id -1 as u64::MAX)
        b.extend_from_slice(&2u64.to_le_bytes());
        for (x, y, id) in [(1.5f64, 2.5f64, 4u64), (3.0, 4.0, u64::MAX)] {
            b.extend_from_slice(&x.to_le_bytes());
            b.extend_from_slice(&y.to_le_bytes());
            b.extend_from_slice(&id.to_le_bytes());
        }
    }
    std::fs::write(dir.join("images.bin"), b).unwrap();
}

#[test]
fn colmap_binary_model_reads_and_truncation_names_the_offset() {
    let dir = tempfile::tempdir().unwrap();
    let m = sample_model();
    write_colmap_binary(dir.path(), &m);
    let back = read_model(dir.path()).unwrap();
    assert_models_equal(&m, &back);
    // truncate images.bin in the middle of the third image
    let p = dir.path().join("images.bin");
    let bytes = std::fs::read(&p).unwrap();
    let per_image = 4 + 56 + 4 + "light/view_000.exr".len() + 1 + 8 + 48;
    std::fs::write(&p, &bytes[..8 + 2 * per_image + 30]).unwrap();
    let e = read_model(dir.path()).unwrap_err();
    match &e {
        ColmapError::Binary { path, offset, .. } => {
            assert!(path.ends_with("images.bin"));
            assert_eq!(*offset, 8 + 2 * per_image + 28); // start of the unfinished f64
        }
        other => panic!("{other}"),
    }
    assert!(e.to_string().contains("images.bin"));
    // unsupported model id 5 (OPENCV_FISHEYE)
    let p = dir.path().join("cameras.bin");
    let mut bytes = std::fs::read(&p).unwrap();
    bytes[12..16].copy_from_slice(&5i32.to_le_bytes());
    std::fs::write(&p, bytes).unwrap();
    let e = read_model(dir.path()).unwrap_err();
    assert!(
        matches!(&e, ColmapError::Binary { offset: 8, .. }) && e.to_string().contains("model id 5"),
        "{e}"
    );
}

#[test]
fn colmap_malformed_text_names_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cams = "# header\n#\n1 PINHOLE 640 480 500 500 320 240\n";
    let imgs_ok = "# header\n1 1 0 0 0 0 0 0 1 a.png\n\n2 1 0 0 0 0 0 1 1 b.png\n\n";
    let cases: [(&str, &str, &str, &str); 6] = [
        (
            "1 PINHOLE 640 480 500 500 320\n",
            imgs_ok,
            "cameras.txt:1",
            "takes 4 parameters",
        ),
        (
            "# x\n1 OPENCV_FISHEYE 640 480 1 1 1 1 0 0 0 0\n",
            imgs_ok,
            "cameras.txt:2",
            "unsupported camera model",
        ),
        (
            "1 PINHOLE 640 abc 500 500 320 240\n",
            imgs_ok,
            "cameras.txt:1",
            "HEIGHT",
        ),
        (
            cams,
            "# h\n1 1 0 0 0 0 0 zero 1 a.png\n\n",
            "images.txt:2",
            "TZ",
        ),
        (
            cams,
            "1 1 0 0 0 0 0 0 1 a.png\n\n2 1 0 0 0 0 0 0 9 b.png\n\n",
            "images.txt:3",
            "unknown camera 9",
        ),
        (
            cams,
            "1 0 0 0 0 0 0 0 1 a.png\n\n",
            "images.txt:1",
            "zero quaternion",
        ),
    ];
    for (c, i, place, what) in cases {
        std::fs::write(d.join("cameras.txt"), c).unwrap();
        std::fs::write(d.join("images.txt"), i).unwrap();
        let e = read_model(d).unwrap_err().to_string();
        assert!(
            e.contains(place) && e.contains(what),
            "expected {place} / {what}: {e}"
        );
    }
    std::fs::write(d.join("cameras.txt"), cams).unwrap();
    std::fs::write(d.join("images.txt"), imgs_ok).unwrap();
    assert_eq!(read_model(d).unwrap().images.len(), 2);
    let empty = tempfile::tempdir().unwrap();
    assert!(matches!(
        read_model(empty.path()).unwrap_err(),
        ColmapError::NoModel { .. }
    ));
    // export refuses what COLMAP could not read back
    let mut m = sample_model();
    m.images[0].name = "has space.png".into();
    assert!(matches!(
        write_text(d, &m).unwrap_err(),
        ColmapError::Export { .. }
    ));
    let mut m = sample_model();
    m.cameras.get_mut(&1).unwrap().intrinsics.k1 = 0.1; // SIMPLE_PINHOLE cannot hold k1
    assert!(matches!(
        write_text(d, &m).unwrap_err(),
        ColmapError::Export { camera: 1, .. }
    ));
}

// ---------------------------------------------------------------------------------------------
// SfM-like meshes

use brdf_rig::geometry::sfm_like::{SfmLikeParams, mean_edge_length, sfm_like};

#[test]
fn sfm_like_noise_is_seeded_along_normals_with_the_stated_sigma() {
    let truth = uv_sphere(1.0, 60, 120);
    let params = SfmLikeParams {
        iterations: 0,
        noise_rel: 0.1,
        seed: 42,
        ..Default::default()
    };
    let a = sfm_like(&truth, &params);
    let b = sfm_like(&truth, &params);
    assert_eq!(a.positions(), b.positions());
    let c = sfm_like(&truth, &SfmLikeParams { seed: 43, ..params });
    assert_ne!(a.positions(), c.positions());
    let sigma = 0.1 * mean_edge_length(&truth);
    let mut sum2 = 0.0;
    for ((p, q), n) in a
        .positions()
        .iter()
        .zip(truth.positions())
        .zip(truth.vertex_normals())
    {
        let d = p - q;
        // along the normal only
        assert!((d - n * d.dot(n)).norm() < 1e-12);
        sum2 += d.norm_squared();
    }
    let rms = (sum2 / truth.positions().len() as f64).sqrt();
    // 7000 samples: the RMS of a Gaussian is within 5% of sigma with overwhelming probability
    assert!((rms / sigma - 1.0).abs() < 0.05, "rms {rms} sigma {sigma}");
}

#[test]
fn sfm_like_smoothing_keeps_a_sphere_and_bends_normals_where_curvature_is_high() {
    // Taubin keeps a sphere's size (plain Laplacian smoothing would shrink it)
    let s = uv_sphere(1.0, 30, 60);
    let params = SfmLikeParams {
        noise_rel: 0.0,
        ..Default::default()
    };
    let smooth = sfm_like(&s, &params);
    let mean_r: f64 = smooth
        .positions()
        .iter()
        .map(|p| p.coords.norm())
        .sum::<f64>()
        / s.positions().len() as f64;
    assert!((mean_r - 1.0).abs() < 0.01, "mean radius {mean_r}");
    // on Spot, normal error after smoothing grows with |H| (METHOD.md assumption 1)
    let (spot, _) = load_mesh(&meshes().join("spot_triangulated.obj")).unwrap();
    let h = principal_curvatures(&spot).mean;
    let smooth = sfm_like(
        &spot,
        &SfmLikeParams {
            iterations: 20,
            ..params
        },
    );
    let err: Vec<f64> = spot
        .vertex_normals()
        .iter()
        .zip(smooth.vertex_normals())
        .map(|(a, b)| a.dot(b).clamp(-1.0, 1.0).acos())
        .collect();
    let mut idx: Vec<usize> = (0..h.len()).collect();
    idx.sort_by(|&i, &j| h[i].abs().total_cmp(&h[j].abs()));
    let q = idx.len() / 4;
    let mean = |s: &[usize]| s.iter().map(|&i| err[i]).sum::<f64>() / s.len() as f64;
    let (flat, curved) = (mean(&idx[..q]), mean(&idx[idx.len() - q..]));
    assert!(
        curved > 2.0 * flat,
        "normal error: flattest quarter {flat}, most curved {curved}"
    );
}

#[test]
fn rasterised_fragments_carry_interpolated_mean_curvature() {
    let r = 0.8;
    let s = uv_sphere(r, 30, 60);
    let bvh = Bvh::build(&s);
    let h = principal_curvatures(&s).mean;
    let k = Intrinsics::pinhole(48, 36, 50.0, 50.0, 24.0, 18.0);
    let pose = Pose::look_at(Point3::new(0.0, -3.0, 1.0), Point3::origin(), Vector3::z());
    let g = rasterise(&s, &bvh, &k, &pose, Some(&h));
    assert!(g.covered() > 100);
    for f in g.fragments().iter().flatten() {
        assert!((f.mean_curvature.unwrap() * r - 1.0).abs() < 0.02);
        // the interpolated normal of a fine sphere is close to the true radial direction
        assert!(f.normal.dot(&f.position.coords.normalize()) > 0.999);
    }
    // a curvature slice for another mesh is ignored rather than misread
    let g = rasterise(&s, &bvh, &k, &pose, Some(&h[1..]));
    assert!(
        g.fragments()
            .iter()
            .flatten()
            .all(|f| f.mean_curvature.is_none())
    );
}

#[test]
fn a_convex_mesh_never_shadows_itself_beyond_its_terminator() {
    // no shadow acne: on a sphere, every face turned towards the light is lit
    let s = uv_sphere(0.7, 40, 80);
    let bvh = Bvh::build(&s);
    let k = Intrinsics::pinhole(96, 72, 70.0, 70.0, 48.0, 36.0);
    let eye = Point3::new(0.4, -2.5, 0.8);
    let pose = Pose::look_at(eye, Point3::origin(), Vector3::z());
    let g = rasterise(&s, &bvh, &k, &pose, None);
    for l in [
        Vector3::new(0.3, -0.2, 0.9),
        Vector3::new(-0.95, 0.1, 0.05),
        Vector3::new(0.0, 1.0, 0.0),
    ] {
        let l = l.normalize();
        let mask = shadow_mask(&s, &bvh, &g, &eye, &l);
        let mut lit = 0;
        for (f, m) in g.fragments().iter().zip(&mask) {
            let Some(f) = f else { continue };
            let facing = s.face_normals()[f.face as usize].dot(&l) > 0.0;
            assert_eq!(m.unwrap(), facing, "face {} at {:?}", f.face, f.position);
            lit += facing as usize;
        }
        assert!(lit > 0 || l.y > 0.9);
    }
}

#[test]
fn obj_objects_sharing_vertices_stay_connected() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "two.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 1\no a\nf 1 2 3\no b\nf 1 3 4\n",
    );
    let (m, _) = load_mesh(&p).unwrap();
    // the shared edge (1, 3) must be one edge, so both faces blend normals at its ends
    assert_eq!(m.positions().len(), 4);
    let (f0, f1) = (m.faces()[0], m.faces()[1]);
    assert_eq!((f0[0], f0[2]), (f1[0], f1[1]));
    let n = m.vertex_normals()[f0[0] as usize];
    assert!(
        n.y < -0.1 && n.z > 0.5,
        "normal at the shared corner blends both faces: {n:?}"
    );
}
