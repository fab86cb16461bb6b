//! The normal refinement's depth unknowns (issue #12): one displacement per vertex along its
//! starting direction instead of two free tangent angles, the normals following from the
//! displaced positions (`RefineSettings::depth`).
//!
//! A photogrammetry mesh's normal error comes from its depth noise: a vertex off the surface
//! along its normal tilts the normals of its whole one-ring. Free normals have two unknowns per
//! vertex, each held by the few pixels of its own faces, and fit the images' noise where pixels
//! are few (started from the true normals on the true positions, the free-normal objective
//! drifts 0.6-0.7 degrees away from them; docs/normal-refinement.md, "Session 28"). A
//! displacement has one unknown per vertex, held by the pixels of every face around it, and
//! the normals it makes are those of a surface. A vertex's normal is `start + N(p) - N(p0)`,
//! normalised (`N`: the mesh's angle-weighted vertex normals of positions `p`; `p0` the mesh's
//! positions; `start` the refinement's chosen start), so it is the start where nothing moved
//! and a mesh whose file carries its own normals keeps them there.
//!
//! The Gauss-Newton step is the free-normal one (`refine::Problem`'s linearised pixels and
//! `refine::Prior`'s anchor and smoothness, in normal space) composed with the sparse
//! derivative of the normals by the displacements; a ridge keeps each displacement near zero
//! (`depth_sigma_edges` mean edge lengths). The positions are used only for the normals:
//! pixels, shadows and visibility keep coming from the mesh. Pure; no I/O.

use super::{
    Model, Prior, Problem, RefineSettings, clamp_tilt, conjugate_gradients, data_gradient,
    data_product, frames_of,
};
use crate::geometry::mesh::{angle_weighted_normals, mean_edge_length};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// One entry of the normals' derivative: vertex `v`'s two tangent angles per unit displacement
/// of vertex `u`.
struct Entry {
    v: u32,
    u: u32,
    e: [f64; 2],
}

/// Sparse entries grouped by one of their vertices (compressed rows), so products run in
/// parallel without scatter: `of(k)` lists the other vertex and the entry.
struct Grouped {
    start: Vec<usize>,
    list: Vec<(u32, [f64; 2])>,
}

impl Grouped {
    fn new(entries: &[Entry], vertices: usize, key: impl Fn(&Entry) -> (u32, u32)) -> Self {
        let mut start = vec![0usize; vertices + 1];
        for e in entries {
            start[key(e).0 as usize + 1] += 1;
        }
        for k in 0..vertices {
            start[k + 1] += start[k];
        }
        let mut next = start.clone();
        let mut list = vec![(0u32, [0.0; 2]); entries.len()];
        for e in entries {
            let (k, other) = key(e);
            list[next[k as usize]] = (other, e.e);
            next[k as usize] += 1;
        }
        Self { start, list }
    }

    fn of(&self, k: usize) -> &[(u32, [f64; 2])] {
        &self.list[self.start[k]..self.start[k + 1]]
    }
}

/// One face at the current positions: its corners, unit normal, twice its area, and the angle at
/// each corner.
struct FaceAt {
    q: [Point3<f64>; 3],
    n: Vector3<f64>,
    len: f64,
    angles: [f64; 3],
}

/// The displacement field and what turns it into normals.
pub(super) struct Depth<'a> {
    faces: &'a [[u32; 3]],
    p0: &'a [Point3<f64>],
    /// Unit direction each vertex moves along (its normal on `p0`).
    dir: Vec<Vector3<f64>>,
    /// `N(p0)`.
    base: Vec<Vector3<f64>>,
    start: Vec<Vector3<f64>>,
    /// No normal turns further than `max_tilt` (radians) from these (the mesh's own).
    bound: &'a [Vector3<f64>],
    max_tilt: f64,
    /// Vertices that move.
    pub(super) free: Vec<bool>,
    ridge: f64,
    /// The displacements, in the positions' unit.
    pub(super) d: Vec<f64>,
}

impl<'a> Depth<'a> {
    /// `None` when the positions do not fit the normals or the mesh has no extent. `anchor_weight`
    /// and `anchor_rad`: the prior's anchor weight and scale (the ridge weighs a displacement
    /// of `depth_sigma_edges` edges as the anchor weighs a tilt of `anchor_rad`).
    pub(super) fn new(
        faces: &'a [[u32; 3]],
        p0: &'a [Point3<f64>],
        start: &[Vector3<f64>],
        bound: &'a [Vector3<f64>],
        free: Vec<bool>,
        settings: &RefineSettings,
        anchor_weight: f64,
    ) -> Option<Self> {
        if p0.len() != start.len() || bound.len() != start.len() || free.len() != start.len() {
            return None;
        }
        let (base, _) = angle_weighted_normals(faces, p0);
        let edge = mean_edge_length(faces, p0);
        let sigma = settings.depth_sigma_edges * edge;
        if !(sigma.is_finite() && sigma > 0.0) {
            return None;
        }
        let anchor_rad = settings.anchor_deg.to_radians();
        Some(Self {
            faces,
            p0,
            dir: base.clone(),
            base,
            start: start.to_vec(),
            bound,
            max_tilt: settings.max_tilt_deg.to_radians(),
            free,
            ridge: anchor_weight * anchor_rad * anchor_rad / (sigma * sigma),
            d: vec![0.0; start.len()],
        })
    }

    fn positions(&self, d: &[f64]) -> Vec<Point3<f64>> {
        self.p0
            .iter()
            .zip(&self.dir)
            .zip(d)
            .map(|((p, n), x)| p + n * *x)
            .collect()
    }

    /// The vertex normals of displacements `d`.
    pub(super) fn normals(&self, d: &[f64]) -> Vec<Vector3<f64>> {
        let (np, _) = angle_weighted_normals(self.faces, &self.positions(d));
        (0..np.len())
            .into_par_iter()
            .map(|v| {
                let s = self.start[v];
                let m = s + np[v] - self.base[v];
                if s == Vector3::zeros() || m.norm() < 1e-12 {
                    return s;
                }
                clamp_tilt(&m.normalize(), &self.bound[v], self.max_tilt)
            })
            .collect()
    }

    /// d (tangent angles of each vertex normal, in `frames`) / d (displacement of each free
    /// vertex) at `d`: per face, the unit normal's derivative by each corner's displacement,
    /// spread to the corners by their angles like `N`, over each vertex's unnormalised sum.
    /// The angles' own derivatives are left out (a Gauss-Newton step needs the direction; the
    /// line search checks the cost).
    fn jacobian(&self, d: &[f64], frames: &[(Vector3<f64>, Vector3<f64>)]) -> Vec<Entry> {
        let p = self.positions(d);
        let faces: Vec<FaceAt> = self
            .faces
            .iter()
            .map(|f| {
                let q = [p[f[0] as usize], p[f[1] as usize], p[f[2] as usize]];
                let c = (q[1] - q[0]).cross(&(q[2] - q[0]));
                let len = c.norm();
                let angles = std::array::from_fn(|k| {
                    let e1 = q[(k + 1) % 3] - q[k];
                    let e2 = q[(k + 2) % 3] - q[k];
                    let denom = e1.norm() * e2.norm();
                    if denom > 0.0 {
                        (e1.dot(&e2) / denom).clamp(-1.0, 1.0).acos()
                    } else {
                        0.0
                    }
                });
                let n = if len > 0.0 { c / len } else { Vector3::zeros() };
                FaceAt { q, n, len, angles }
            })
            .collect();
        let mut m = vec![Vector3::zeros(); p.len()];
        for (f, at) in self.faces.iter().zip(&faces) {
            for k in 0..3 {
                m[f[k] as usize] += at.n * at.angles[k];
            }
        }
        let m_len: Vec<f64> = m.iter().map(Vector3::norm).collect();
        let mut out = Vec::with_capacity(9 * self.faces.len());
        for (f, FaceAt { q, n, len, angles }) in self.faces.iter().zip(&faces) {
            if *len <= 0.0 {
                continue;
            }
            for k in 0..3 {
                let u = f[k];
                if !self.free[u as usize] {
                    continue;
                }
                // d(cross)/d(corner k along dir): dir x (next corner - the one after)
                let dc = self.dir[u as usize].cross(&(q[(k + 1) % 3] - q[(k + 2) % 3]));
                let dn = (dc - n * n.dot(&dc)) / *len;
                for j in 0..3 {
                    let v = f[j];
                    let ml = m_len[v as usize];
                    if ml <= 0.0 || self.start[v as usize] == Vector3::zeros() {
                        continue;
                    }
                    let g = dn * (angles[j] / ml);
                    let (t1, t2) = &frames[v as usize];
                    out.push(Entry {
                        v,
                        u,
                        e: [g.dot(t1), g.dot(t2)],
                    });
                }
            }
        }
        out
    }

    fn ridge_cost(&self, d: &[f64]) -> f64 {
        self.ridge * d.iter().map(|x| x * x).sum::<f64>()
    }

    /// `settings.depth_sweeps` Gauss-Newton steps on the displacements under one reflectance; returns
    /// the normals they end on.
    pub(super) fn sweeps(
        &mut self,
        problem: &Problem<'_>,
        model: &Model,
        idx: &[usize],
        prior: &Prior<'_>,
    ) -> Vec<Vector3<f64>> {
        let mut n = self.normals(&self.d);
        let mut c = problem.cost(model, idx, &n, prior) + self.ridge_cost(&self.d);
        for _ in 0..problem.settings.depth_sweeps {
            let Some((d, n2, c2)) = self.step(problem, model, idx, prior, &n, c) else {
                break;
            };
            (self.d, n, c) = (d, n2, c2);
        }
        n
    }

    /// One damped Gauss-Newton step from the current displacements (normals `n`, cost `c0`);
    /// `None` when no step length lowers the cost.
    fn step(
        &self,
        problem: &Problem<'_>,
        model: &Model,
        idx: &[usize],
        prior: &Prior<'_>,
        n: &[Vector3<f64>],
        c0: f64,
    ) -> Option<(Vec<f64>, Vec<Vector3<f64>>, f64)> {
        let vertices = n.len();
        let vars = 2 * vertices;
        let frames = frames_of(n);
        let lins = problem.linearise(model, idx, n, &frames);
        let (mut grad, diag) = data_gradient(&lins, vars);
        let offsets: Vec<Vector3<f64>> = n.par_iter().zip(prior.n0).map(|(a, b)| a - b).collect();
        super::add_into(&mut grad, &prior.gradient(&offsets, &frames, true));
        let jac = self.jacobian(&self.d, &frames);
        let by_v = Grouped::new(&jac, vertices, |e| (e.v, e.u));
        let by_u = Grouped::new(&jac, vertices, |e| (e.u, e.v));
        let forward = |x: &[f64]| -> Vec<f64> {
            let mut y = vec![0.0; vars];
            y.par_chunks_mut(2).enumerate().for_each(|(v, o)| {
                for (u, e) in by_v.of(v) {
                    let xu = x[*u as usize];
                    o[0] += e[0] * xu;
                    o[1] += e[1] * xu;
                }
            });
            y
        };
        let backward = |y: &[f64]| -> Vec<f64> {
            (0..vertices)
                .into_par_iter()
                .map(|u| {
                    by_u.of(u)
                        .iter()
                        .map(|(v, e)| e[0] * y[2 * *v as usize] + e[1] * y[2 * *v as usize + 1])
                        .sum()
                })
                .collect()
        };
        let mut rhs = backward(&grad);
        for (u, r) in rhs.iter_mut().enumerate() {
            *r = if self.free[u] {
                -(*r + self.ridge * self.d[u])
            } else {
                0.0
            };
        }
        let prior_diagonal: Vec<f64> = (0..vertices)
            .into_par_iter()
            .map(|v| prior.diagonal(v))
            .collect();
        let mut precond: Vec<f64> = (0..vertices)
            .into_par_iter()
            .map(|u| {
                by_u.of(u)
                    .iter()
                    .map(|(v, e)| {
                        let v = *v as usize;
                        let pd = prior_diagonal[v];
                        e[0] * e[0] * (diag[2 * v] + pd) + e[1] * e[1] * (diag[2 * v + 1] + pd)
                    })
                    .sum()
            })
            .collect();
        let damping = 1e-6 * precond.iter().sum::<f64>() / vertices.max(1) as f64 + 1e-12;
        for (u, p) in precond.iter_mut().enumerate() {
            let s = *p + self.ridge + damping;
            *p = if self.free[u] && s > 0.0 {
                1.0 / s
            } else {
                0.0
            };
        }
        let apply = |x: &[f64]| -> Vec<f64> {
            let y = forward(x);
            let mut z = data_product(&lins, vars, &y);
            let moves: Vec<Vector3<f64>> = (0..vertices)
                .into_par_iter()
                .map(|v| frames[v].0 * y[2 * v] + frames[v].1 * y[2 * v + 1])
                .collect();
            super::add_into(&mut z, &prior.gradient(&moves, &frames, false));
            let mut out = backward(&z);
            for (u, o) in out.iter_mut().enumerate() {
                *o = if self.free[u] {
                    *o + (self.ridge + damping) * x[u]
                } else {
                    0.0
                };
            }
            out
        };
        let x = conjugate_gradients(
            apply,
            &rhs,
            &precond,
            problem.settings.depth_cg_iterations,
            problem.settings.cg_tolerance,
        );
        let mut scale = problem.settings.step;
        for _ in 0..4 {
            let trial: Vec<f64> = self.d.iter().zip(&x).map(|(a, b)| a + b * scale).collect();
            let nt = self.normals(&trial);
            let c = problem.cost(model, idx, &nt, prior) + self.ridge_cost(&trial);
            if c < c0 {
                return Some((trial, nt, c));
            }
            scale *= 0.5;
        }
        None
    }
}
