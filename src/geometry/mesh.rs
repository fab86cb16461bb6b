//! A validated triangle mesh: positions, triangle faces and per-vertex normals.
//!
//! Conventions: faces are counter-clockwise seen from outside, so the face normal
//! `(p1 - p0) x (p2 - p0)` points outwards. Vertex normals are the angle-weighted mean of the
//! incident face normals (Thürmer and Wüthrich 1998): unlike area weighting, the result does not
//! change when a face is split, so it is stable under SfM/MVS re-triangulation. A vertex no face
//! uses keeps a zero normal. Units are whatever the source file uses (SfM: arbitrary scale).
//!
//! Validation is the one place file content becomes trusted geometry: NaN/inf coordinates and
//! out-of-range indices are errors naming the source and the element; degenerate faces (repeated
//! indices or zero area) are dropped and counted in [`MeshReport`], never silently.
//! Pure: no file I/O here (see `mesh_io`); must not depend on rendering or BRDF code.

use nalgebra::{Point3, Vector3};
use thiserror::Error;

/// Why a mesh was rejected. `origin` names the file (or `<memory>`) the data came from.
#[derive(Debug, Error, PartialEq)]
pub enum MeshError {
    #[error("{origin}: vertex {vertex} has a non-finite coordinate {coords:?}")]
    NonFiniteVertex {
        origin: String,
        vertex: usize,
        coords: [f64; 3],
    },
    #[error(
        "{origin}: face {face} uses vertex index {index}, but there are only {vertex_count} vertices"
    )]
    IndexOutOfRange {
        origin: String,
        face: usize,
        index: i64,
        vertex_count: usize,
    },
    #[error("{origin}: no usable triangle ({dropped} degenerate faces dropped)")]
    NoFaces { origin: String, dropped: usize },
}

/// What validation changed, for the caller to report (the library never prints).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshReport {
    /// Faces with a repeated index or zero area, removed from the mesh.
    pub degenerate_faces_dropped: usize,
    /// Vertices no face uses (kept, so vertex ids stay those of the file).
    pub unreferenced_vertices: usize,
}

/// A triangle mesh whose content has been validated (finite, indices in range, no degenerate
/// faces). Fields are private so that invariant holds; build it with [`Mesh::new`].
#[derive(Clone, Debug)]
pub struct Mesh {
    positions: Vec<Point3<f64>>,
    faces: Vec<[u32; 3]>,
    vertex_normals: Vec<Vector3<f64>>,
    face_normals: Vec<Vector3<f64>>,
    /// Cached `(min, max)` of the positions: shading asks for the scale once per pixel.
    bounds: (Point3<f64>, Point3<f64>),
}

impl Mesh {
    /// Validates positions and faces (indices as read, possibly negative or too large) and
    /// computes normals. `source` names where the data came from, for error messages.
    pub fn new(
        positions: Vec<Point3<f64>>,
        faces: Vec<[i64; 3]>,
        source: &str,
    ) -> Result<(Mesh, MeshReport), MeshError> {
        for (i, p) in positions.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
                return Err(MeshError::NonFiniteVertex {
                    origin: source.to_string(),
                    vertex: i,
                    coords: [p.x, p.y, p.z],
                });
            }
        }
        let n = positions.len();
        let mut kept = Vec::with_capacity(faces.len());
        let mut dropped = 0;
        for (fi, f) in faces.iter().enumerate() {
            for &idx in f {
                if idx < 0 || idx as u64 >= n as u64 || idx > u32::MAX as i64 {
                    return Err(MeshError::IndexOutOfRange {
                        origin: source.to_string(),
                        face: fi,
                        index: idx,
                        vertex_count: n,
                    });
                }
            }
            let tri = [f[0] as u32, f[1] as u32, f[2] as u32];
            if is_degenerate(&positions, tri) {
                dropped += 1;
            } else {
                kept.push(tri);
            }
        }
        if kept.is_empty() {
            return Err(MeshError::NoFaces {
                origin: source.to_string(),
                dropped,
            });
        }
        let mut used = vec![false; n];
        for f in &kept {
            for &i in f {
                used[i as usize] = true;
            }
        }
        let report = MeshReport {
            degenerate_faces_dropped: dropped,
            unreferenced_vertices: used.iter().filter(|u| !**u).count(),
        };
        let mut mesh = Mesh {
            positions,
            faces: kept,
            vertex_normals: Vec::new(),
            face_normals: Vec::new(),
            bounds: (Point3::origin(), Point3::origin()),
        };
        mesh.recompute_normals();
        Ok((mesh, report))
    }

    pub fn positions(&self) -> &[Point3<f64>] {
        &self.positions
    }

    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }

    /// Unit angle-weighted vertex normals (zero for unreferenced vertices).
    pub fn vertex_normals(&self) -> &[Vector3<f64>] {
        &self.vertex_normals
    }

    /// Unit geometric face normals, outward for counter-clockwise faces.
    pub fn face_normals(&self) -> &[Vector3<f64>] {
        &self.face_normals
    }

    /// The three corner positions of face `f`.
    pub fn triangle(&self, f: usize) -> [Point3<f64>; 3] {
        let [a, b, c] = self.faces[f];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Axis-aligned bounds `(min, max)` of all positions (cached).
    pub fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        self.bounds
    }

    /// Length of the bounding-box diagonal: the scale used for ray offsets and tolerances.
    pub fn diagonal(&self) -> f64 {
        let (lo, hi) = self.bounds();
        (hi - lo).norm()
    }

    /// Replaces the positions (same count and topology), e.g. after smoothing, and recomputes
    /// normals. Returns `false` and leaves the mesh unchanged when the count differs or a
    /// position is not finite.
    pub fn set_positions(&mut self, positions: Vec<Point3<f64>>) -> bool {
        if positions.len() != self.positions.len()
            || positions
                .iter()
                .any(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
        {
            return false;
        }
        self.positions = positions;
        self.recompute_normals();
        true
    }

    /// Replaces the vertex normals (e.g. refined from images), keeping positions, faces, face
    /// normals and bounds. Each normal is renormalised. Returns `false` and leaves the mesh
    /// unchanged when the count differs or a normal is not finite or is zero.
    pub fn set_vertex_normals(&mut self, normals: Vec<Vector3<f64>>) -> bool {
        if normals.len() != self.vertex_normals.len() {
            return false;
        }
        let mut unit = Vec::with_capacity(normals.len());
        for (n, old) in normals.iter().zip(&self.vertex_normals) {
            let len = n.norm();
            if !len.is_finite() {
                return false;
            }
            // an unreferenced vertex keeps its zero normal
            if *old == Vector3::zeros() || len == 0.0 {
                if len != 0.0 || *old != Vector3::zeros() {
                    return false;
                }
                unit.push(Vector3::zeros());
            } else {
                unit.push(n / len);
            }
        }
        self.vertex_normals = unit;
        true
    }

    /// The one-ring of every vertex: the vertices it shares an edge with (sorted, unique).
    pub fn vertex_neighbours(&self) -> Vec<Vec<u32>> {
        let mut nb = vec![Vec::new(); self.positions.len()];
        for f in &self.faces {
            for j in 0..3 {
                let a = f[j] as usize;
                nb[a].push(f[(j + 1) % 3]);
                nb[a].push(f[(j + 2) % 3]);
            }
        }
        for n in &mut nb {
            n.sort_unstable();
            n.dedup();
        }
        nb
    }

    /// Recomputes the cached bounds and the normals after the positions changed.
    fn recompute_normals(&mut self) {
        let mut lo = Point3::from([f64::INFINITY; 3]);
        let mut hi = Point3::from([f64::NEG_INFINITY; 3]);
        for p in &self.positions {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        self.bounds = (lo, hi);
        let (vn, fnorm) = angle_weighted_normals(&self.faces, &self.positions);
        self.vertex_normals = vn;
        self.face_normals = fnorm;
    }
}

/// Unit vertex normals (each the angle-weighted mean of its faces' normals; zero for a vertex no
/// face uses) and unit face normals (zero for a degenerate face) of the triangles `faces` over
/// `positions`: what [`Mesh`] computes, for callers that move positions without a mesh (the
/// normal refinement's depth unknowns). Faces must index `positions`.
pub fn angle_weighted_normals(
    faces: &[[u32; 3]],
    positions: &[Point3<f64>],
) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
    let mut vn = vec![Vector3::zeros(); positions.len()];
    let mut fnorm = Vec::with_capacity(faces.len());
    for f in faces {
        let p = [
            positions[f[0] as usize],
            positions[f[1] as usize],
            positions[f[2] as usize],
        ];
        let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
        let len = n.norm();
        let n = if len > 0.0 { n / len } else { Vector3::zeros() };
        fnorm.push(n);
        for k in 0..3 {
            let e1 = p[(k + 1) % 3] - p[k];
            let e2 = p[(k + 2) % 3] - p[k];
            let denom = e1.norm() * e2.norm();
            if denom > 0.0 {
                let angle = (e1.dot(&e2) / denom).clamp(-1.0, 1.0).acos();
                vn[f[k] as usize] += n * angle;
            }
        }
    }
    for n in &mut vn {
        let len = n.norm();
        if len > 0.0 {
            *n /= len;
        }
    }
    (vn, fnorm)
}

/// Mean length of the edges of the triangles `faces` over `positions` (each interior edge
/// counted twice; a scale, not a statistic; 0 without faces). Faces must index `positions`.
pub fn mean_edge_length(faces: &[[u32; 3]], positions: &[Point3<f64>]) -> f64 {
    let mut sum = 0.0;
    for f in faces {
        for j in 0..3 {
            sum += (positions[f[(j + 1) % 3] as usize] - positions[f[j] as usize]).norm();
        }
    }
    sum / (3 * faces.len()).max(1) as f64
}

/// A UV sphere of radius `r` about the origin with outward faces: `rings` latitude bands (at
/// least 2) of `segments` quads (at least 3), poles as single vertices. For tests and studies
/// that need a closed surface whose true normal is known everywhere (`position / r`).
pub fn uv_sphere(r: f64, rings: usize, segments: usize) -> Result<Mesh, MeshError> {
    let (rings, segments) = (rings.max(2), segments.max(3));
    let mut p = vec![Point3::new(0.0, 0.0, r)];
    for i in 1..rings {
        let th = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let ph = std::f64::consts::TAU * j as f64 / segments as f64;
            p.push(Point3::new(
                r * th.sin() * ph.cos(),
                r * th.sin() * ph.sin(),
                r * th.cos(),
            ));
        }
    }
    p.push(Point3::new(0.0, 0.0, -r));
    let south = (p.len() - 1) as i64;
    let id = |i: usize, j: usize| (1 + (i - 1) * segments + j % segments) as i64;
    let mut f = Vec::new();
    for j in 0..segments {
        f.push([0, id(1, j), id(1, j + 1)]);
        f.push([south, id(rings - 1, j + 1), id(rings - 1, j)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            f.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            f.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Ok(Mesh::new(p, f, "<uv sphere>")?.0)
}

/// A face is degenerate when two corners share an index or its area vanishes relative to its
/// longest edge (collinear corners).
fn is_degenerate(positions: &[Point3<f64>], f: [u32; 3]) -> bool {
    if f[0] == f[1] || f[1] == f[2] || f[0] == f[2] {
        return true;
    }
    let a = positions[f[0] as usize];
    let b = positions[f[1] as usize];
    let c = positions[f[2] as usize];
    let e1 = b - a;
    let e2 = c - a;
    let longest2 = e1
        .norm_squared()
        .max(e2.norm_squared())
        .max((c - b).norm_squared());
    let area2 = e1.cross(&e2).norm();
    // twice the area against the squared longest edge: ~1e-12 means corners collinear to
    // double precision, not merely a thin triangle
    longest2 == 0.0 || area2 <= 1e-12 * longest2
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    fn tetra() -> (Vec<Point3<f64>>, Vec<[i64; 3]>) {
        let p = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        let f = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        (p, f)
    }

    #[test]
    fn tetrahedron_normals_point_outwards() {
        let (p, f) = tetra();
        let (m, r) = Mesh::new(p, f, "<memory>").unwrap();
        assert_eq!(r, MeshReport::default());
        let c = Point3::new(0.25, 0.25, 0.25);
        for (i, n) in m.vertex_normals().iter().enumerate() {
            assert!((n.norm() - 1.0).abs() < 1e-12);
            assert!(n.dot(&(m.positions()[i] - c)) > 0.0);
        }
        // the corner at the origin sees three right angles: normal along -(1,1,1)
        let n0 = m.vertex_normals()[0];
        assert!((n0 + Vector3::new(1.0, 1.0, 1.0).normalize()).norm() < 1e-12);
    }

    #[test]
    fn bad_content_is_named_and_degenerate_faces_counted() {
        let (mut p, mut f) = tetra();
        f.push([0, 0, 1]);
        p.push(Point3::new(2.0, 0.0, 0.0)); // collinear with 0 and 1
        f.push([0, 1, 4]);
        let (m, r) = Mesh::new(p.clone(), f.clone(), "x.ply").unwrap();
        assert_eq!(r.degenerate_faces_dropped, 2);
        assert_eq!(r.unreferenced_vertices, 1);
        assert_eq!(m.faces().len(), 4);

        f.push([0, 1, 7]);
        let e = Mesh::new(p.clone(), f, "x.ply").unwrap_err();
        assert!(matches!(
            e,
            MeshError::IndexOutOfRange {
                face: 6,
                index: 7,
                ..
            }
        ));
        assert!(e.to_string().contains("x.ply"));

        p[2].y = f64::NAN;
        let e = Mesh::new(p, tetra().1, "y.obj").unwrap_err();
        assert!(matches!(e, MeshError::NonFiniteVertex { vertex: 2, .. }));
        assert!(e.to_string().starts_with("y.obj"));
    }

    #[test]
    fn vertex_normals_can_be_replaced_but_not_with_nonsense() {
        let (p, f) = tetra();
        let (mut m, _) = Mesh::new(p, f, "t").expect("valid");
        let faces = m.faces().to_vec();
        let turned: Vec<Vector3<f64>> = m.vertex_normals().iter().map(|n| n * 3.0).collect();
        assert!(m.set_vertex_normals(turned));
        assert!(
            m.vertex_normals()
                .iter()
                .all(|n| (n.norm() - 1.0).abs() < 1e-12)
        );
        assert_eq!(m.faces(), &faces[..], "topology kept");
        let before = m.vertex_normals().to_vec();
        assert!(!m.set_vertex_normals(vec![Vector3::x()]), "wrong count");
        let mut bad = before.clone();
        bad[0] = Vector3::new(f64::NAN, 0.0, 1.0);
        assert!(!m.set_vertex_normals(bad), "not finite");
        let mut zero = before.clone();
        zero[1] = Vector3::zeros();
        assert!(!m.set_vertex_normals(zero), "zero on a used vertex");
        assert_eq!(m.vertex_normals(), &before[..], "unchanged after a refusal");
        let nb = m.vertex_neighbours();
        assert!(nb.iter().all(|n| n.len() == 3), "a tetrahedron: three each");
    }

    #[test]
    fn a_uv_sphere_is_closed_and_its_normals_are_radial() {
        let m = uv_sphere(2.0, 8, 12).expect("valid");
        assert_eq!(m.positions().len(), 2 + 7 * 12);
        assert_eq!(m.faces().len(), 2 * 12 + 2 * 6 * 12);
        for (p, n) in m.positions().iter().zip(m.vertex_normals()) {
            assert!((p.coords.norm() - 2.0).abs() < 1e-12);
            assert!(n.dot(&(p.coords / 2.0)) > 0.98, "outward, near radial");
        }
        // degenerate requests are raised to the smallest closed sphere
        assert_eq!(
            uv_sphere(1.0, 0, 0).expect("valid").positions().len(),
            2 + 3
        );
    }
}
