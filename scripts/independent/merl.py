"""MERL tables of the truth BRDFs, computed from the format's definition (not from brdf-rig).

The MERL format: int32 header (90, 90, 180), then float64 planar R, G, B, each indexed
`phi_d + 180 (theta_d + 90 theta_h)`; stored value = f_r / scale with scales 1/1500, 1.15/1500,
1.66/1500 (a reader multiplies them back); negative = no data. Bins: theta_h bin
floor(90 sqrt(theta_h / (pi/2))), theta_d bin floor(90 theta_d / (pi/2)), phi_d bin
floor(180 phi_d / pi) over [0, pi) (reciprocity folds [pi, 2 pi) onto it).

Bin centres are the middle of each bin in index space (theta_h = ((i + 0.5)/90)^2 pi/2), at
phi_h = 0. From (theta_h, theta_d, phi_d) the two directions are built in the frame of the half
vector h = (sin theta_h, 0, cos theta_h): with tangent t = (cos theta_h, 0, -sin theta_h) and
bitangent b = (0, 1, 0), the difference vector d = (sin theta_d cos phi_d, sin theta_d sin phi_d,
cos theta_d) gives `wi = d_x t + d_y b + d_z h` (towards the light) and `wo = 2 (wi.h) h - wi`
(towards the viewer, the mirror of wi about h). Bins with either centre direction at or below
the horizon are written as no data (-1).

The compact subset (`truth_subset.bin`, for tests): every `step`-th bin, in index order, of the
bins above the horizon. Little endian: 8 bytes magic `BRDFSUB1`, u32 count, u32 step, then
`count` records of 24 bytes: u32 flat MERL index, f32 cos theta_i, f32 cos theta_o (at the bin
centre), f32 f_r red, green, blue (1/sr, no MERL scale applied).
"""

import numpy as np

from .meshes import write_atomic

N_TH, N_TD, N_PD = 90, 90, 180
BINS = N_TH * N_TD * N_PD
SCALES = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
SUBSET_MAGIC = b"BRDFSUB1"
SUBSET_RECORD = np.dtype([("index", "<u4"), ("cos_i", "<f4"), ("cos_o", "<f4"), ("rgb", "<f4", 3)])


def bin_centres():
    """(wi, wo, above) for every flat MERL index in order: unit directions (BINS, 3), local
    frame with the normal +z, and whether both lie strictly above the horizon."""
    th, td, pd = (a.reshape(-1) for a in np.indices((N_TH, N_TD, N_PD)))
    theta_h = ((th + 0.5) / N_TH) ** 2 * (np.pi / 2)
    theta_d = (td + 0.5) / N_TD * (np.pi / 2)
    phi_d = (pd + 0.5) / N_PD * np.pi
    sh, ch = np.sin(theta_h), np.cos(theta_h)
    zero = np.zeros_like(sh)
    h = np.stack([sh, zero, ch], axis=1)
    t = np.stack([ch, zero, -sh], axis=1)
    dx = np.sin(theta_d) * np.cos(phi_d)
    dy = np.sin(theta_d) * np.sin(phi_d)
    dz = np.cos(theta_d)
    wi = dx[:, None] * t + dz[:, None] * h
    wi[:, 1] += dy
    wo = 2.0 * np.einsum("ij,ij->i", wi, h)[:, None] * h - wi
    above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    return wi, wo, above


def bin_index(wi, wo):
    """Flat MERL index of direction pairs (the forward conversion, to check `bin_centres`):
    h = (wi + wo)/|wi + wo|; rotate wi by -phi_h about z, then by -theta_h about y to get d."""
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    theta_h = np.arccos(np.clip(h[:, 2], -1, 1))
    phi_h = np.arctan2(h[:, 1], h[:, 0])
    c, s = np.cos(-phi_h), np.sin(-phi_h)
    x, y, z = c * wi[:, 0] - s * wi[:, 1], s * wi[:, 0] + c * wi[:, 1], wi[:, 2]
    c, s = np.cos(-theta_h), np.sin(-theta_h)
    x, z = c * x + s * z, -s * x + c * z
    theta_d = np.arccos(np.clip(z, -1, 1))
    phi_d = np.mod(np.arctan2(y, x), np.pi)
    i_th = np.clip(np.floor(np.sqrt(theta_h / (np.pi / 2)) * N_TH), 0, N_TH - 1).astype(np.int64)
    i_td = np.clip(np.floor(theta_d / (np.pi / 2) * N_TD), 0, N_TD - 1).astype(np.int64)
    i_pd = np.clip(np.floor(phi_d / np.pi * N_PD), 0, N_PD - 1).astype(np.int64)
    return i_pd + N_PD * (i_td + N_TD * i_th)


def write_table(path, f, above):
    """Writes a full MERL `.binary` (f: (BINS, 3) f_r in 1/sr; no data where not `above`)."""
    data = np.full((3, BINS), -1.0)
    for c in range(3):
        data[c, above] = f[above, c] / SCALES[c]
    header = np.array([N_TH, N_TD, N_PD], dtype="<i4").tobytes()
    write_atomic(path, header + data.astype("<f8").tobytes())


def subset_indices(above, step):
    return np.nonzero(above)[0][::step]


def write_subset(path, idx, wi, wo, f, step):
    rec = np.empty(len(idx), dtype=SUBSET_RECORD)
    rec["index"] = idx
    rec["cos_i"] = wi[idx, 2]
    rec["cos_o"] = wo[idx, 2]
    rec["rgb"] = f[idx]
    head = SUBSET_MAGIC + np.array([len(idx), step], dtype="<u4").tobytes()
    write_atomic(path, head + rec.tobytes())
