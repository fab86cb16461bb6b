"""A Mitsuba 3 BSDF that reads a MERL `.binary` table (the format of scripts/independent/merl.py),
so that the independent renderer can show materials of the measured kind, not only analytic
ones. Written from the format's definition, not from brdf-rig's reader.

Lookup: nearest bin (no interpolation), as the MERL reference code does: h = (wi + wo) / |wi +
wo|, theta_h = acos(h.z), phi_h = atan2(h.y, h.x); the difference vector is wi rotated by
-phi_h about z and by -theta_h about y; theta_d = acos(d.z), phi_d = atan2(d.y, d.x) mod pi.
Indices: floor(90 sqrt(theta_h / (pi/2))), floor(90 theta_d / (pi/2)), floor(180 phi_d / pi),
clamped to the grid. Bins marked "no data" (negative) count as 0. The table is reciprocal, so
which of the two directions is the light does not matter.

Sampling: cosine-weighted hemisphere (the scenes' `direct` integrator samples only the
emitters, which are directional; the path integrator needs some sampling, and this one is
unbiased for any BRDF).

Usage: `import independent.merl_bsdf` after `mi.set_variant(...)`, then
`{"type": "merl_table", "filename": PATH}` in a scene dictionary.
"""

import mitsuba as mi
import drjit as dr
import numpy as np

N_TH, N_TD, N_PD = 90, 90, 180
SCALES = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])


def read_table(path):
    """f_r (BINS, 3) in 1/sr from a MERL `.binary`; no data becomes 0."""
    raw = np.fromfile(path, dtype="<i4", count=3)
    if tuple(raw) != (N_TH, N_TD, N_PD):
        raise ValueError(f"{path}: header {tuple(raw)} is not (90, 90, 180)")
    data = np.fromfile(path, dtype="<f8", offset=12)
    bins = N_TH * N_TD * N_PD
    if data.size != 3 * bins:
        raise ValueError(f"{path}: {data.size} values, expected {3 * bins}")
    f = data.reshape(3, bins).T * SCALES[None, :]
    return np.where(f > 0, f, 0.0)


def merl_index(wi, wo):
    """Flat MERL bin index of direction pairs (Dr.Jit vectors in the local frame)."""
    h = dr.normalize(wi + wo)
    theta_h = dr.acos(dr.clip(h.z, -1.0, 1.0))
    phi_h = dr.atan2(h.y, h.x)
    c, s = dr.cos(-phi_h), dr.sin(-phi_h)
    x = c * wi.x - s * wi.y
    y = s * wi.x + c * wi.y
    z = wi.z
    c, s = dr.cos(-theta_h), dr.sin(-theta_h)
    x, z = c * x + s * z, -s * x + c * z
    theta_d = dr.acos(dr.clip(z, -1.0, 1.0))
    phi_d = dr.atan2(y, x)
    phi_d = dr.select(phi_d < 0, phi_d + dr.pi, phi_d)
    phi_d = dr.select(phi_d >= dr.pi, phi_d - dr.pi, phi_d)
    i_th = mi.Int32(dr.clip(dr.floor(dr.sqrt(dr.maximum(theta_h, 0.0) / (dr.pi / 2)) * N_TH),
                            0, N_TH - 1))
    i_td = mi.Int32(dr.clip(dr.floor(theta_d / (dr.pi / 2) * N_TD), 0, N_TD - 1))
    i_pd = mi.Int32(dr.clip(dr.floor(phi_d / dr.pi * N_PD), 0, N_PD - 1))
    return mi.UInt32(i_pd + N_PD * (i_td + N_TD * i_th))


class MerlTable(mi.BSDF):
    def __init__(self, props):
        mi.BSDF.__init__(self, props)
        self.path = str(props["filename"])
        table = read_table(self.path)
        # The vectorised variants gather from a Dr.Jit array; the scalar one (`scalar_rgb`, the
        # fallback without libLLVM >= 17) has no array to gather from: it indexes the numpy
        # table with the one bin each call looks up.
        self.scalar = not dr.is_array_v(mi.Float)
        self.table = table if self.scalar else mi.Float(np.ascontiguousarray(table.reshape(-1)))
        flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
        self.m_components = [flags]
        self.m_flags = flags

    def f(self, si, wo, active):
        cos_i = mi.Frame3f.cos_theta(si.wi)
        cos_o = mi.Frame3f.cos_theta(wo)
        ok = active & (cos_i > 0) & (cos_o > 0)
        idx = merl_index(wo, si.wi)
        if self.scalar:
            value = mi.Color3f(*self.table[int(idx)]) if ok else mi.Color3f(0.0)
            return value, cos_o
        value = dr.gather(mi.Color3f, self.table, idx, ok)
        return dr.select(ok, value, 0.0), cos_o

    def eval(self, ctx, si, wo, active=True):
        value, cos_o = self.f(si, wo, active)
        return value * dr.maximum(cos_o, 0.0)

    def pdf(self, ctx, si, wo, active=True):
        ok = active & (mi.Frame3f.cos_theta(si.wi) > 0)
        return dr.select(ok, mi.warp.square_to_cosine_hemisphere_pdf(wo), 0.0)

    def eval_pdf(self, ctx, si, wo, active=True):
        return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

    def sample(self, ctx, si, sample1, sample2, active=True):
        wo = mi.warp.square_to_cosine_hemisphere(sample2)
        pdf = mi.warp.square_to_cosine_hemisphere_pdf(wo)
        bs = dr.zeros(mi.BSDFSample3f)
        bs.wo = wo
        bs.pdf = pdf
        bs.eta = 1.0
        bs.sampled_type = mi.UInt32(+mi.BSDFFlags.DiffuseReflection)
        bs.sampled_component = 0
        ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (pdf > 0)
        value = self.eval(ctx, si, wo, ok) / dr.maximum(pdf, 1e-12)
        return bs, dr.select(ok, value, 0.0)

    def traverse(self, callback):
        pass

    def to_string(self):
        return f"MerlTable[filename={self.path}]"


mi.register_bsdf("merl_table", lambda props: MerlTable(props))
