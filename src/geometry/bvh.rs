//! A bounding-volume hierarchy over a mesh's triangles, for camera rays (the rasteriser) and
//! shadow rays (towards a directional light).
//!
//! Hand-written rather than a crate: the rasteriser, shadow test and renderer all need the same
//! two queries (closest hit with barycentrics and face id; any hit within a range) on `f64`
//! nalgebra types and our `Mesh`, and the build plus both traversals are ~200 lines; the crates
//! we looked at (bvh, parry) bring their own geometry types and far more than we use.
//!
//! Build: binned surface-area heuristic (12 bins on the centroid extent of the longest axis),
//! leaves of at most 4 triangles. Intersection: Möller–Trumbore, both faces (no back-face
//! culling: SfM meshes are not reliably oriented, and shadows must see both sides).
//! Conventions: a hit's barycentrics `(u, v)` weight corners 1 and 2 of the face, so the point is
//! `(1-u-v) p0 + u p1 + v p2`; `t` is in units of the ray direction's length.
//! Pure; depends only on `mesh`.

use super::mesh::Mesh;
use nalgebra::{Point3, Vector3};

/// A ray `origin + t * dir`.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Point3<f64>,
    pub dir: Vector3<f64>,
}

/// The closest intersection along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f64,
    pub face: u32,
    pub u: f64,
    pub v: f64,
}

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: [f64; 3],
    hi: [f64; 3],
    /// Leaf: first triangle; inner: index of the right child (the left is the next node).
    index: u32,
    /// Number of triangles in a leaf; 0 marks an inner node.
    count: u32,
}

#[derive(Clone, Copy, Debug)]
struct Tri {
    p0: Vector3<f64>,
    e1: Vector3<f64>,
    e2: Vector3<f64>,
    face: u32,
}

/// The hierarchy; build once per mesh (bunny: ~0.1 s release), query from many threads.
#[derive(Clone, Debug)]
pub struct Bvh {
    nodes: Vec<Node>,
    tris: Vec<Tri>,
}

const MAX_LEAF: usize = 4;
const BINS: usize = 12;

#[derive(Clone, Copy)]
struct Aabb {
    lo: Vector3<f64>,
    hi: Vector3<f64>,
}

impl Aabb {
    fn empty() -> Self {
        Self {
            lo: Vector3::repeat(f64::INFINITY),
            hi: Vector3::repeat(f64::NEG_INFINITY),
        }
    }
    fn grow(&mut self, p: &Vector3<f64>) {
        self.lo = self.lo.inf(p);
        self.hi = self.hi.sup(p);
    }
    fn merge(&mut self, b: &Aabb) {
        self.lo = self.lo.inf(&b.lo);
        self.hi = self.hi.sup(&b.hi);
    }
    fn area(&self) -> f64 {
        let d = self.hi - self.lo;
        if d.x < 0.0 {
            return 0.0;
        }
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }
}

struct Prim {
    bounds: Aabb,
    centroid: Vector3<f64>,
    tri: Tri,
}

impl Bvh {
    /// Builds the hierarchy over every face of `mesh`.
    pub fn build(mesh: &Mesh) -> Bvh {
        let mut prims: Vec<Prim> = (0..mesh.faces().len())
            .map(|f| {
                let [a, b, c] = mesh.triangle(f);
                let mut bounds = Aabb::empty();
                for p in [a, b, c] {
                    bounds.grow(&p.coords);
                }
                Prim {
                    bounds,
                    centroid: (a.coords + b.coords + c.coords) / 3.0,
                    tri: Tri {
                        p0: a.coords,
                        e1: b - a,
                        e2: c - a,
                        face: f as u32,
                    },
                }
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * prims.len() / MAX_LEAF + 1);
        let n = prims.len();
        build_node(&mut prims, 0, n, &mut nodes);
        Bvh {
            nodes,
            tris: prims.into_iter().map(|p| p.tri).collect(),
        }
    }

    /// The closest hit with `t_min < t < t_max`.
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_far = t_max;
        self.traverse(ray, t_min, &mut t_far, |tri, t, u, v| {
            best = Some(Hit {
                t,
                face: tri.face,
                u,
                v,
            });
            false
        });
        best
    }

    /// Whether anything lies on the ray with `t_min < t < t_max` (stops at the first hit).
    pub fn occluded(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        let mut hit = false;
        let mut t_far = t_max;
        self.traverse(ray, t_min, &mut t_far, |_, _, _, _| {
            hit = true;
            true
        });
        hit
    }

    /// Walks nodes front to back; `on_hit` gets every hit closer than `t_far` (which shrinks to
    /// it) and returns `true` to stop.
    fn traverse(
        &self,
        ray: &Ray,
        t_min: f64,
        t_far: &mut f64,
        mut on_hit: impl FnMut(&Tri, f64, f64, f64) -> bool,
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let inv = Vector3::new(1.0 / ray.dir.x, 1.0 / ray.dir.y, 1.0 / ray.dir.z);
        let o = ray.origin.coords;
        let Some(t_root) = slab(&self.nodes[0], &o, &inv, t_min, *t_far) else {
            return;
        };
        // each entry carries the distance at which the ray enters the node's box, tested when
        // it was pushed; a node is skipped when a hit found since then is nearer
        let mut stack = [(0u32, 0.0f64); 64];
        stack[0] = (0, t_root);
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let (ni, t_enter) = stack[sp];
            if t_enter > *t_far {
                continue;
            }
            let node = &self.nodes[ni as usize];
            if node.count > 0 {
                let start = node.index as usize;
                for tri in &self.tris[start..start + node.count as usize] {
                    if let Some((t, u, v)) = moller_trumbore(tri, ray, t_min, *t_far) {
                        *t_far = t;
                        if on_hit(tri, t, u, v) {
                            return;
                        }
                    }
                }
            } else {
                let left = ni + 1;
                let right = node.index;
                let tl = slab(&self.nodes[left as usize], &o, &inv, t_min, *t_far);
                let tr = slab(&self.nodes[right as usize], &o, &inv, t_min, *t_far);
                // push the farther child first so the nearer one is visited next
                let order = match (tl, tr) {
                    (Some(a), Some(b)) if a <= b => [Some((right, b)), Some((left, a))],
                    (Some(a), Some(b)) => [Some((left, a)), Some((right, b))],
                    (Some(a), None) => [None, Some((left, a))],
                    (None, Some(b)) => [None, Some((right, b))],
                    (None, None) => [None, None],
                };
                for c in order.into_iter().flatten() {
                    // depth is bounded by the build (median fallback); guard anyway
                    if sp < stack.len() {
                        stack[sp] = c;
                        sp += 1;
                    }
                }
            }
        }
    }
}

/// The ray against one triangle `(p0, p1, p2)` with the arithmetic of the BVH's own test, so a
/// caller that already knows the face (a z-buffer) gets the hit a traversal would report:
/// `(t, u, v)` with `t_min < t < t_max`, `(u, v)` weighting corners 1 and 2.
pub fn intersect_triangle(
    corners: &[Point3<f64>; 3],
    ray: &Ray,
    t_min: f64,
    t_max: f64,
) -> Option<(f64, f64, f64)> {
    let [a, b, c] = corners;
    let tri = Tri {
        p0: a.coords,
        e1: b - a,
        e2: c - a,
        face: 0,
    };
    moller_trumbore(&tri, ray, t_min, t_max)
}

/// Entry distance of the ray into the node's box within `[t_min, t_max]`, if it enters.
#[inline]
fn slab(n: &Node, o: &Vector3<f64>, inv: &Vector3<f64>, t_min: f64, t_max: f64) -> Option<f64> {
    let mut t0 = t_min;
    let mut t1 = t_max;
    for a in 0..3 {
        let ta = (n.lo[a] - o[a]) * inv[a];
        let tb = (n.hi[a] - o[a]) * inv[a];
        let (near, far) = if ta <= tb { (ta, tb) } else { (tb, ta) };
        // NaN (0 * inf on a slab boundary) leaves the bound unchanged
        if near > t0 {
            t0 = near;
        }
        if far < t1 {
            t1 = far;
        }
    }
    (t0 <= t1).then_some(t0)
}

#[inline]
fn moller_trumbore(tri: &Tri, ray: &Ray, t_min: f64, t_max: f64) -> Option<(f64, f64, f64)> {
    let pvec = ray.dir.cross(&tri.e2);
    let det = tri.e1.dot(&pvec);
    if det.abs() < 1e-300 {
        return None;
    }
    let inv_det = 1.0 / det;
    let tvec = ray.origin.coords - tri.p0;
    let u = tvec.dot(&pvec) * inv_det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qvec = tvec.cross(&tri.e1);
    let v = ray.dir.dot(&qvec) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = tri.e2.dot(&qvec) * inv_det;
    (t > t_min && t < t_max).then_some((t, u, v))
}

fn build_node(prims: &mut [Prim], start: usize, end: usize, nodes: &mut Vec<Node>) -> u32 {
    let idx = nodes.len();
    let mut bounds = Aabb::empty();
    let mut cb = Aabb::empty();
    for p in &prims[start..end] {
        bounds.merge(&p.bounds);
        cb.grow(&p.centroid);
    }
    nodes.push(Node {
        lo: bounds.lo.into(),
        hi: bounds.hi.into(),
        index: start as u32,
        count: (end - start) as u32,
    });
    let n = end - start;
    if n <= MAX_LEAF {
        return idx as u32;
    }
    let ext = cb.hi - cb.lo;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    if ext[axis] <= 0.0 {
        // all centroids coincide: no split can separate them; a long leaf is still correct
        return idx as u32;
    }
    // binned SAH
    let mut bin_bounds = [Aabb::empty(); BINS];
    let mut bin_count = [0usize; BINS];
    let scale = BINS as f64 / ext[axis];
    let bin_of = |c: &Vector3<f64>| (((c[axis] - cb.lo[axis]) * scale) as usize).min(BINS - 1);
    for p in &prims[start..end] {
        let b = bin_of(&p.centroid);
        bin_count[b] += 1;
        bin_bounds[b].merge(&p.bounds);
    }
    let mut best = (f64::INFINITY, 0);
    let mut right_area = [0.0; BINS];
    let mut right_count = [0usize; BINS];
    let mut acc = Aabb::empty();
    let mut cnt = 0;
    for b in (1..BINS).rev() {
        acc.merge(&bin_bounds[b]);
        cnt += bin_count[b];
        right_area[b] = acc.area();
        right_count[b] = cnt;
    }
    let mut acc = Aabb::empty();
    let mut cnt = 0;
    for b in 0..BINS - 1 {
        acc.merge(&bin_bounds[b]);
        cnt += bin_count[b];
        let cost = acc.area() * cnt as f64 + right_area[b + 1] * right_count[b + 1] as f64;
        if cnt > 0 && right_count[b + 1] > 0 && cost < best.0 {
            best = (cost, b + 1);
        }
    }
    let mid = if best.0.is_finite() {
        let split = best.1;
        let slice = &mut prims[start..end];
        let mut i = 0;
        for j in 0..slice.len() {
            if bin_of(&slice[j].centroid) < split {
                slice.swap(i, j);
                i += 1;
            }
        }
        start + i
    } else {
        start + n / 2
    };
    let mid = if mid == start || mid == end {
        // every centroid fell in one bin: split at the median instead
        prims[start..end]
            .select_nth_unstable_by(n / 2, |a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
        start + n / 2
    } else {
        mid
    };
    build_node(prims, start, mid, nodes);
    let right = build_node(prims, mid, end, nodes);
    nodes[idx].count = 0;
    nodes[idx].index = right;
    idx as u32
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A soup of random triangles: the BVH must agree with testing every triangle.
    #[test]
    fn agrees_with_brute_force_on_random_triangles() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut pos = Vec::new();
        let mut faces = Vec::new();
        for i in 0..300 {
            let c = Vector3::new(rng.r#gen::<f64>(), rng.r#gen::<f64>(), rng.r#gen::<f64>()) * 4.0;
            for _ in 0..3 {
                let d = Vector3::new(rng.r#gen::<f64>(), rng.r#gen::<f64>(), rng.r#gen::<f64>());
                pos.push(Point3::from(c + (d - Vector3::repeat(0.5)) * 0.6));
            }
            faces.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let (mesh, _) = Mesh::new(pos, faces, "<random>").unwrap();
        let bvh = Bvh::build(&mesh);
        let tris: Vec<Tri> = (0..mesh.faces().len())
            .map(|f| {
                let [a, b, c] = mesh.triangle(f);
                Tri {
                    p0: a.coords,
                    e1: b - a,
                    e2: c - a,
                    face: f as u32,
                }
            })
            .collect();
        let mut hits = 0;
        for _ in 0..2000 {
            let o = Point3::new(rng.gen_range(-1.0..5.0), rng.gen_range(-1.0..5.0), -1.0);
            let target = Point3::new(rng.gen_range(0.0..4.0), rng.gen_range(0.0..4.0), 5.0);
            let ray = Ray {
                origin: o,
                dir: (target - o).normalize(),
            };
            let brute = tris
                .iter()
                .filter_map(|t| moller_trumbore(t, &ray, 0.0, f64::INFINITY).map(|h| (h.0, t.face)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let got = bvh.intersect(&ray, 0.0, f64::INFINITY);
            assert_eq!(got.map(|h| h.face), brute.map(|b| b.1));
            assert_eq!(bvh.occluded(&ray, 0.0, f64::INFINITY), brute.is_some());
            if let (Some(g), Some(b)) = (got, brute) {
                hits += 1;
                assert!((g.t - b.0).abs() < 1e-12);
                // the barycentrics reproduce the hit point
                let [p0, p1, p2] = mesh.triangle(g.face as usize);
                let p = p0.coords * (1.0 - g.u - g.v) + p1.coords * g.u + p2.coords * g.v;
                assert!((p - (o.coords + ray.dir * g.t)).norm() < 1e-9);
            }
        }
        assert!(hits > 200, "too few hits ({hits}) to test anything");
    }
}
