"""Ray casting in numpy, written here from scratch (Moeller-Trumbore), so that the pixel check
of render_recon_scenes.py predicts pixel values without Mitsuba's or brdf-rig's geometry code.

No acceleration structure: the rays of one call share a projection (through the camera centre,
or parallel to the light), so each ray is tested only against the triangles whose projected
bounding box contains the ray's projected point; the test is exact, the culling conservative.
"""

import numpy as np


class Caster:
    def __init__(self, v, faces):
        self.v = v
        self.faces = faces
        self.v0 = v[faces[:, 0]]
        self.e1 = v[faces[:, 1]] - self.v0
        self.e2 = v[faces[:, 2]] - self.v0
        n = np.cross(self.e1, self.e2)
        self.face_normal = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)

    def _nearest(self, o, d, cand, t_min):
        """Nearest hit of one ray among candidate triangles: (t, face, b1, b2)."""
        if len(cand) == 0:
            return np.inf, -1, 0.0, 0.0
        e1, e2, v0 = self.e1[cand], self.e2[cand], self.v0[cand]
        p = np.cross(d, e2)
        det = np.einsum("fk,fk->f", p, e1)
        ok = np.abs(det) > 1e-18
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = o - v0
        b1 = np.einsum("fk,fk->f", s, p) * inv
        q = np.cross(s, e1)
        b2 = (q @ d) * inv
        t = np.einsum("fk,fk->f", q, e2) * inv
        hit = ok & (b1 >= 0) & (b2 >= 0) & (b1 + b2 <= 1) & (t > t_min)
        if not hit.any():
            return np.inf, -1, 0.0, 0.0
        t = np.where(hit, t, np.inf)
        k = int(np.argmin(t))
        return float(t[k]), int(cand[k]), float(b1[k]), float(b2[k])

    def _cast(self, origins, dirs, ray_uv, tri_uv, t_min, eps=1e-9):
        lo, hi = tri_uv.min(axis=1) - eps, tri_uv.max(axis=1) + eps
        out = np.empty((len(origins), 4))
        for r in range(len(origins)):
            u, v = ray_uv[r]
            cand = np.nonzero((lo[:, 0] <= u) & (u <= hi[:, 0]) & (lo[:, 1] <= v) & (v <= hi[:, 1]))[0]
            out[r] = self._nearest(origins[r], dirs[r], cand, t_min)
        return out[:, 0], out[:, 1].astype(np.int64), out[:, 2], out[:, 3]

    def cast_from_camera(self, eye, r_cam_from_world, dirs):
        """Nearest hits of rays leaving `eye` (the camera centre; every triangle must lie in
        front of it) along unit world directions (k, 3): (t, face or -1, b1, b2); the hit is
        v0 + b1 e1 + b2 e2."""
        def proj(x):
            return x[..., :2] / x[..., 2:3]

        tri_cam = (self.v[self.faces] - eye) @ r_cam_from_world.T
        if (tri_cam[..., 2] <= 0).any():
            raise ValueError("a triangle lies behind the camera: the culling would be wrong")
        origins = np.broadcast_to(eye, dirs.shape)
        return self._cast(origins, dirs, proj(dirs @ r_cam_from_world.T), proj(tri_cam), 0.0)

    def cast_parallel(self, origins, direction, t_min=0.0):
        """Nearest hits of parallel rays (origins (k, 3), one unit direction)."""
        a = np.cross(direction, [1.0, 0.0, 0.0] if abs(direction[0]) < 0.9 else [0.0, 1.0, 0.0])
        a /= np.linalg.norm(a)
        b = np.cross(direction, a)
        basis = np.stack([a, b], axis=1)
        dirs = np.broadcast_to(direction, origins.shape)
        return self._cast(origins, dirs, origins @ basis, self.v[self.faces] @ basis, t_min)
