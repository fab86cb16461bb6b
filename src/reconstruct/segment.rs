//! Which material each part of the surface is, from the observations (issue #17), and from
//! the materials the job's label masks give where they give them (per vertex, `mask_labels`;
//! [`segment_with_labels`]): no ground truth. Pure: observations, the mesh and the given
//! labels in, labels and the evidence out; it must not read files or fit the basis (the
//! per-material BRDFs are `core`'s job).
//!
//! 1. **Features per vertex that do not depend on the normals' error**: each observation
//!    belongs to the nearest corner of the face it saw; a vertex pools the observations of
//!    itself and its one-ring. Its features are the chromaticity of the summed reflectance
//!    (`r / (r + g + b)`, `g / (r + g + b)`: a wrong normal scales all three channels alike)
//!    and the median of `ln` of the mean reflectance (the level; a wrong normal moves it by
//!    `ln(cos)` ratios, a highlight by more, so the median over the pooled pixels). The
//!    features are scaled by what counts as a different material ([`SegmentSettings`]).
//! 2. **k-means** (k-means++ seeding, seeded restarts, weighted by pixels), then **spatial
//!    smoothness**: a few sweeps of iterated conditional modes on the mesh's vertex graph
//!    (a Potts cost per neighbour of another label), which also labels the vertices no pixel
//!    saw. Materials below `min_share` of the observed vertices, whose centres are closer
//!    than `merge_distance`, whose body colours are that close (the chromaticity of each
//!    vertex's darker half of pixels, [`body_colours`]: a dielectric's white highlights and
//!    grazing reflections whiten the regions seen most often near them, its darker pixels
//!    keep its colour; docs/materials.md, "Phantom materials at 128x96"), or that lie between
//!    two larger ones (the mixed pixels where two materials meet), are merged away.
//! 3. **How many materials**: for each count, on folds of whole images, the labels are found
//!    from the training images alone, the count model (`count_model`; by default one
//!    reflectance shape shared by the object times an RGB scale per material,
//!    [`super::shared_shape`]) is fitted to the training pixels and renders the held-out
//!    pixels, and the image-space error is averaged over the folds. The simplest count whose
//!    error is within one standard error (of its paired difference to the best) or within
//!    `min_gain` (5 %) of the best wins: the model ladder's rule, so a
//!    one-material object gives one. The count's fits and scores leave out the pixels near
//!    the specular peak (`count_min_theta_h_deg`, 10 degrees): the shared shape's coarse
//!    table cannot follow a sharp peak, a held-out image with a highlight is missed by far,
//!    and a second scale on a region of one shiny material then lowers that miss as much as a
//!    true second material does (docs/materials.md, "One material at the accuracy grid's
//!    size").
//! 4. **Which pixels each material's fit gets** ([`fit_groups`]): those of faces whose corners
//!    all carry its label ([`interior_groups`]), less those near the labels' boundary whose
//!    colour is another material's ([`drop_foreign_colours`]).

use super::baselines::{fit_lambert, fit_lambert_ggx};
use super::ladder::{AnalyticCandidate, image_residual, subset};
use super::observation::{NO_FACE, Observation};
use super::prior::Candidate;
use super::shared_shape::fit_shared_shape;
use crate::geometry::mesh::Mesh;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Knobs of the segmentation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmentSettings {
    /// The largest number of materials tried.
    pub max_materials: usize,
    /// A chromaticity difference of this much is one unit of feature distance.
    pub chroma_scale: f64,
    /// A difference of `ln` reflectance level of this much is one unit.
    pub level_scale: f64,
    /// Potts cost of a neighbour with another label, in squared feature units per pixel
    /// weight (the data cost of a vertex is its pixel count, capped at 8, times its squared
    /// distance to the material's centre).
    pub smoothness: f64,
    /// A material must hold at least this share of the observed vertices.
    pub min_share: f64,
    /// Two materials whose centres are closer than this (scaled feature units) are one.
    pub merge_distance: f64,
    /// A count must lower the held-out error by more than this share of the best error to be
    /// chosen over a simpler one, however small the folds' spread (near-identical fits give
    /// paired differences with a vanishing standard error). 5 %: with the shared-shape count
    /// model, the splits of one material gained 1.6-3.2 % (Mitsuba's painted metal, whose
    /// regions a realistic mesh tilts differently), the true materials of the study 9.7 % or
    /// more in 35 of 36 objects (3.7 % in the one whose count it misses; docs/materials.md).
    pub min_gain: f64,
    /// k-means restarts.
    pub restarts: usize,
    /// Folds of whole images for the choice of the count.
    pub folds: usize,
    /// At most this many pixels per material and fold in the count's fits.
    pub max_fit_pixels: usize,
    /// The model fitted per material to score a count on held-out images.
    pub count_model: CountModel,
    pub seed: u64,
    /// The count's fits and held-out scores use only pixels whose half-vector is at least
    /// this far from the normal (degrees; 0: every pixel, what a `materials.json` written
    /// before session 29 means).
    #[serde(default)]
    pub count_min_theta_h_deg: f64,
    /// Fit each material's BRDF only to the pixels of faces whose three corners all carry its
    /// label ([`interior_groups`]). `false` (what a `materials.json` written before it means):
    /// every pixel goes to the material of the face corner nearest to it.
    #[serde(default)]
    pub fit_interior_only: bool,
    /// Merge two found materials whose body colours ([`Features::body`]) lie within
    /// `merge_distance`. `false` (what a `materials.json` written before session 34 means).
    #[serde(default)]
    pub merge_same_body: bool,
    /// With `fit_interior_only`, also leave out the pixels of faces with a corner within this
    /// many rings of edges of the labels' boundary ([`interior_groups`]; 0: only the faces
    /// across it, what a `materials.json` written before session 51 means).
    #[serde(default)]
    pub boundary_rings: usize,
    /// Within this many rings of the labels' boundary, leave a material's pixels whose colour
    /// is nearer another material's out of its fit ([`drop_foreign_colours`]; 0: off, what a
    /// `materials.json` written before session 51 means).
    #[serde(default)]
    pub foreign_colour_rings: usize,
    /// Passes of [`relabel_boundary`] over the chosen labels: each moves a boundary vertex
    /// to the neighbouring material its own pixels' colour and level are nearest (0: off, the
    /// default and what a `materials.json` written before session 52 means; a study knob,
    /// measured and not adopted: docs/materials.md, "The labels' boundary moved by its own
    /// pixels").
    #[serde(default)]
    pub relabel_passes: usize,
}

impl Default for SegmentSettings {
    fn default() -> Self {
        Self {
            max_materials: 4,
            chroma_scale: 0.02,
            level_scale: 0.7,
            smoothness: 2.0,
            min_share: 0.03,
            merge_distance: 1.0,
            min_gain: 0.05,
            restarts: 4,
            folds: 5,
            max_fit_pixels: 1500,
            count_model: CountModel::SharedShape,
            seed: 0x5E6,
            count_min_theta_h_deg: 10.0,
            fit_interior_only: true,
            merge_same_body: true,
            boundary_rings: 0,
            foreign_colour_rings: 3,
            relabel_passes: 0,
        }
    }
}

/// The model fitted per material when a count is scored on held-out images. The two older
/// models stay selectable in the settings: `materials.json` files written by session 17 name
/// `lambert`, and read back.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CountModel {
    /// The default: one reflectance shape over (theta_h, theta_d, phi_d) shared by the object,
    /// times an RGB scale per material ([`super::shared_shape`]). A region that only looks
    /// brighter because it faces the lights differently (a glossy paint) gains nothing, a second
    /// colour or level does; and nothing per material can blow up on a held-out image.
    SharedShape,
    /// A diffuse colour per material (session 17's default): cannot blow up either, but a
    /// glossy material's regions that face the lights differently get different colours, and
    /// the split lowers the held-out error (Mitsuba's painted metal on Spot: 3 "materials").
    Lambert,
    /// Lambert + GGX per material: one fold's error can be 10x the others on a shiny material
    /// (alum-bronze + blue-acrylic, docs/materials.md).
    LambertGgx,
}

/// One count of materials tried.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CountScore {
    /// The count asked for.
    pub asked: usize,
    /// The count found on all images (after merging small or close materials).
    pub found: usize,
    /// Held-out image error per fold (`None`: the fold could not be scored).
    pub fold_errors: Vec<Option<f64>>,
    pub error: Option<f64>,
    pub standard_error: Option<f64>,
}

/// What the segmentation found.
#[derive(Clone, Debug, PartialEq)]
pub struct Segmentation {
    /// The chosen number of materials.
    pub count: usize,
    /// Per mesh vertex, its material (0..count).
    pub vertex_labels: Vec<u32>,
    /// Per material: the observed vertices that carry it.
    pub observed_vertices: Vec<usize>,
    /// Per material: the mean chromaticity (r, g, b shares) of its pixels.
    pub chromaticity: Vec<[f64; 3]>,
    /// Per material: the vertices whose label was given (fixed), not found.
    pub fixed_vertices: Vec<usize>,
    /// Materials `0..given` are the given ones ([`segment_with_labels`]), in their order.
    pub given: usize,
    /// Every count tried.
    pub scores: Vec<CountScore>,
    /// Why this count (one sentence).
    pub reason: String,
}

impl Segmentation {
    /// The material of an observation (through the corner of its face it is nearest);
    /// `None` for an observation not seen on this mesh.
    pub fn label_of(&self, mesh: &Mesh, o: &Observation) -> Option<u32> {
        let v = nearest_corner(mesh, o)?;
        self.vertex_labels.get(v).copied()
    }
}

/// The pixels of each of `count` materials that its fit uses, and how many of the pixels
/// labelled with it were left out. A pixel belongs to the material of its face's nearest corner
/// ([`Segmentation::label_of`]); with `interior_only`, a pixel whose face has corners of
/// another material is left out of every fit: it may mix two materials (the camera sees both
/// across the boundary), and the boundary is where the labels themselves are least sure. With
/// `rings` above 0, so is a pixel whose face has a corner fewer than `rings` rings of edges
/// from a vertex of another material (a study knob, `SegmentSettings::boundary_rings`,
/// measured and not adopted: it also takes a material's own pixels near its boundary, which
/// cost fruitwood-241 on the three-material Bunny; docs/materials.md, session 51). A material keeps every
/// pixel when its interior ones would be fewer than half of them (a thin strip, or labels
/// broken into specks): a fit to a few boundary-free pixels is worse than one to some mixed
/// ones. Pure.
pub fn interior_groups(
    mesh: &Mesh,
    vertex_labels: &[u32],
    count: usize,
    observations: &[Observation],
    interior_only: bool,
    rings: usize,
) -> (Vec<Vec<Observation>>, Vec<usize>) {
    let near = if interior_only && rings > 0 {
        rings_from_boundary(mesh, vertex_labels, rings)
    } else {
        Vec::new()
    };
    let mut all: Vec<Vec<Observation>> = vec![Vec::new(); count];
    let mut inner: Vec<Vec<Observation>> = vec![Vec::new(); count];
    for o in observations {
        let Some(l) = nearest_corner(mesh, o)
            .and_then(|v| vertex_labels.get(v))
            .map(|&l| l as usize)
            .filter(|&l| l < count)
        else {
            continue;
        };
        all[l].push(*o);
        let pure = mesh.faces().get(o.face as usize).is_some_and(|f| {
            f.iter().all(|&v| {
                vertex_labels
                    .get(v as usize)
                    .is_some_and(|&x| x as usize == l)
                    && near.get(v as usize).is_none_or(|&r| r >= rings)
            })
        });
        if interior_only && pure {
            inner[l].push(*o);
        }
    }
    all.into_iter()
        .zip(inner)
        .map(|(all, inner)| {
            if interior_only && inner.len() * 2 >= all.len() {
                let dropped = all.len() - inner.len();
                (inner, dropped)
            } else {
                (all, 0)
            }
        })
        .unzip()
}

/// The pixels each material's BRDF is fitted to, and how many of its labelled pixels were
/// left out: [`interior_groups`] by `settings`, then [`drop_foreign_colours`]. What
/// `reconstruct --materials auto` fits and what the benches fit their baselines to. Pure.
pub fn fit_groups(
    mesh: &Mesh,
    segmentation: &Segmentation,
    observations: &[Observation],
    settings: &SegmentSettings,
) -> (Vec<Vec<Observation>>, Vec<usize>) {
    let labels = &segmentation.vertex_labels;
    let (mut groups, mut left_out) = interior_groups(
        mesh,
        labels,
        segmentation.count,
        observations,
        settings.fit_interior_only,
        settings.boundary_rings,
    );
    let foreign = drop_foreign_colours(
        mesh,
        labels,
        &mut groups,
        &segmentation.chromaticity,
        settings.foreign_colour_rings,
    );
    for (n, f) in left_out.iter_mut().zip(foreign) {
        *n += f;
    }
    (groups, left_out)
}

/// Of each material's pixels (`groups`, in label order) on faces with a corner fewer than
/// `rings` rings of edges from the labels' boundary, leaves out those whose chromaticity lies
/// nearer another material's (`chromaticity`) than their own: where the labels' boundary is
/// off the true one, the pixels of the wrong side carry the other material's colour (the
/// default since session 51, 3 rings: docs/materials.md, "Another material's colour near the
/// boundary"). A material that would keep fewer than half of its pixels keeps them all, as in
/// [`interior_groups`]. Returns how many were left out per material. Pure.
pub fn drop_foreign_colours(
    mesh: &Mesh,
    vertex_labels: &[u32],
    groups: &mut [Vec<Observation>],
    chromaticity: &[[f64; 3]],
    rings: usize,
) -> Vec<usize> {
    let Some(rule) = ForeignColours::new(mesh, vertex_labels, chromaticity, rings) else {
        return vec![0; groups.len()];
    };
    groups
        .iter_mut()
        .enumerate()
        .map(|(l, g)| {
            let own_colour = |o: &Observation| !rule.is_foreign(o.face, l, o.reflectance);
            let kept = g.iter().filter(|o| own_colour(o)).count();
            if kept * 2 < g.len() {
                return 0;
            }
            let before = g.len();
            g.retain(own_colour);
            before - kept
        })
        .collect()
}

/// The rule of [`drop_foreign_colours`] for one pixel at a time: a pixel of material `label`
/// on a face with a corner fewer than `rings` rings from the labels' boundary whose
/// chromaticity lies nearer another material's mean than its own. Shared by the fits and the
/// normal refinement's reflectance tables (`reconstruct::prepare`). Pure.
pub struct ForeignColours<'a> {
    mesh: &'a Mesh,
    ring: Vec<usize>,
    rings: usize,
    chromaticity: &'a [[f64; 3]],
}

impl<'a> ForeignColours<'a> {
    /// `None` when the rule cannot apply (`rings` 0, or fewer than two materials).
    pub fn new(
        mesh: &'a Mesh,
        vertex_labels: &[u32],
        chromaticity: &'a [[f64; 3]],
        rings: usize,
    ) -> Option<Self> {
        if rings == 0 || chromaticity.len() < 2 {
            return None;
        }
        Some(Self {
            mesh,
            ring: rings_from_boundary(mesh, vertex_labels, rings),
            rings,
            chromaticity,
        })
    }

    /// Whether a pixel of material `label` seen on `face` with `reflectance` (r, g, b) carries
    /// another material's colour near the boundary. A pixel of no colour (non-positive or not
    /// finite) or of a material without a mean is never foreign.
    pub fn is_foreign(&self, face: u32, label: usize, reflectance: [f64; 3]) -> bool {
        let Some(own) = self.chromaticity.get(label) else {
            return false;
        };
        let near = self.mesh.faces().get(face as usize).is_some_and(|f| {
            f.iter()
                .any(|&v| self.ring.get(v as usize).is_some_and(|&r| r < self.rings))
        });
        let t: f64 = reflectance.iter().sum();
        if !near || !t.is_finite() || t <= 0.0 {
            return false;
        }
        let c = reflectance.map(|x| x / t);
        let dist2 = |m: &[f64; 3]| (0..3).map(|i| (c[i] - m[i]).powi(2)).sum::<f64>();
        let d = dist2(own);
        self.chromaticity
            .iter()
            .enumerate()
            .any(|(m, other)| m != label && dist2(other) < d)
    }
}

/// Per vertex, the rings of edges between it and the nearest vertex with a neighbour of
/// another label (0 for such a vertex), counted up to `max` (farther vertices get `max`).
fn rings_from_boundary(mesh: &Mesh, vertex_labels: &[u32], max: usize) -> Vec<usize> {
    let nb = mesh.vertex_neighbours();
    let label = |v: usize| vertex_labels.get(v).copied();
    let mut ring = vec![max; nb.len()];
    let mut front: Vec<usize> = (0..nb.len())
        .filter(|&v| nb[v].iter().any(|&u| label(u as usize) != label(v)))
        .collect();
    for &v in &front {
        ring[v] = 0;
    }
    for r in 1..max {
        let mut next = Vec::new();
        for v in front {
            for &u in &nb[v] {
                let u = u as usize;
                if ring[u] > r {
                    ring[u] = r;
                    next.push(u);
                }
            }
        }
        front = next;
    }
    ring
}

/// The vertex of `o`'s face nearest to where it was seen.
fn nearest_corner(mesh: &Mesh, o: &Observation) -> Option<usize> {
    if o.face == NO_FACE {
        return None;
    }
    let f = mesh.faces().get(o.face as usize)?;
    let p = mesh.positions();
    f.iter()
        .map(|&v| v as usize)
        .filter(|&v| v < p.len())
        .min_by(|&a, &b| {
            let da = (p[a] - o.position).norm_squared();
            let db = (p[b] - o.position).norm_squared();
            da.total_cmp(&db)
        })
}

/// The scaled features of the observed vertices.
struct Features {
    /// Per vertex: `Some(index into points)` when observed.
    slot: Vec<Option<usize>>,
    points: Vec<[f64; 3]>,
    /// Pixels pooled per point.
    weight: Vec<f64>,
    /// Per point: the chromaticity (r, g shares, scaled as the features) of the pooled pixels
    /// at or below their median level: the body colour, which a dielectric's white highlight
    /// or grazing reflection does not move.
    body: Vec<[f64; 2]>,
}

/// The features of the observations `keep` admits, each at its nearest corner (`corners`, in
/// the order of `obs`), each vertex's pixels pooled with its one-ring's (`pool`, what the
/// labelling uses) or alone: the pixels are read in their order, so a subset gives what the
/// same pixels copied out would.
fn features(
    mesh: &Mesh,
    nb: &[Vec<u32>],
    obs: &[Observation],
    corners: &[Option<usize>],
    keep: impl Fn(usize) -> bool,
    settings: &SegmentSettings,
    pool: bool,
) -> Features {
    let n = mesh.positions().len();
    let mut per_vertex: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, o) in obs.iter().enumerate() {
        if !keep(i) {
            continue;
        }
        let finite = o.reflectance.iter().all(|v| v.is_finite() && *v > 0.0);
        if let (true, Some(v)) = (finite, corners[i]) {
            per_vertex[v].push(i);
        }
    }
    let mut slot = vec![None; n];
    let mut points = Vec::new();
    let mut weight = Vec::new();
    let mut body = Vec::new();
    for v in 0..n {
        if per_vertex[v].is_empty() {
            continue;
        }
        let ring: &[u32] = if pool { &nb[v] } else { &[] };
        let pooled: Vec<usize> = std::iter::once(v)
            .chain(ring.iter().map(|&u| u as usize))
            .flat_map(|u| per_vertex[u].iter().copied())
            .collect();
        let mut sum = [0.0f64; 3];
        let mut levels: Vec<f64> = Vec::with_capacity(pooled.len());
        for &i in &pooled {
            let r = obs[i].reflectance;
            for c in 0..3 {
                sum[c] += r[c];
            }
            levels.push(((r[0] + r[1] + r[2]) / 3.0).ln());
        }
        let total = sum[0] + sum[1] + sum[2];
        let Some(level) = crate::stats::median(&mut levels.clone()) else {
            continue;
        };
        if !(total > 0.0 && total.is_finite()) {
            continue;
        }
        let mut dark = [0.0f64; 3];
        for (&i, &l) in pooled.iter().zip(&levels) {
            if l <= level {
                for (d, x) in dark.iter_mut().zip(obs[i].reflectance) {
                    *d += x;
                }
            }
        }
        let dark_total = dark[0] + dark[1] + dark[2];
        body.push(if dark_total > 0.0 && dark_total.is_finite() {
            [
                dark[0] / dark_total / settings.chroma_scale,
                dark[1] / dark_total / settings.chroma_scale,
            ]
        } else {
            [
                sum[0] / total / settings.chroma_scale,
                sum[1] / total / settings.chroma_scale,
            ]
        });
        slot[v] = Some(points.len());
        points.push([
            sum[0] / total / settings.chroma_scale,
            sum[1] / total / settings.chroma_scale,
            level / settings.level_scale,
        ]);
        weight.push(per_vertex[v].len() as f64);
    }
    Features {
        slot,
        points,
        weight,
        body,
    }
}

/// Moves the labels' boundary to where the pixels put it. The features pool each vertex's
/// pixels with its one-ring's, so a vertex beside the boundary carries some of the other
/// material's colour and the labels' boundary runs a ring or two off the true one (session 51:
/// 80 of the 89 mislabelled vertices of the half Spot, seed 2, on or one ring from it). Here
/// each vertex on the boundary (a neighbour of another label; not fixed; at least
/// [`RELABEL_MIN_PIXELS`] pixels of its own) takes, of its own material and its neighbours',
/// the one whose centre its own pixels' body colour and level (unpooled: [`Features::body`]
/// and the median level) are nearest, when nearer by more than one squared unit than its own
/// material's. The centres are the materials' pixel-weighted mean of the same unpooled
/// features. `passes` rounds, each on the boundary the last one left. Returns how many
/// vertices changed material. Pure.
fn relabel_boundary(
    own: &Features,
    nb: &[Vec<u32>],
    labels: &mut [u32],
    count: usize,
    fixed: &[Option<u32>],
    passes: usize,
) -> usize {
    if count < 2 || passes == 0 {
        return 0;
    }
    let point = |v: usize| -> Option<([f64; 3], f64)> {
        let i = own.slot.get(v).copied().flatten()?;
        let b = own.body[i];
        Some(([b[0], b[1], own.points[i][2]], own.weight[i]))
    };
    let mut sums = vec![([0.0f64; 3], 0.0f64); count];
    for (v, &l) in labels.iter().enumerate() {
        if let Some((p, w)) = point(v)
            && let Some(s) = sums.get_mut(l as usize)
        {
            for (acc, x) in s.0.iter_mut().zip(p) {
                *acc += w * x;
            }
            s.1 += w;
        }
    }
    let centres: Vec<Option<[f64; 3]>> = sums
        .iter()
        .map(|(s, w)| (*w > 0.0).then(|| s.map(|x| x / w)))
        .collect();
    let mut moved = vec![false; labels.len()];
    for _ in 0..passes {
        let changes: Vec<(usize, u32)> = (0..labels.len())
            .filter(|&v| fixed.get(v).copied().flatten().is_none())
            .filter_map(|v| {
                let (p, w) = point(v)?;
                if w < RELABEL_MIN_PIXELS as f64 {
                    return None;
                }
                let own_label = labels[v];
                let others: Vec<u32> = nb[v]
                    .iter()
                    .map(|&u| labels[u as usize])
                    .filter(|&l| l != own_label)
                    .collect();
                if others.is_empty() {
                    return None;
                }
                let d = |l: u32| {
                    centres
                        .get(l as usize)
                        .copied()
                        .flatten()
                        .map_or(f64::INFINITY, |c| dist2(&p, &c))
                };
                let here = d(own_label);
                let (best, d_best) = others
                    .iter()
                    .map(|&l| (l, d(l)))
                    .min_by(|a, b| a.1.total_cmp(&b.1))?;
                (d_best + 1.0 < here).then_some((v, best))
            })
            .collect();
        if changes.is_empty() {
            break;
        }
        for (v, l) in changes {
            labels[v] = l;
            moved[v] = !moved[v];
        }
    }
    moved.iter().filter(|&&m| m).count()
}

/// A boundary vertex needs this many pixels of its own to be relabelled ([`relabel_boundary`]).
pub const RELABEL_MIN_PIXELS: usize = 3;

fn dist2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]) * (a[i] - b[i])).sum()
}

/// Squared distance of `c` from the segment between `a` and `b`, inside its middle 80 %
/// (infinite outside it: a point near an end is near that material, not between two).
fn between(a: &[f64; 3], b: &[f64; 3], c: &[f64; 3]) -> f64 {
    let ab: Vec<f64> = (0..3).map(|i| b[i] - a[i]).collect();
    let len2: f64 = ab.iter().map(|x| x * x).sum();
    if len2 <= 0.0 {
        return f64::INFINITY;
    }
    let t = (0..3).map(|i| (c[i] - a[i]) * ab[i]).sum::<f64>() / len2;
    if !(0.1..=0.9).contains(&t) {
        return f64::INFINITY;
    }
    let p = [a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]];
    dist2(&p, c)
}

/// Weighted k-means with k-means++ seeding and restarts; the centres of the best restart.
/// `given`: centres that stay where they are (the given materials, first in the result); the
/// others are seeded and moved among them, up to `k` in all.
fn kmeans(
    points: &[[f64; 3]],
    weight: &[f64],
    k: usize,
    given: &[[f64; 3]],
    restarts: usize,
    seed: u64,
) -> Vec<[f64; 3]> {
    let k = k.min(given.len() + points.len()).max(1);
    let mut best: Option<(f64, Vec<[f64; 3]>)> = None;
    for r in 0..restarts.max(1) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ (r as u64).wrapping_mul(0x9E37_79B9));
        let mut centres = given.to_vec();
        if centres.iter().all(|c| !c[0].is_finite()) {
            centres.push(points[rng.gen_range(0..points.len())]);
        }
        while centres.len() < k {
            let d: Vec<f64> = points
                .iter()
                .zip(weight)
                .map(|(p, w)| {
                    w * centres
                        .iter()
                        .map(|c| dist2(p, c))
                        .fold(f64::INFINITY, f64::min)
                })
                .collect();
            let total: f64 = d.iter().sum();
            if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                break;
            }
            let mut pick = rng.r#gen::<f64>() * total;
            let mut chosen = points.len() - 1;
            for (i, di) in d.iter().enumerate() {
                pick -= di;
                if pick <= 0.0 {
                    chosen = i;
                    break;
                }
            }
            centres.push(points[chosen]);
        }
        let mut cost = f64::INFINITY;
        for _ in 0..50 {
            let mut sums = vec![[0.0f64; 4]; centres.len()];
            let mut c = 0.0;
            for (p, w) in points.iter().zip(weight) {
                let (j, d) = nearest(&centres, p);
                c += w * d;
                for i in 0..3 {
                    sums[j][i] += w * p[i];
                }
                sums[j][3] += w;
            }
            let moved: Vec<[f64; 3]> = sums
                .iter()
                .zip(&centres)
                .enumerate()
                .map(|(j, (s, old))| {
                    if j >= given.len() && s[3] > 0.0 {
                        [s[0] / s[3], s[1] / s[3], s[2] / s[3]]
                    } else {
                        *old
                    }
                })
                .collect();
            let done = moved == centres;
            centres = moved;
            cost = c;
            if done {
                break;
            }
        }
        if best.as_ref().is_none_or(|(b, _)| cost < *b) {
            best = Some((cost, centres));
        }
    }
    best.map(|b| b.1).unwrap_or_default()
}

fn nearest(centres: &[[f64; 3]], p: &[f64; 3]) -> (usize, f64) {
    centres
        .iter()
        .enumerate()
        .map(|(j, c)| (j, dist2(p, c)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((0, 0.0))
}

/// Labels every vertex: nearest centre where observed, then ICM sweeps with the Potts cost
/// (unobserved vertices take their neighbours' majority). A vertex `fixed` to a material keeps
/// it (and pulls its neighbours through the Potts cost).
fn smooth_labels(
    f: &Features,
    nb: &[Vec<u32>],
    centres: &[[f64; 3]],
    smoothness: f64,
    fixed: &[Option<u32>],
) -> Vec<u32> {
    let n = f.slot.len();
    let none = u32::MAX;
    let fixed_of = |v: usize| fixed.get(v).copied().flatten();
    let mut labels: Vec<u32> = f
        .slot
        .iter()
        .enumerate()
        .map(|(v, s)| match fixed_of(v) {
            Some(l) => l,
            None => s.map_or(none, |i| nearest(centres, &f.points[i]).0 as u32),
        })
        .collect();
    // Unobserved vertices: breadth-first from the observed ones.
    let mut frontier: Vec<usize> = (0..n).filter(|&v| labels[v] != none).collect();
    while !frontier.is_empty() {
        let mut next = Vec::new();
        for &v in &frontier {
            for &u in &nb[v] {
                let u = u as usize;
                if labels[u] == none {
                    labels[u] = labels[v];
                    next.push(u);
                }
            }
        }
        frontier = next;
    }
    for l in &mut labels {
        if *l == none {
            *l = 0; // a part of the mesh no pixel reaches, not connected to any that is seen
        }
    }
    // Neighbours per label, counted once per vertex (the cost of every label reads it).
    let mut same = vec![0usize; centres.len()];
    // A vertex none of whose neighbours changed since it was last visited would choose its
    // label again: only the others are visited (the same sweeps, in the same order, as
    // visiting every vertex).
    let mut dirty = vec![true; n];
    for _ in 0..10 {
        let mut changed = 0;
        for v in (0..n).filter(|&v| fixed_of(v).is_none()) {
            if !dirty[v] {
                continue;
            }
            dirty[v] = false;
            same.fill(0);
            for &u in &nb[v] {
                if let Some(c) = same.get_mut(labels[u as usize] as usize) {
                    *c += 1;
                }
            }
            let cost = |k: usize| {
                let data = f.slot[v].map_or(0.0, |i| {
                    f.weight[i].min(8.0) * dist2(&f.points[i], &centres[k])
                });
                data + smoothness * (nb[v].len() - same[k]) as f64
            };
            let best = (0..centres.len())
                .map(|k| (k, cost(k)))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map_or(0, |(k, _)| k) as u32;
            if best != labels[v] {
                labels[v] = best;
                changed += 1;
                for &u in &nb[v] {
                    dirty[u as usize] = true;
                }
            }
        }
        if changed == 0 {
            break;
        }
    }
    labels
}

/// Labels for `asked` materials from these observations; small or close materials merged.
/// Returns the vertex labels (0..found) and the count found. The materials given by `fixed`
/// (per vertex; [`given_count`] of them) are materials `0..given`: their centres are their
/// fixed vertices' mean features, they are never merged away, and their vertices keep them;
/// `asked` counts them, so only the rest are found by k-means among the free vertices.
fn label_vertices(
    f: &Features,
    nb: &[Vec<u32>],
    asked: usize,
    settings: &SegmentSettings,
    fixed: &[Option<u32>],
) -> (Vec<u32>, usize) {
    let n = f.slot.len();
    let given = given_count(fixed);
    if given == 0 && (asked <= 1 || f.points.len() < 2 * asked) {
        return (vec![0; n], 1);
    }
    let is_fixed = |v: usize| fixed.get(v).copied().flatten().is_some();
    let free: Vec<usize> = (0..n)
        .filter(|&v| !is_fixed(v))
        .filter_map(|v| f.slot[v])
        .collect();
    let extra = asked.saturating_sub(given);
    let given_centres = given_centres(f, fixed, given);
    let mut centres = if extra == 0 || free.len() < 2 * extra {
        given_centres
    } else {
        let points: Vec<[f64; 3]> = free.iter().map(|&i| f.points[i]).collect();
        let weight: Vec<f64> = free.iter().map(|&i| f.weight[i]).collect();
        kmeans(
            &points,
            &weight,
            given + extra,
            &given_centres,
            settings.restarts,
            settings.seed,
        )
    };
    loop {
        let labels = smooth_labels(f, nb, &centres, settings.smoothness, fixed);
        let observed = f.slot.iter().filter(|s| s.is_some()).count().max(1);
        let mut counts = vec![0usize; centres.len()];
        for (v, s) in f.slot.iter().enumerate() {
            if s.is_some() {
                counts[labels[v] as usize] += 1;
            }
        }
        // The weakest found material (a given one is never dropped): too small, or too close
        // to another to be a material.
        let small = (given..centres.len())
            .filter(|&j| (counts[j] as f64) < settings.min_share * observed as f64)
            .min_by_key(|&j| counts[j]);
        let dropped_of = |(a, b): (usize, usize)| {
            if a < given || counts[b] <= counts[a] {
                b
            } else {
                a
            }
        };
        let close = (0..centres.len())
            .flat_map(|a| ((a + 1).max(given)..centres.len()).map(move |b| (a, b)))
            .filter(|&(a, b)| dist2(&centres[a], &centres[b]) < settings.merge_distance.powi(2))
            .min_by_key(|&p| counts[dropped_of(p)])
            .map(dropped_of);
        // One body colour: two materials whose darker pixels share a chromaticity (within
        // `merge_distance`) are one material whose highlights or grazing reflections whitened
        // part of it.
        let same_body = if settings.merge_same_body {
            let body = body_colours(f, &labels, centres.len());
            (0..centres.len())
                .flat_map(|a| ((a + 1).max(given)..centres.len()).map(move |b| (a, b)))
                .filter(|&(a, b)| match (body[a], body[b]) {
                    (Some(x), Some(y)) => {
                        (x[0] - y[0]).powi(2) + (x[1] - y[1]).powi(2)
                            < settings.merge_distance.powi(2)
                    }
                    _ => false,
                })
                .min_by_key(|&p| counts[dropped_of(p)])
                .map(dropped_of)
        } else {
            None
        };
        // A blend: a smaller material lying on the segment between two others (within
        // `merge_distance`), as the mixed pixels where two materials meet do.
        let blend = (given..centres.len())
            .filter(|&c| {
                (0..centres.len()).any(|a| {
                    (0..centres.len()).any(|b| {
                        a != b
                            && a != c
                            && b != c
                            && counts[c] < counts[a].min(counts[b])
                            && between(&centres[a], &centres[b], &centres[c])
                                < settings.merge_distance.powi(2)
                    })
                })
            })
            .min_by_key(|&c| counts[c]);
        let Some(drop) = small.or(close).or(same_body).or(blend) else {
            return (labels, centres.len());
        };
        if centres.len() <= 1 {
            return (vec![0; n], 1);
        }
        centres.remove(drop);
    }
}

/// Per material: the pixel-weighted mean body colour ([`Features::body`]) of its observed
/// vertices; `None` for a material with none.
fn body_colours(f: &Features, labels: &[u32], materials: usize) -> Vec<Option<[f64; 2]>> {
    let mut sum = vec![[0.0f64; 3]; materials];
    for (v, s) in f.slot.iter().enumerate() {
        if let (Some(i), Some(&l)) = (s, labels.get(v))
            && let Some(acc) = sum.get_mut(l as usize)
        {
            let w = f.weight[*i];
            acc[0] += w * f.body[*i][0];
            acc[1] += w * f.body[*i][1];
            acc[2] += w;
        }
    }
    sum.iter()
        .map(|a| (a[2] > 0.0).then(|| [a[0] / a[2], a[1] / a[2]]))
        .collect()
}

/// The number of given materials in per-vertex fixed labels (`0..given`, dense).
fn given_count(fixed: &[Option<u32>]) -> usize {
    fixed.iter().flatten().max().map_or(0, |&m| m as usize + 1)
}

/// The centre of each given material: the pixel-weighted median, per feature, of its fixed
/// vertices that were observed here (a median, so that a label drawn over a little of a
/// neighbouring material does not move the material's centre); infinitely far (never the
/// nearest) when none was observed.
fn given_centres(f: &Features, fixed: &[Option<u32>], given: usize) -> Vec<[f64; 3]> {
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); given];
    for (v, l) in fixed.iter().enumerate() {
        if let (Some(l), Some(Some(i))) = (l, f.slot.get(v)) {
            members[*l as usize].push(*i);
        }
    }
    members
        .iter()
        .map(|m| {
            let median = |c: usize| {
                let mut values: Vec<(f64, f64)> =
                    m.iter().map(|&i| (f.points[i][c], f.weight[i])).collect();
                crate::stats::weighted_median(&mut values)
            };
            match (median(0), median(1), median(2)) {
                (Some(a), Some(b), Some(c)) => [a, b, c],
                _ => [f64::INFINITY; 3],
            }
        })
        .collect()
}

/// Relative image-space error of per-material fits on held-out pixels (the ladder's
/// `image_residual`, summed over the materials).
fn held_out_error(
    fits: &[Option<Box<dyn Candidate>>],
    held: &[(u32, &Observation)],
) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for (m, fit) in fits.iter().enumerate() {
        let own: Vec<Observation> = held
            .iter()
            .filter(|(l, _)| *l as usize == m)
            .map(|(_, o)| **o)
            .collect();
        if own.is_empty() {
            continue;
        }
        let (n, d) = image_residual(fit.as_deref()?, &own);
        num += n;
        den += d;
    }
    (den > 0.0 && num.is_finite()).then(|| (num / den).sqrt())
}

/// The count's model per material, each on at most `max_fit_pixels` of its pixels; a material with too few
/// pixels takes the fit of all of them.
fn fit_per_material(
    labelled: &[(u32, &Observation)],
    count: usize,
    settings: &SegmentSettings,
) -> Vec<Option<Box<dyn Candidate>>> {
    let ggx = match settings.count_model {
        // one fit of every training pixel: the shape is shared, the scales are cheap
        CountModel::SharedShape => return fit_shared_shape(labelled, count).unwrap_or_default(),
        CountModel::Lambert => false,
        CountModel::LambertGgx => true,
    };
    let fit = |obs: Vec<Observation>| -> Option<Box<dyn Candidate>> {
        let obs = subset(&obs, settings.max_fit_pixels, settings.seed ^ 0xF17);
        if ggx {
            fit_lambert_ggx(&obs).map(|b| Box::new(AnalyticCandidate(b)) as Box<dyn Candidate>)
        } else {
            fit_lambert(&obs).map(|b| Box::new(AnalyticCandidate(b)) as Box<dyn Candidate>)
        }
    };
    (0..count as u32)
        .map(|m| {
            let own: Vec<Observation> = labelled
                .iter()
                .filter(|(l, _)| *l == m)
                .map(|(_, o)| **o)
                .collect();
            if own.len() >= 30 {
                fit(own)
            } else {
                fit(labelled.iter().map(|(_, o)| **o).collect())
            }
        })
        .collect()
}

fn mean_se(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    if v.len() < 2 {
        return (mean, f64::INFINITY);
    }
    let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Finds the materials of the surface (see the module header).
pub fn segment(mesh: &Mesh, obs: &[Observation], settings: &SegmentSettings) -> Segmentation {
    segment_with_labels(mesh, obs, settings, &[])
}

/// [`segment`] with some vertices' materials given: `fixed[v] = Some(m)` keeps vertex `v` on
/// material `m` (dense, `0..given`; the job's label masks, `mask_labels`). The given materials
/// are materials `0..given` of the result, whatever the count; their centres are their fixed
/// vertices' mean features; the free vertices join the nearest material in feature space with
/// the same Potts smoothing. Counts from `given` (at least 1) to `max_materials` (or `given`,
/// if more) are tried and chosen by the same held-out rule, so a material the labels do not
/// name is added only when the held-out images call for it. The fixed labels hold in every
/// fold (they are the user's statement about the surface, not image data). Empty `fixed`:
/// exactly [`segment`].
pub fn segment_with_labels(
    mesh: &Mesh,
    obs: &[Observation],
    settings: &SegmentSettings,
    fixed: &[Option<u32>],
) -> Segmentation {
    let given = given_count(fixed);
    let nb = mesh.vertex_neighbours();
    let mut images: Vec<usize> = obs.iter().map(|o| o.image).collect();
    images.sort_unstable();
    images.dedup();
    let folds = settings.folds.min(images.len());
    // Per pixel, once: its fold, its nearest corner and whether it counts (away from the peak).
    let fold: Vec<usize> = obs
        .iter()
        .map(|o| images.binary_search(&o.image).unwrap_or(0) % folds.max(1))
        .collect();
    let corners: Vec<Option<usize>> = obs.iter().map(|o| nearest_corner(mesh, o)).collect();
    // the count is judged away from the specular peak (see the module header)
    let min_h = settings.count_min_theta_h_deg.to_radians();
    let off_peak: Vec<bool> = obs
        .iter()
        .map(|o| {
            min_h <= 0.0
                || crate::brdf::coords::MerlBin::from_index(o.bin)
                    .is_some_and(|b| b.centre().theta_h >= min_h)
        })
        .collect();
    // The features depend on the pixels, not on the count: once for every pixel and once per
    // fold's training pixels.
    let all_features = features(mesh, &nb, obs, &corners, |_| true, settings, true);
    let fold_features: Vec<Features> = if folds < 2 {
        Vec::new()
    } else {
        (0..folds)
            .into_par_iter()
            .map(|k| features(mesh, &nb, obs, &corners, |i| fold[i] != k, settings, true))
            .collect()
    };
    let mut scores = Vec::new();
    let mut full = Vec::new();
    let first = given.max(1);
    let last = settings.max_materials.max(first);
    for asked in first..=last {
        let (labels, found) = label_vertices(&all_features, &nb, asked, settings, fixed);
        if asked > 1 && full.iter().any(|(_, f, _)| *f == found) {
            // merging gave a count already tried: nothing new to score
            scores.push(CountScore {
                asked,
                found,
                fold_errors: Vec::new(),
                error: None,
                standard_error: None,
            });
            continue;
        }
        // a single count needs no score
        let fold_errors: Vec<Option<f64>> = if first == last {
            Vec::new()
        } else {
            fold_features
                .par_iter()
                .enumerate()
                .map(|(k, train_features)| {
                    let (train_labels, train_found) =
                        label_vertices(train_features, &nb, asked, settings, fixed);
                    // the fold's pixels away from the peak, with the training labels
                    let labelled_where = |in_fold: bool| -> Vec<(u32, &Observation)> {
                        obs.iter()
                            .enumerate()
                            .filter(|&(i, _)| (fold[i] == k) == in_fold && off_peak[i])
                            .filter_map(|(i, o)| {
                                let l = corners[i].and_then(|v| train_labels.get(v).copied())?;
                                Some((l, o))
                            })
                            .collect()
                    };
                    let labelled = labelled_where(false);
                    let held = labelled_where(true);
                    let fits = fit_per_material(&labelled, train_found, settings);
                    held_out_error(&fits, &held)
                })
                .collect()
        };
        let scored: Vec<f64> = fold_errors.iter().flatten().copied().collect();
        let (error, standard_error) = if scored.len() == fold_errors.len() && !scored.is_empty() {
            let (m, s) = mean_se(&scored);
            (Some(m), Some(s))
        } else {
            (None, None)
        };
        scores.push(CountScore {
            asked,
            found,
            fold_errors,
            error,
            standard_error,
        });
        full.push((scores.len() - 1, found, labels));
    }
    let scored = scores.iter().any(|s| s.error.is_some());
    let (chosen, reason) = if given > 0 && !scored {
        let why = if first == last {
            format!(
                "no other count was tried (at most {} asked)",
                settings.max_materials
            )
        } else {
            "no other count could be scored on held-out images".to_string()
        };
        (
            0,
            format!("the job's label masks give {given} material(s); {why}"),
        )
    } else {
        let (c, r) = choose_count(&scores, settings.min_gain);
        match given {
            0 => (c, r),
            _ => (
                c,
                format!("{r}; the job's label masks give {given} of them"),
            ),
        }
    };
    let (_, count, mut vertex_labels) = full
        .iter()
        .find(|(i, _, _)| *i == chosen)
        .cloned()
        .unwrap_or((0, 1, vec![0; mesh.positions().len()]));
    if settings.relabel_passes > 0 && count > 1 {
        let own = features(mesh, &nb, obs, &corners, |_| true, settings, false);
        relabel_boundary(
            &own,
            &nb,
            &mut vertex_labels,
            count,
            fixed,
            settings.relabel_passes,
        );
    }
    let mut fixed_vertices = vec![0usize; count];
    for (v, l) in vertex_labels.iter().enumerate() {
        if fixed.get(v).copied().flatten().is_some()
            && let Some(c) = fixed_vertices.get_mut(*l as usize)
        {
            *c += 1;
        }
    }
    let mut observed_vertices = vec![0usize; count];
    let mut sums = vec![[0.0f64; 3]; count];
    let mut seen = vec![false; mesh.positions().len()];
    for (o, corner) in obs.iter().zip(&corners) {
        if let Some(v) = *corner {
            let l = vertex_labels[v] as usize;
            if !seen[v] {
                seen[v] = true;
                observed_vertices[l] += 1;
            }
            if o.reflectance.iter().all(|x| x.is_finite()) {
                for (s, r) in sums[l].iter_mut().zip(o.reflectance) {
                    *s += r;
                }
            }
        }
    }
    let chromaticity = sums
        .iter()
        .map(|s| {
            let t = s[0] + s[1] + s[2];
            if t > 0.0 {
                [s[0] / t, s[1] / t, s[2] / t]
            } else {
                [1.0 / 3.0; 3]
            }
        })
        .collect();
    Segmentation {
        count,
        vertex_labels,
        observed_vertices,
        chromaticity,
        fixed_vertices,
        given,
        scores,
        reason,
    }
}

/// The simplest count within one standard error of the best, the error of each count's
/// difference to the best taken over the same folds (paired), or within `min_gain`.
fn choose_count(scores: &[CountScore], min_gain: f64) -> (usize, String) {
    let Some(best) = scores
        .iter()
        .enumerate()
        .filter(|(_, s)| s.error.is_some())
        .min_by(|a, b| {
            a.1.error
                .unwrap_or(f64::INFINITY)
                .total_cmp(&b.1.error.unwrap_or(f64::INFINITY))
        })
        .map(|(i, _)| i)
    else {
        return (
            0,
            "no count of materials could be scored on held-out images: one material".into(),
        );
    };
    let b = &scores[best];
    for (i, s) in scores.iter().enumerate() {
        let Some(e) = s.error else { continue };
        let diffs: Vec<f64> = s
            .fold_errors
            .iter()
            .zip(&b.fold_errors)
            .filter_map(|(x, y)| Some((*x)? - (*y)?))
            .collect();
        let (d, se) = if diffs.is_empty() {
            (e - b.error.unwrap_or(e), 0.0)
        } else {
            mean_se(&diffs)
        };
        let gain = min_gain * b.error.unwrap_or(0.0);
        if i == best || d <= se.max(gain) {
            let why = if i == best {
                format!(
                    "{} material(s) rendered the held-out images best ({:.4})",
                    s.found, e
                )
            } else {
                let within = if d <= se {
                    "one standard error".to_string()
                } else {
                    format!(
                        "{:.0} % (the least gain worth a material)",
                        100.0 * min_gain
                    )
                };
                format!(
                    "{} material(s) are within {within} of the best ({} material(s)): \
                     held-out image error {:.4} against {:.4} (paired difference {:.4} +- {:.4})",
                    s.found,
                    b.found,
                    e,
                    b.error.unwrap_or(f64::NAN),
                    d,
                    se
                )
            };
            return (i, why);
        }
    }
    (best, "the best held-out error".into())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::brdf::Brdf;
    use crate::brdf::analytic::LambertGgx;
    use crate::reconstruct::observation::Seen;
    use nalgebra::{Point3, Vector3};

    /// A flat grid of `n` x `n` vertices in the xy plane (normal +z), two triangles per cell.
    pub(crate) fn grid(n: usize) -> Mesh {
        let mut p = Vec::new();
        for j in 0..n {
            for i in 0..n {
                p.push(Point3::new(i as f64, j as f64, 0.0));
            }
        }
        let mut f: Vec<[i64; 3]> = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = (j * n + i) as i64;
                let b = a + 1;
                let c = a + n as i64;
                let d = c + 1;
                f.push([a, b, d]);
                f.push([a, d, c]);
            }
        }
        Mesh::new(p, f, "grid").expect("a valid grid").0
    }

    /// Pixels on every face of the grid, in `images` images with lights from several
    /// directions, shaded by the material of the face's left (x < split) or right half. The
    /// surface's true normal is the grid's tilted by up to 6 degrees per face (a photogrammetry
    /// mesh's error: the observations keep the grid's +z) and each pixel has 3 % noise.
    pub(crate) fn scene(
        mesh: &Mesh,
        materials: &[LambertGgx],
        split: f64,
        images: usize,
    ) -> Vec<Observation> {
        let last = materials.len() - 1;
        scene_by(
            mesh,
            materials,
            |c| if c.x < split { 0 } else { 1.min(last) },
            images,
        )
    }

    /// [`scene`] with the material of a face given by `material_of` its centroid.
    fn scene_by(
        mesh: &Mesh,
        materials: &[LambertGgx],
        material_of: impl Fn(&Point3<f64>) -> usize,
        images: usize,
    ) -> Vec<Observation> {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut obs = Vec::new();
        let view = Vector3::z();
        let tilts: Vec<Vector3<f64>> = (0..mesh.faces().len())
            .map(|_| {
                let t = rng.gen_range(0.0..6.0f64).to_radians();
                let p = rng.gen_range(0.0..std::f64::consts::TAU);
                Vector3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
            })
            .collect();
        for img in 0..images {
            let a = 0.2 + 0.9 * img as f64 / images as f64;
            let light = Vector3::new(
                a.sin() * (img as f64).cos(),
                a.sin() * (img as f64).sin(),
                a.cos(),
            );
            for (fi, _) in mesh.faces().iter().enumerate() {
                let t = mesh.triangle(fi);
                let c = Point3::from((t[0].coords + t[1].coords + t[2].coords) / 3.0);
                let m = material_of(&c);
                let n = tilts[fi];
                let (wi, wo) = super::super::observation::to_local(&n, &light, &view);
                let fr = materials[m].eval_local(&wi, &wo);
                let cos = n.dot(&light).max(0.0);
                let rad = [0, 1, 2].map(|c| fr[c] * cos * (1.0 + 0.03 * rng.gen_range(-1.0..1.0)));
                let seen = Seen {
                    face: fi as u32,
                    position: c,
                    ..Seen::pixel(img, fi as u32, 0, Vector3::z())
                };
                if let Some(o) = Observation::new(seen, light, view, rad, [1.0; 3]) {
                    obs.push(o);
                }
            }
        }
        obs
    }

    pub(crate) fn ggx(rgb: [f64; 3], alpha: f64) -> LambertGgx {
        LambertGgx {
            kd: rgb,
            ks: [0.3; 3],
            alpha,
            f0: 0.04,
        }
    }

    #[test]
    fn a_region_whitened_by_highlights_has_its_body_colour_and_is_merged_back() {
        // One orange material; on the left half one pixel in three is a white highlight, which
        // moves the left half's chromaticity far from the right half's but not its darker
        // pixels' (its body colour).
        let mesh = grid(12);
        let nb = mesh.vertex_neighbours();
        let view = Vector3::z();
        let orange = [0.30, 0.15, 0.05];
        let mut obs = Vec::new();
        for img in 0..4 {
            let light =
                Vector3::new(0.3 * (img as f64).cos(), 0.3 * (img as f64).sin(), 1.0).normalize();
            for fi in 0..mesh.faces().len() {
                let t = mesh.triangle(fi);
                let c = Point3::from((t[0].coords + t[1].coords + t[2].coords) / 3.0);
                for k in 0..3 {
                    let rgb = if c.x < 5.5 && k == 2 {
                        [0.9, 0.85, 0.8]
                    } else {
                        orange.map(|x| x * (1.0 + 0.02 * k as f64))
                    };
                    let cos = light.z;
                    let seen = Seen {
                        face: fi as u32,
                        position: c,
                        ..Seen::pixel(img, fi as u32, k, Vector3::z())
                    };
                    if let Some(o) =
                        Observation::new(seen, light, view, rgb.map(|x| x * cos), [1.0; 3])
                    {
                        obs.push(o);
                    }
                }
            }
        }
        let settings = SegmentSettings::default();
        let corners: Vec<Option<usize>> = obs.iter().map(|o| nearest_corner(&mesh, o)).collect();
        let f = features(&mesh, &nb, &obs, &corners, |_| true, &settings, true);
        let off = SegmentSettings {
            merge_same_body: false,
            ..settings
        };
        assert_eq!(label_vertices(&f, &nb, 2, &off, &[]).1, 2);
        let (labels, found) = label_vertices(&f, &nb, 2, &settings, &[]);
        assert_eq!(found, 1);
        let body = body_colours(&f, &labels, 1);
        let b = body[0].expect("observed");
        // the body colour is orange's chromaticity (0.6, 0.3), in chroma_scale units
        assert!(
            (b[0] - 0.6 / 0.02).abs() < 0.5 && (b[1] - 0.3 / 0.02).abs() < 0.5,
            "{b:?}"
        );
    }

    #[test]
    fn one_material_gives_one() {
        let mesh = grid(16);
        let obs = scene(&mesh, &[ggx([0.3, 0.2, 0.1], 0.3)], 8.0, 6);
        let s = segment(&mesh, &obs, &SegmentSettings::default());
        assert_eq!(s.count, 1, "{:?}", s.scores);
        assert!(s.vertex_labels.iter().all(|&l| l == 0));
    }

    #[test]
    fn two_colours_give_two_split_where_they_meet() {
        let mesh = grid(16);
        let obs = scene(
            &mesh,
            &[ggx([0.35, 0.08, 0.1], 0.3), ggx([0.05, 0.25, 0.1], 0.2)],
            7.5,
            6,
        );
        let s = segment(&mesh, &obs, &SegmentSettings::default());
        assert_eq!(s.count, 2, "{} / {:?}", s.reason, s.scores);
        // every vertex well inside a half carries that half's label
        let p = mesh.positions();
        let left = s.vertex_labels[0];
        let wrong = p
            .iter()
            .zip(&s.vertex_labels)
            .filter(|(q, _)| (q.x - 7.5).abs() > 1.5)
            .filter(|(q, l)| (q.x < 7.5) != (**l == left))
            .count();
        assert_eq!(wrong, 0, "labels {:?}", s.vertex_labels);
        // the held-out error of two materials is far below that of one
        let e = |n: usize| s.scores.iter().find(|c| c.found == n).and_then(|c| c.error);
        assert!(e(2).unwrap() < 0.5 * e(1).unwrap(), "{:?}", s.scores);
    }

    /// Two materials split at x = 3.5, and a third that is one column of vertices (x = 7):
    /// no face has all three corners in it.
    fn three_bands(mesh: &Mesh) -> Vec<u32> {
        mesh.positions()
            .iter()
            .map(|v| match v.x {
                x if x < 3.5 => 0,
                x if x > 6.5 => 2,
                _ => 1,
            })
            .collect()
    }

    #[test]
    fn boundary_faces_are_left_out_of_the_fits_unless_a_material_would_lose_half() {
        let mesh = grid(8);
        let obs = scene(&mesh, &[ggx([0.3, 0.2, 0.1], 0.3)], 8.0, 2);
        let labels = three_bands(&mesh);
        let seg = Segmentation {
            count: 3,
            vertex_labels: labels.clone(),
            observed_vertices: vec![0; 3],
            chromaticity: vec![[1.0 / 3.0; 3]; 3],
            fixed_vertices: vec![0; 3],
            given: 0,
            scores: Vec::new(),
            reason: String::new(),
        };
        let (all, none_dropped) = interior_groups(&mesh, &labels, 3, &obs, false, 0);
        assert_eq!(none_dropped, vec![0, 0, 0]);
        for (l, g) in all.iter().enumerate() {
            assert!(!g.is_empty());
            assert!(g.iter().all(|o| seg.label_of(&mesh, o) == Some(l as u32)));
        }
        let (inner, dropped) = interior_groups(&mesh, &labels, 3, &obs, true, 0);
        let pure = |o: &Observation, l: usize| {
            mesh.faces()[o.face as usize]
                .iter()
                .all(|&v| labels[v as usize] as usize == l)
        };
        for l in 0..2 {
            assert!(inner[l].iter().all(|o| pure(o, l)), "material {l}");
            let mixed = all[l].iter().filter(|o| !pure(o, l)).count();
            assert!(mixed > 0, "material {l} has boundary pixels");
            assert_eq!(dropped[l], mixed);
            assert_eq!(inner[l].len() + dropped[l], all[l].len());
        }
        // The one-column material has no interior face: it keeps every pixel.
        assert_eq!(dropped[2], 0);
        assert_eq!(inner[2].len(), all[2].len());
    }

    #[test]
    fn rings_around_the_boundary_leave_out_the_faces_near_it_too() {
        let mesh = grid(8);
        let obs = scene(&mesh, &[ggx([0.3, 0.2, 0.1], 0.3)], 8.0, 2);
        let labels = three_bands(&mesh);
        let p = mesh.positions();
        // rings counted from the last column of material 0 (x = 3, beside x = 4), capped at 3
        let ring = rings_from_boundary(&mesh, &labels, 3);
        for (q, r) in p.iter().zip(&ring).filter(|(q, _)| q.x < 3.5) {
            assert_eq!(*r, (3.0 - q.x).round() as usize, "vertex at x = {}", q.x);
        }
        let (all, _) = interior_groups(&mesh, &labels, 3, &obs, false, 0);
        let (across, _) = interior_groups(&mesh, &labels, 3, &obs, true, 0);
        let (inner, dropped) = interior_groups(&mesh, &labels, 3, &obs, true, 1);
        // material 0 keeps only the faces whose corners all lie at x <= 2
        let corners_within = |o: &Observation, x_max: f64| {
            mesh.faces()[o.face as usize]
                .iter()
                .all(|&v| p[v as usize].x <= x_max + 1e-9)
        };
        assert!(!inner[0].is_empty());
        assert!(inner[0].len() < across[0].len());
        assert!(inner[0].iter().all(|o| corners_within(o, 2.0)));
        assert_eq!(
            inner[0].len(),
            all[0].iter().filter(|o| corners_within(o, 2.0)).count()
        );
        assert_eq!(inner[0].len() + dropped[0], all[0].len());
        // material 1 (x = 4 to 6) has no face a ring from both its boundaries: it keeps every
        // pixel, as a thin strip does
        assert_eq!(dropped[1], 0);
        assert_eq!(inner[1].len(), all[1].len());
    }

    #[test]
    fn pixels_of_another_materials_colour_near_the_boundary_are_left_out() {
        // Red faces left of x = 4.5, blue right of it; the labels put the boundary a column of
        // faces further left (x = 3.5), so the red faces between x = 4 and 4.5 are labelled blue.
        let mesh = grid(8);
        let (red, blue) = (ggx([0.5, 0.05, 0.05], 0.3), ggx([0.05, 0.05, 0.5], 0.3));
        let obs = scene(&mesh, &[red, blue], 4.5, 4);
        let p = mesh.positions();
        let labels: Vec<u32> = p.iter().map(|v| u32::from(v.x > 3.5)).collect();
        let chroma = |c: [f64; 3]| c.map(|x| x / c.iter().sum::<f64>());
        let seg = Segmentation {
            count: 2,
            vertex_labels: labels.clone(),
            observed_vertices: vec![0; 2],
            chromaticity: vec![chroma(red.kd), chroma(blue.kd)],
            fixed_vertices: vec![0; 2],
            given: 0,
            scores: Vec::new(),
            reason: String::new(),
        };
        let is_red = |o: &Observation| {
            let t = mesh.triangle(o.face as usize);
            (t[0].x + t[1].x + t[2].x) / 3.0 < 4.5
        };
        let settings = |rings| SegmentSettings {
            foreign_colour_rings: rings,
            ..SegmentSettings::default()
        };
        let (kept, _) = fit_groups(&mesh, &seg, &obs, &settings(0));
        let red_in_blue = kept[1].iter().filter(|o| is_red(o)).count();
        assert!(
            red_in_blue > 0,
            "the labels' offset puts red pixels in blue"
        );
        let (clean, left_out) = fit_groups(&mesh, &seg, &obs, &settings(3));
        assert!(
            clean[1].iter().all(|o| !is_red(o)),
            "no red pixel left in blue"
        );
        // only the red ones went: every blue pixel stays, and the red material keeps its own
        assert_eq!(clean[1].len(), kept[1].len() - red_in_blue);
        assert_eq!(clean[0].len(), kept[0].len());
        let (_, interior_only) = interior_groups(&mesh, &labels, 2, &obs, true, 0);
        assert_eq!(left_out[1], interior_only[1] + red_in_blue);
        // a material that would lose most of its pixels keeps them all (colours swapped: every
        // pixel near the boundary is "another material's")
        let mut swapped = kept.clone();
        let gone = drop_foreign_colours(
            &mesh,
            &labels,
            &mut swapped,
            &[chroma(blue.kd), chroma(red.kd)],
            3,
        );
        assert_eq!(gone, vec![0, 0]);
        assert_eq!(swapped[0].len(), kept[0].len());
    }

    #[test]
    fn the_labels_boundary_moves_to_where_the_vertices_own_pixels_put_it() {
        // Red faces left of x = 4.5, blue right of it: by their own pixels the vertices at
        // x <= 4 are red. The labels put the boundary a column further left (x = 3.5), as the
        // pooled features do.
        let mesh = grid(8);
        let nb = mesh.vertex_neighbours();
        let (red, blue) = (ggx([0.5, 0.05, 0.05], 0.3), ggx([0.05, 0.05, 0.5], 0.3));
        let obs = scene(&mesh, &[red, blue], 4.5, 4);
        let corners: Vec<Option<usize>> = obs.iter().map(|o| nearest_corner(&mesh, o)).collect();
        let settings = SegmentSettings::default();
        let own = features(&mesh, &nb, &obs, &corners, |_| true, &settings, false);
        let p = mesh.positions();
        let offset: Vec<u32> = p.iter().map(|v| u32::from(v.x > 3.5)).collect();
        let counted =
            |v: usize| own.slot[v].is_some_and(|i| own.weight[i] >= RELABEL_MIN_PIXELS as f64);
        let wrong = |l: &[u32]| {
            (0..p.len())
                .filter(|&v| counted(v) && l[v] != u32::from(p[v].x > 4.5))
                .count()
        };
        let before = wrong(&offset);
        assert!(before >= 6, "a column of vertices labelled wrong: {before}");
        let mut labels = offset.clone();
        let moved = relabel_boundary(&own, &nb, &mut labels, 2, &[], 2);
        assert_eq!(
            wrong(&labels),
            0,
            "every vertex with its own pixels on its side"
        );
        assert!(moved >= before, "{moved} moved, {before} were wrong");
        // a vertex fixed by a label mask stays where the mask put it
        let fixed: Vec<Option<u32>> = (0..p.len())
            .map(|v| (p[v].x == 4.0 && p[v].y == 3.0).then_some(1))
            .collect();
        let mut held = offset.clone();
        relabel_boundary(&own, &nb, &mut held, 2, &fixed, 2);
        let v = (0..p.len())
            .find(|&v| fixed[v].is_some())
            .expect("the fixed vertex");
        assert_eq!(held[v], 1);
        // no passes or one material: nothing moves
        let mut same = offset.clone();
        assert_eq!(relabel_boundary(&own, &nb, &mut same, 2, &[], 0), 0);
        assert_eq!(relabel_boundary(&own, &nb, &mut same, 1, &[], 2), 0);
        assert_eq!(same, offset);
    }

    #[test]
    fn observations_off_the_mesh_have_no_label() {
        let mesh = grid(4);
        let s = Segmentation {
            count: 1,
            vertex_labels: vec![0; 16],
            observed_vertices: vec![16],
            chromaticity: vec![[1.0 / 3.0; 3]],
            fixed_vertices: vec![0],
            given: 0,
            scores: Vec::new(),
            reason: String::new(),
        };
        let o = Observation::new(
            Seen::pixel(0, 0, 0, Vector3::z()),
            Vector3::z(),
            Vector3::z(),
            [0.1; 3],
            [1.0; 3],
        )
        .expect("a valid observation");
        assert_eq!(s.label_of(&mesh, &o), None);
    }

    /// Per grid vertex: `Some(m)` where `given` says so.
    fn fixed_where(mesh: &Mesh, given: impl Fn(&Point3<f64>) -> Option<u32>) -> Vec<Option<u32>> {
        mesh.positions().iter().map(given).collect()
    }

    #[test]
    fn fixed_labels_survive_and_free_vertices_join_the_material_of_their_colour() {
        let mesh = grid(16);
        let red = ggx([0.35, 0.08, 0.1], 0.3);
        let green = ggx([0.05, 0.25, 0.1], 0.2);
        let obs = scene(&mesh, &[red, green], 7.5, 6);
        // Given: a strip at each end with its own colour, and a block inside the red half
        // labelled green: the labels contradict the colours there.
        let block = |p: &Point3<f64>| (3.0..=4.0).contains(&p.x) && (3.0..=5.0).contains(&p.y);
        let fixed = fixed_where(&mesh, |p| {
            if p.x <= 1.0 {
                Some(0)
            } else if p.x >= 14.0 || block(p) {
                Some(1)
            } else {
                None
            }
        });
        for max_materials in [1, 4] {
            let settings = SegmentSettings {
                max_materials,
                ..SegmentSettings::default()
            };
            let s = segment_with_labels(&mesh, &obs, &settings, &fixed);
            assert_eq!(
                s.count, 2,
                "max {max_materials}: {} / {:?}",
                s.reason, s.scores
            );
            assert_eq!(s.given, 2);
            assert!(s.reason.contains("label masks"), "{}", s.reason);
            for (v, f) in fixed.iter().enumerate() {
                if let Some(m) = f {
                    assert_eq!(s.vertex_labels[v], *m, "fixed vertex {v} moved");
                }
            }
            assert_eq!(
                s.fixed_vertices.iter().sum::<usize>(),
                fixed.iter().flatten().count()
            );
            // every free vertex away from the colour boundary and from the contradicting block
            // takes the given material of its colour
            let near_block =
                |p: &Point3<f64>| (2.0..=5.0).contains(&p.x) && (2.0..=6.0).contains(&p.y);
            let wrong: Vec<usize> = mesh
                .positions()
                .iter()
                .enumerate()
                .filter(|(v, p)| fixed[*v].is_none() && (p.x - 7.5).abs() > 1.5 && !near_block(p))
                .filter(|(v, p)| s.vertex_labels[*v] != u32::from(p.x > 7.5))
                .map(|(v, _)| v)
                .collect();
            assert!(
                wrong.is_empty(),
                "max {max_materials}: wrong free vertices {wrong:?}"
            );
        }
        // no fixed labels: exactly the automatic segmentation
        let settings = SegmentSettings::default();
        assert_eq!(
            segment_with_labels(&mesh, &obs, &settings, &[]),
            segment(&mesh, &obs, &settings)
        );
    }

    #[test]
    fn a_colour_the_labels_do_not_name_is_added_only_by_the_held_out_rule() {
        let mesh = grid(16);
        let bands = [
            ggx([0.35, 0.08, 0.1], 0.3),
            ggx([0.05, 0.25, 0.1], 0.2),
            ggx([0.06, 0.08, 0.35], 0.25),
        ];
        let band = |p: &Point3<f64>| (p.x / 5.0).floor().min(2.0) as usize;
        let obs = scene_by(&mesh, &bands, band, 6);
        // labels on part of the first two bands; the third is never labelled
        let fixed = fixed_where(&mesh, |p| match p.x {
            x if x <= 2.0 => Some(0),
            x if (6.0..=8.0).contains(&x) => Some(1),
            _ => None,
        });
        let blue: Vec<usize> = (0..mesh.positions().len())
            .filter(|&v| mesh.positions()[v].x >= 11.0)
            .collect();
        // --materials auto: the blue band is a third material, found, not given
        let s = segment_with_labels(&mesh, &obs, &SegmentSettings::default(), &fixed);
        assert_eq!(s.count, 3, "{} / {:?}", s.reason, s.scores);
        assert_eq!(s.given, 2);
        assert!(
            blue.iter().all(|&v| s.vertex_labels[v] == 2),
            "{:?}",
            s.vertex_labels
        );
        assert_eq!(s.fixed_vertices[2], 0);
        // one material asked (the default): only the given ones; the blue band joins one whole
        let one = SegmentSettings {
            max_materials: 1,
            ..SegmentSettings::default()
        };
        let s = segment_with_labels(&mesh, &obs, &one, &fixed);
        assert_eq!(s.count, 2, "{}", s.reason);
        assert!(
            s.scores.iter().all(|c| c.fold_errors.is_empty()),
            "one count, no folds"
        );
        let l = s.vertex_labels[blue[0]];
        assert!(blue.iter().all(|&v| s.vertex_labels[v] == l));
        for (v, f) in fixed.iter().enumerate() {
            if let Some(m) = f {
                assert_eq!(s.vertex_labels[v], *m);
            }
        }
    }
}
