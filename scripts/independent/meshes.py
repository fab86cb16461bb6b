"""Meshes for the independent scenes: OBJ in, PLY out, vertex normals, photogrammetry-like
degradations and their normal error against the exact surface.

Conventions: positions are float32 as written to the PLY (both Mitsuba and brdf-rig read those
numbers), computations in float64. Faces are counter-clockwise seen from outside; vertex
normals are the angle-weighted mean of the incident face normals (Thuermer and Wuethrich 1998),
the definition brdf-rig's `geometry::mesh` documents, so the renderer shades the exact mesh
with the normals the reconstruction will compute from it. Needs numpy and scipy only.
"""

import os

import numpy as np
from scipy.sparse import coo_matrix, diags
from scipy.spatial import cKDTree


def read_obj(path):
    """Vertices (n, 3) float64 and triangles (m, 3) int64 of an OBJ; polygons are fanned."""
    verts, faces = [], []
    with open(path, encoding="utf-8") as f:
        for lineno, line in enumerate(f, 1):
            tok = line.split()
            if not tok:
                continue
            if tok[0] == "v":
                verts.append([float(x) for x in tok[1:4]])
            elif tok[0] == "f":
                idx = []
                for t in tok[1:]:
                    i = int(t.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(verts) + i)
                if len(idx) < 3:
                    raise ValueError(f"{path}:{lineno}: face with fewer than 3 corners")
                for k in range(1, len(idx) - 1):
                    faces.append([idx[0], idx[k], idx[k + 1]])
    v = np.asarray(verts, dtype=np.float64)
    fa = np.asarray(faces, dtype=np.int64)
    if len(v) == 0 or len(fa) == 0 or fa.min() < 0 or fa.max() >= len(v):
        raise ValueError(f"{path}: no vertices or faces, or a face index out of range")
    return v, fa


def as_float32(v):
    """The positions exactly as a float32 PLY stores them, back in float64."""
    return v.astype(np.float32).astype(np.float64)


def write_atomic(path, data):
    """Writes bytes to `path` through a temporary file and a rename (never half-written)."""
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def write_ply(path, v, faces, normals=None):
    """Binary little-endian PLY: float32 x y z (and nx ny nz), faces as uchar/int lists."""
    n, m = len(v), len(faces)
    header = ["ply", "format binary_little_endian 1.0",
              "comment written by scripts/render_recon_scenes.py",
              f"element vertex {n}", "property float x", "property float y", "property float z"]
    if normals is not None:
        header += ["property float nx", "property float ny", "property float nz"]
    header += [f"element face {m}", "property list uchar int vertex_indices", "end_header"]
    cols = 6 if normals is not None else 3
    vert = np.empty((n, cols), dtype="<f4")
    vert[:, :3] = v
    if normals is not None:
        vert[:, 3:] = normals
    face = np.empty(m, dtype=[("k", "u1"), ("i", "<i4", 3)])
    face["k"] = 3
    face["i"] = faces
    data = ("\n".join(header) + "\n").encode("ascii") + vert.tobytes() + face.tobytes()
    write_atomic(path, data)


def vertex_normals(v, faces):
    """Unit angle-weighted vertex normals (zero for vertices no face uses)."""
    p0, p1, p2 = v[faces[:, 0]], v[faces[:, 1]], v[faces[:, 2]]
    fn = np.cross(p1 - p0, p2 - p0)
    length = np.linalg.norm(fn, axis=1)
    ok = length > 0
    fn[ok] /= length[ok, None]
    fn[~ok] = 0.0

    def angle(a, b):
        la = np.linalg.norm(a, axis=1)
        lb = np.linalg.norm(b, axis=1)
        c = np.einsum("ij,ij->i", a, b) / np.maximum(la * lb, 1e-300)
        return np.arccos(np.clip(c, -1.0, 1.0))

    angles = [angle(p1 - p0, p2 - p0), angle(p0 - p1, p2 - p1), angle(p0 - p2, p1 - p2)]
    out = np.zeros_like(v)
    for k in range(3):
        np.add.at(out, faces[:, k], fn * angles[k][:, None])
    length = np.linalg.norm(out, axis=1)
    ok = length > 0
    out[ok] /= length[ok, None]
    return out


def mean_edge(v, faces):
    e = np.concatenate([v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 1]],
                        v[faces[:, 0]] - v[faces[:, 2]]])
    return float(np.linalg.norm(e, axis=1).mean())


def subdivide(v, faces):
    """Midpoint subdivision (1 triangle -> 4), the surface unchanged."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    uniq, inv = np.unique(edges, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    mid = len(v) + inv
    m = len(faces)
    a, b, c = faces[:, 0], faces[:, 1], faces[:, 2]
    ab, bc, ca = mid[:m], mid[m:2 * m], mid[2 * m:]
    v2 = np.concatenate([v, 0.5 * (v[uniq[:, 0]] + v[uniq[:, 1]])])
    f2 = np.concatenate([np.stack(t, axis=1) for t in
                         ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return v2, f2


def clean(v, faces):
    """Drops faces with repeated corners, duplicate faces and unused vertices."""
    ok = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])
    faces = faces[ok]
    _, first = np.unique(np.sort(faces, axis=1), axis=0, return_index=True)
    faces = faces[np.sort(first)]
    used = np.unique(faces)
    remap = np.full(len(v), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return v[used], remap[faces]


def cluster(v, faces, cell):
    """Vertex clustering on a grid of `cell`: a coarser, differently triangulated resampling of
    the surface, as a photogrammetry remesh would give (each cell's vertices merge at their
    mean)."""
    keys = np.floor((v - v.min(axis=0)) / cell).astype(np.int64)
    _, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    count = np.bincount(inv).astype(np.float64)
    v2 = np.stack([np.bincount(inv, weights=v[:, k]) for k in range(3)], axis=1) / count[:, None]
    return clean(v2, inv[faces])


def adjacency(n, faces):
    """Row-normalised vertex adjacency (uniform Laplacian weights), sparse."""
    i = np.concatenate([faces[:, 0], faces[:, 1], faces[:, 2], faces[:, 1], faces[:, 2], faces[:, 0]])
    j = np.concatenate([faces[:, 1], faces[:, 2], faces[:, 0], faces[:, 0], faces[:, 1], faces[:, 2]])
    a = coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n)).tocsr()  # duplicates summed
    a.data[:] = 1.0  # each neighbour once
    deg = np.asarray(a.sum(axis=1)).reshape(-1)
    deg[deg == 0] = 1.0
    return diags(1.0 / deg) @ a


def taubin(v, faces, iterations, lam=0.5, mu=-0.53):
    """Taubin's lambda/mu smoothing: rounds off detail as MVS does, without shrinking much."""
    w = adjacency(len(v), faces)
    for _ in range(iterations):
        v = v + lam * (w @ v - v)
        v = v + mu * (w @ v - v)
    return v


def smooth_field(v, rng, diag, waves=24):
    """A smooth random scalar field on the points: a sum of random plane waves with wavelengths
    of 10-40 % of the object's diagonal, unit RMS."""
    f = np.zeros(len(v))
    for _ in range(waves):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        lam = rng.uniform(0.1, 0.4) * diag
        f += rng.normal() * np.sin(2 * np.pi * (v @ d) / lam + rng.uniform(0, 2 * np.pi))
    return f / max(np.sqrt(np.mean(f * f)), 1e-300)


# The two degradations. `cell_div`: the remesh cell is diagonal / cell_div; `smooth`: Taubin
# iterations; `low`, `white`: weights of the smooth field and of per-vertex white noise in the
# displacement along the normals, whose amplitude is `strength * cell`. `target_deg`: the
# median vertex-normal error the strength is tuned to (bisection).
DEGRADATIONS = {
    "realistic": dict(cell_div=150.0, min_cell_edges=1.0, smooth=6, low=1.0, white=0.15, target_deg=4.5,
                      what="MVS-like: the surface resampled by vertex clustering, Taubin-smoothed, "
                           "displaced along the normals by a smooth random field and a little "
                           "white noise"),
    "poor": dict(cell_div=70.0, min_cell_edges=2.0, smooth=1, low=0.3, white=1.0, target_deg=30.0,
                 what="a bad scan: a coarse clustering remesh, barely smoothed, with strong "
                      "per-vertex noise along the normals"),
}


class Degradation:
    """A photogrammetry-like copy of the exact mesh (a different triangulation); the remesh and
    the noise pattern are fixed by `kind` and `seed`, `at(strength)` scales the displacement."""

    def __init__(self, v, faces, kind, seed):
        p = DEGRADATIONS[kind]
        diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
        # never finer than the source mesh (a coarse source such as Spot would become dense)
        self.cell = max(diag / p["cell_div"], p["min_cell_edges"] * mean_edge(v, faces))
        vs, fs = v, faces
        while mean_edge(vs, fs) > 0.5 * self.cell:
            vs, fs = subdivide(vs, fs)
        vc, self.faces = cluster(vs, fs, self.cell)
        self.base = taubin(vc, self.faces, p["smooth"])
        rng = np.random.default_rng(seed)
        field = smooth_field(self.base, rng, diag)
        white = rng.uniform(-1.0, 1.0, size=len(self.base)) * np.sqrt(3.0)
        self.pattern = p["low"] * field + p["white"] * white
        self.normals = vertex_normals(self.base, self.faces)

    def at(self, strength):
        disp = strength * self.cell * self.pattern
        return as_float32(self.base + self.normals * disp[:, None]), self.faces


class ExactSurface:
    """The exact mesh sampled densely (about a million points, barycentric grids per face) with
    interpolated vertex normals, for nearest-point normal look-ups."""

    def __init__(self, v, faces, normals, points=1_000_000):
        m = max(2, int(round(np.sqrt(2.0 * points / len(faces)))))
        bary = np.array([(i, j, m - i - j) for i in range(m + 1) for j in range(m + 1 - i)],
                        dtype=np.float64) / m
        p = np.einsum("bk,fkd->fbd", bary, v[faces]).reshape(-1, 3)
        nn = np.einsum("bk,fkd->fbd", bary, normals[faces]).reshape(-1, 3)
        nn /= np.maximum(np.linalg.norm(nn, axis=1, keepdims=True), 1e-300)
        self.normals = nn
        self.samples_per_face = len(bary)  # sample s lies on face s // samples_per_face
        self.tree = cKDTree(p)

    def nearest_face(self, points):
        """Per point (n, 3), the exact face whose sample is nearest (a vertex of the exact mesh
        is a sample of each face around it: the k-d tree returns one of them)."""
        _, idx = self.tree.query(points)
        return idx // self.samples_per_face

    def normal_error_deg(self, v, faces):
        """Per-vertex angle (degrees) between the mesh's vertex normal and the exact surface's
        normal at the nearest exact sample."""
        n = vertex_normals(v, faces)
        _, idx = self.tree.query(v)
        c = np.einsum("ij,ij->i", n, self.normals[idx])
        return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def error_stats(err):
    return {
        "median_normal_error_deg": round(float(np.median(err)), 3),
        "mean_normal_error_deg": round(float(np.mean(err)), 3),
        "p90_normal_error_deg": round(float(np.percentile(err, 90)), 3),
    }


def tuned_degradation(v, faces, kind, surface, seed, log=print):
    """Degrades with the strength whose median normal error is the kind's target (bisection
    on the strength; the seed stays fixed, so the noise pattern only scales). Returns the
    mesh, its per-vertex errors and the parameters used."""
    p = DEGRADATIONS[kind]
    target = p["target_deg"]
    deg = Degradation(v, faces, kind, seed)

    def median_at(s):
        return float(np.median(surface.normal_error_deg(*deg.at(s))))

    lo, hi = 0.0, 0.25
    if median_at(lo) >= target:
        log(f"  {kind}: the remesh alone already gives {median_at(lo):.2f} deg (target {target})")
        hi = 0.0
    else:
        while median_at(hi) < target and hi < 64:
            lo, hi = hi, hi * 2
        for _ in range(20):
            mid = 0.5 * (lo + hi)
            m = median_at(mid)
            if abs(m - target) < 0.01 * target:
                hi = mid
                break
            lo, hi = (mid, hi) if m < target else (lo, mid)
    vd, fd = deg.at(hi)
    params = {k: val for k, val in p.items() if k != "what"}
    params.update(strength=round(hi, 6), seed=seed, cell=deg.cell)
    return vd, fd, surface.normal_error_deg(vd, fd), params
