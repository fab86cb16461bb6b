//! Material labels on a mesh: which of an object's materials each face is made of. The
//! simulated multi-material scenes paint faces with them (`sim::job_scene`), segmentation
//! produces them, and [`area_agreement`] scores one labelling against another.
//!
//! Conventions: one label per face, in face order, numbered `0..count`; a label is only a name
//! (label 2 of a segmentation need not be label 2 of the truth), so comparisons match labels up
//! first. Areas are triangle areas in the mesh's units; a vertex's label is the label covering
//! most of the area of its incident faces; its display colour is [`label_colour`]. Pure: no
//! file I/O (the truth file is written and read by `sim::truth_labels`); depends only on `mesh`.

use super::mesh::Mesh;
use nalgebra::Vector3;
use thiserror::Error;

/// The display colour of labels 0, 1, 2, ... (then repeating), 8-bit sRGB: distinct hues (the
/// Okabe-Ito palette, designed to stay distinct with the common colour-vision deficiencies,
/// without its black and its blue). One palette for every picture of labels: the vertex colours of
/// `material_map.ply`, the material map of the comparison panels, the report's swatches.
pub const LABEL_COLOURS: [[u8; 3]; 6] = [
    [230, 159, 0],
    [86, 180, 233],
    [0, 158, 115],
    [213, 94, 0],
    [204, 121, 167],
    [240, 228, 66],
];

/// The colour of `label` ([`LABEL_COLOURS`], repeating past its end).
pub fn label_colour(label: u32) -> [u8; 3] {
    LABEL_COLOURS[label as usize % LABEL_COLOURS.len()]
}

/// Why labels could not be attached to a mesh.
#[derive(Debug, Error, PartialEq)]
pub enum LabelError {
    #[error("{labels} face labels for a mesh of {faces} faces: there must be one label per face")]
    CountMismatch { labels: usize, faces: usize },
}

/// One material label per mesh face, each in `0..count`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FaceLabels {
    pub labels: Vec<u32>,
    /// Number of materials; at least 1 (an empty label list has count 1).
    pub count: u32,
}

impl FaceLabels {
    /// Per face, the label most of its corners carry in `vertex_labels` (the first corner's
    /// when all three differ; a corner past the list counts as label 0): the face labels of a
    /// per-vertex labelling such as a segmentation's.
    pub fn from_vertex_labels(mesh: &Mesh, vertex_labels: &[u32]) -> Self {
        let labels: Vec<u32> = mesh
            .faces()
            .iter()
            .map(|f| {
                let l = f.map(|v| vertex_labels.get(v as usize).copied().unwrap_or(0));
                if l[1] == l[2] { l[1] } else { l[0] }
            })
            .collect();
        let count = labels.iter().max().map_or(1, |m| m + 1);
        Self { labels, count }
    }

    /// Labels for a mesh of `faces` faces; `count` is the largest label plus one.
    pub fn new(labels: Vec<u32>, faces: usize) -> Result<Self, LabelError> {
        if labels.len() != faces {
            return Err(LabelError::CountMismatch {
                labels: labels.len(),
                faces,
            });
        }
        let count = labels.iter().max().map_or(1, |&m| m + 1);
        Ok(Self { labels, count })
    }

    /// Every one of `faces` faces made of material 0: a one-material object.
    pub fn uniform(faces: usize) -> Self {
        Self {
            labels: vec![0; faces],
            count: 1,
        }
    }

    /// Per vertex, the label covering most of the area of its incident faces (ties: the lowest
    /// label). A vertex no face uses gets label 0. Faces beyond `labels` (a labelling made for
    /// another mesh) are ignored.
    pub fn vertex_labels(&self, mesh: &Mesh) -> Vec<u32> {
        let count = self.count.max(1) as usize;
        let mut area = vec![0.0f64; mesh.positions().len() * count];
        for (f, (face, &label)) in mesh.faces().iter().zip(&self.labels).enumerate() {
            let a = face_area(mesh, f);
            for &v in face {
                if let Some(slot) = area.get_mut(v as usize * count + label as usize) {
                    *slot += a;
                }
            }
        }
        area.chunks(count.max(1))
            .map(|per_label| {
                let mut best = 0;
                for (l, &a) in per_label.iter().enumerate() {
                    if a > per_label[best] {
                        best = l;
                    }
                }
                best as u32
            })
            .collect()
    }
}

/// Area of face `f`.
pub fn face_area(mesh: &Mesh, f: usize) -> f64 {
    let [a, b, c] = mesh.triangle(f);
    0.5 * (b - a).cross(&(c - a)).norm()
}

/// Splits the object into `parts` slabs of equal thickness along `axis`: a face's label is the
/// slab its centroid falls in, slabs counted from the lowest projection of a vertex on `axis`
/// to the highest (label 0 lowest). `count` is `parts` even if a slab holds no face. `parts` 0
/// is taken as 1; a zero or non-finite axis, or a flat object along it, gives all zeros.
pub fn split_by_planes(mesh: &Mesh, axis: Vector3<f64>, parts: u32) -> FaceLabels {
    let parts = parts.max(1);
    let faces = mesh.faces().len();
    let norm = axis.norm();
    if parts == 1 || !norm.is_finite() || norm == 0.0 {
        return FaceLabels {
            labels: vec![0; faces],
            count: parts,
        };
    }
    let axis = axis / norm;
    let (lo, hi) = mesh
        .positions()
        .iter()
        .map(|p| p.coords.dot(&axis))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
            (lo.min(x), hi.max(x))
        });
    let extent = hi - lo;
    let labels = (0..faces)
        .map(|f| {
            if extent.is_nan() || extent <= 0.0 {
                return 0;
            }
            let [a, b, c] = mesh.triangle(f);
            let centroid = (a.coords + b.coords + c.coords) / 3.0;
            let t = (centroid.dot(&axis) - lo) / extent;
            ((t * parts as f64).floor().max(0.0) as u32).min(parts - 1)
        })
        .collect();
    FaceLabels {
        labels,
        count: parts,
    }
}

/// Labels up to this many on each side are matched by trying every assignment; beyond, greedily.
const BRUTE_FORCE_LABELS: u32 = 5;

/// The fraction of surface area (only faces with `visible[f]`, when given) where `found` agrees
/// with `truth` once `found`'s labels are renamed to `truth`'s by the renaming (one to one) that
/// agrees most. A found label left without a partner (more found labels than true ones) counts
/// as wrong everywhere. Every assignment is tried when both sides have at most 5 labels;
/// otherwise pairs are taken greedily by overlapping area (a lower bound of the best).
///
/// Faces missing from `truth`, `found` or `visible` (shorter lists) are left out. `NaN` when no
/// area is left to score.
pub fn area_agreement(
    mesh: &Mesh,
    truth: &FaceLabels,
    found: &FaceLabels,
    visible: Option<&[bool]>,
) -> f64 {
    let (t_count, f_count) = (truth.count.max(1) as usize, found.count.max(1) as usize);
    // overlap[found][truth]: area labelled `found` by one and `truth` by the other
    let mut overlap = vec![vec![0.0f64; t_count]; f_count];
    let mut total = 0.0;
    let faces = mesh
        .faces()
        .len()
        .min(truth.labels.len())
        .min(found.labels.len());
    for f in 0..faces {
        if let Some(v) = visible
            && !v.get(f).copied().unwrap_or(false)
        {
            continue;
        }
        let a = face_area(mesh, f);
        total += a;
        let (t, g) = (truth.labels[f] as usize, found.labels[f] as usize);
        if let Some(slot) = overlap.get_mut(g).and_then(|row| row.get_mut(t)) {
            *slot += a;
        }
    }
    if total.is_nan() || total <= 0.0 {
        return f64::NAN;
    }
    let matched = if truth.count <= BRUTE_FORCE_LABELS && found.count <= BRUTE_FORCE_LABELS {
        best_assignment(&overlap, 0, &mut vec![false; t_count])
    } else {
        greedy_assignment(&overlap)
    };
    matched / total
}

/// The largest sum of `overlap[g][t]` over one-to-one pairs, found labels from `g` on, truth
/// labels not yet `used` (each found label may also stay unmatched).
fn best_assignment(overlap: &[Vec<f64>], g: usize, used: &mut [bool]) -> f64 {
    let Some(row) = overlap.get(g) else {
        return 0.0;
    };
    let mut best = best_assignment(overlap, g + 1, used); // `g` unmatched
    for t in 0..used.len() {
        if !used[t] {
            used[t] = true;
            best = best.max(row[t] + best_assignment(overlap, g + 1, used));
            used[t] = false;
        }
    }
    best
}

/// Pairs taken by decreasing overlap, each label used once.
fn greedy_assignment(overlap: &[Vec<f64>]) -> f64 {
    let mut pairs: Vec<(f64, usize, usize)> = overlap
        .iter()
        .enumerate()
        .flat_map(|(g, row)| row.iter().enumerate().map(move |(t, &a)| (a, g, t)))
        .filter(|(a, _, _)| *a > 0.0)
        .collect();
    pairs.sort_by(|x, y| y.0.total_cmp(&x.0));
    let mut used_g = vec![false; overlap.len()];
    let mut used_t = vec![false; overlap.first().map_or(0, Vec::len)];
    let mut sum = 0.0;
    for (a, g, t) in pairs {
        if !used_g[g] && !used_t[t] {
            used_g[g] = true;
            used_t[t] = true;
            sum += a;
        }
    }
    sum
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use nalgebra::Point3;

    /// A strip of `n` unit squares along x, each split into two triangles (faces `2i`, `2i + 1`
    /// cover square `i`, x in `[i, i + 1]`); all faces have area 1/2.
    fn strip(n: usize) -> Mesh {
        let mut p = Vec::new();
        for i in 0..=n {
            p.push(Point3::new(i as f64, 0.0, 0.0));
            p.push(Point3::new(i as f64, 1.0, 0.0));
        }
        let mut f = Vec::new();
        for i in 0..n as i64 {
            let (a, b, c, d) = (2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1);
            f.push([a, b, c]);
            f.push([a, c, d]);
        }
        Mesh::new(p, f, "<strip>").unwrap().0
    }

    #[test]
    fn labels_must_cover_every_face() {
        let l = FaceLabels::new(vec![0, 2, 1, 2], 4).unwrap();
        assert_eq!(l.count, 3);
        let e = FaceLabels::new(vec![0, 1], 4).unwrap_err();
        assert_eq!(
            e,
            LabelError::CountMismatch {
                labels: 2,
                faces: 4
            }
        );
        assert!(e.to_string().contains("2 face labels") && e.to_string().contains("4 faces"));
        assert_eq!(FaceLabels::new(vec![], 0).unwrap().count, 1);
    }

    #[test]
    fn face_labels_from_vertex_labels_take_the_corners_majority() {
        let m = strip(2); // vertices 0..6; faces [0,2,3], [0,3,1], [2,4,5], [2,5,3]
        let v = vec![0, 0, 1, 1, 1, 1];
        let f = FaceLabels::from_vertex_labels(&m, &v);
        assert_eq!(f.labels, vec![1, 0, 1, 1]);
        assert_eq!(f.count, 2);
    }

    #[test]
    fn planes_split_into_slabs_of_equal_extent() {
        let m = strip(4); // x in [0, 4]
        let l = split_by_planes(&m, Vector3::x(), 2);
        assert_eq!(l.count, 2);
        assert_eq!(l.labels, vec![0, 0, 0, 0, 1, 1, 1, 1]);
        // the axis' length and sign: reversed axis, lowest slab at high x
        let l = split_by_planes(&m, -3.0 * Vector3::x(), 4);
        assert_eq!(l.labels, vec![3, 3, 2, 2, 1, 1, 0, 0]);
        // one part, or an axis the object is flat along: all zeros
        assert!(
            split_by_planes(&m, Vector3::x(), 1)
                .labels
                .iter()
                .all(|&x| x == 0)
        );
        let flat = split_by_planes(&m, Vector3::z(), 3);
        assert!(flat.labels.iter().all(|&x| x == 0) && flat.count == 3);
        assert!(
            split_by_planes(&m, Vector3::zeros(), 2)
                .labels
                .iter()
                .all(|&x| x == 0)
        );
    }

    #[test]
    fn a_vertex_takes_the_label_of_most_of_its_area() {
        let m = strip(3);
        // squares 0 and 1 are label 0 and 1; square 2 has one face of each
        let l = FaceLabels::new(vec![0, 0, 1, 1, 0, 1], 6).unwrap();
        let v = l.vertex_labels(&m);
        assert_eq!(&v[0..2], &[0, 0], "x = 0 touches only label 0");
        // all faces have the same area, so the majority by count is the one by area; a tie
        // (vertex 3 at (1, 1): faces 1, 3 of label 0 and 1) goes to the lowest label
        assert_eq!(v[3], 0);
        let faces_of = |vi: u32| {
            m.faces()
                .iter()
                .enumerate()
                .filter(|(_, f)| f.contains(&vi))
                .map(|(i, _)| l.labels[i])
                .collect::<Vec<_>>()
        };
        for vi in 0..8u32 {
            let fl = faces_of(vi);
            let ones = fl.iter().filter(|&&x| x == 1).count();
            let zeros = fl.len() - ones;
            let expect = u32::from(ones > zeros);
            assert_eq!(v[vi as usize], expect, "vertex {vi}: faces {fl:?}");
        }
        // area, not the number of faces: stretch square 2 (x = 3 moved to x = 10) so its faces
        // have area 4; vertex 5 at (2, 1) touches faces 2, 3 (label 0, 1/2 each) and face 5
        let mut p = m.positions().to_vec();
        p[6].x = 10.0;
        p[7].x = 10.0;
        let mut big = m.clone();
        assert!(big.set_positions(p));
        let l = FaceLabels::new(vec![0, 0, 0, 0, 0, 1], 6).unwrap();
        assert_eq!(
            l.vertex_labels(&big)[5],
            1,
            "one face of area 4 beats two of 1/2"
        );
    }

    #[test]
    fn agreement_is_up_to_renaming_and_counts_area() {
        let m = strip(4);
        let truth = split_by_planes(&m, Vector3::x(), 2);
        // a relabelled copy agrees fully
        let renamed = FaceLabels::new(truth.labels.iter().map(|&l| 1 - l).collect(), 8).unwrap();
        assert_eq!(area_agreement(&m, &truth, &renamed, None), 1.0);
        assert_eq!(area_agreement(&m, &truth, &truth, None), 1.0);
        // half the area wrong: label 1's half called 0
        let half = FaceLabels::uniform(8);
        assert!((area_agreement(&m, &truth, &half, None) - 0.5).abs() < 1e-12);
        // four found labels for two true ones: two of them stay unmatched and count as wrong
        let four = split_by_planes(&m, Vector3::x(), 4);
        assert!((area_agreement(&m, &truth, &four, None) - 0.5).abs() < 1e-12);
        // ...and the other way round, the best two of the four true slabs are matched
        assert!((area_agreement(&m, &four, &truth, None) - 0.5).abs() < 1e-12);
        // a permutation of three labels, with one square wrong
        let truth3 = FaceLabels::new(vec![0, 0, 1, 1, 2, 2, 2, 2], 8).unwrap();
        let found3 = FaceLabels::new(vec![2, 2, 0, 0, 1, 1, 0, 0], 8).unwrap();
        assert!((area_agreement(&m, &truth3, &found3, None) - 0.75).abs() < 1e-12);
        // only visible faces count
        let vis = [true, true, true, true, true, true, false, false];
        assert!((area_agreement(&m, &truth3, &found3, Some(&vis)) - 1.0).abs() < 1e-12);
        assert!(area_agreement(&m, &truth3, &found3, Some(&[false; 8])).is_nan());
    }

    #[test]
    fn many_labels_are_matched_greedily() {
        let m = strip(8);
        let truth = split_by_planes(&m, Vector3::x(), 8);
        // the same slabs, renamed by a rotation: greedy finds the exact match
        let found = FaceLabels {
            labels: truth.labels.iter().map(|&l| (l + 3) % 8).collect(),
            count: 8,
        };
        assert_eq!(area_agreement(&m, &truth, &found, None), 1.0);
        // and agrees with the exhaustive search where both apply
        let t = FaceLabels::new((0..16).map(|f| (f / 4) as u32).collect(), 16).unwrap();
        let g = FaceLabels::new((0..16).map(|f| ((f / 3) % 5) as u32).collect(), 16).unwrap();
        let mut overlap = vec![vec![0.0; 4]; 5];
        for f in 0..16 {
            overlap[g.labels[f] as usize][t.labels[f] as usize] += 0.5;
        }
        let exact = best_assignment(&overlap, 0, &mut [false; 4]);
        assert!(greedy_assignment(&overlap) <= exact + 1e-12);
        assert!((area_agreement(&m, &t, &g, None) - exact / 8.0).abs() < 1e-12);
    }
}
