#!/usr/bin/env python3
"""Reconstruction scenes for brdf-rig rendered by an independent renderer (Mitsuba 3).

Each scene is a folder that `brdf-rig reconstruct DIR/job_exact.toml --out OUT` runs on as
docs/reconstruction.md documents: linear EXR light images, a COLMAP text model, the exact mesh
and photogrammetry-like degraded ones (one job per mesh), the truth BRDF as a MERL table and a
`truth.json` saying how everything was made. What the scenes are and what was verified:
docs/independent-scenes.md.

Requirements (none of them needed by brdf-rig's build, tests or CI):
    python3 -m venv /work/venv-mitsuba
    /work/venv-mitsuba/bin/pip install mitsuba scipy      # mitsuba 3.9.1, scipy for a k-d tree
  Vectorised evaluation (variant llvm_ad_rgb, the default when available) needs libLLVM >= 17:
  with Debian 12's default libLLVM 14/15 the Dr.Jit JIT aborts ("Cannot select: fmaximum").
    apt-get install libllvm19                             # Debian 12 (bookworm)
  The script finds /usr/lib/*/libLLVM-19.so (or any >= 17) and sets DRJIT_LIBLLVM_PATH; without
  one it falls back to `scalar_rgb` (same images up to noise, the MERL tables much slower).

Usage (the full set, and the tiny scene committed under tests/fixtures/independent):
    /work/venv-mitsuba/bin/python scripts/render_recon_scenes.py --out target/independent-scenes
    /work/venv-mitsuba/bin/python scripts/render_recon_scenes.py \\
        --out tests/fixtures/independent --scenes spot-3lights --materials lambert \\
        --meshes exact,realistic --views 6 --size 96x72 --half --truth subset --path-spp 0
  Objects of two or three materials (slabs along +y; per-face and per-vertex labels, one truth
  table per material; only these scenes are rendered): add `--split A+B[+C]` (repeatable).

Conventions: COLMAP camera axes (x right, y down, z forward), `light_dir_camera` towards the
light, irradiance E such that a white Lambertian of albedo a facing the light has radiance
a E / pi (Mitsuba's `directional` emitter `irradiance`). The jobs use the `direct` integrator's
images (light/): direct light with shadows, which is what the reconstruction models; the `path`
integrator's images (light_path/, jobs job_*_path.toml) add interreflections.
"""

import argparse
import glob
import importlib
import json
import os
import re
import shlex
import shutil
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from independent import merl, rig  # noqa: E402
from independent import meshes as M  # noqa: E402
from independent.raycast import Caster  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

MESHES = {
    "spot": dict(file="data/meshes/spot_triangulated.obj",
                 provenance="Keenan Crane's Spot (spot_triangulated.obj), public domain"),
    "bunny": dict(file="data/meshes/stanford-bunny.obj",
                  provenance="Stanford Bunny, Stanford 3D Scanning Repository: research use, "
                             "credit the Stanford Computer Graphics Laboratory"),
}


def rgb(r, g, b):
    return {"type": "rgb", "value": [r, g, b]}


# Materials that are not in the MERL set, as Mitsuba 3 BSDFs (linear RGB parameters).
MATERIALS = {
    "lambert": dict(
        bsdf={"type": "diffuse", "reflectance": rgb(0.75, 0.6, 0.45)},
        what="pure Lambertian, albedo (0.75, 0.6, 0.45): the sanity check of conventions"),
    "cloth": dict(
        bsdf={"type": "principled", "base_color": rgb(0.22, 0.30, 0.55), "roughness": 0.95,
              "specular": 0.35, "sheen": 1.0, "sheen_tint": 0.3, "metallic": 0.0},
        what="a blue cloth: Disney-principled, very rough, with sheen (grazing brightening)"),
    "coated-paper": dict(
        bsdf={"type": "roughplastic", "distribution": "ggx", "alpha": 0.12, "int_ior": 1.5,
              "ext_ior": 1.0, "diffuse_reflectance": rgb(0.82, 0.80, 0.74), "nonlinear": False},
        what="a coated paper: white diffuse base under a GGX dielectric coating (alpha 0.12)"),
    "painted-metal": dict(
        bsdf={"type": "principled", "base_color": rgb(0.65, 0.12, 0.08), "metallic": 0.85,
              "roughness": 0.45, "specular": 0.5, "clearcoat": 1.0, "clearcoat_gloss": 0.7},
        what="a red painted metal: principled, mostly metallic, broad coloured lobe under a "
             "sharp clear coat"),
    "cardboard": dict(
        bsdf={"type": "principled", "base_color": rgb(0.52, 0.38, 0.24), "roughness": 0.8,
              "specular": 0.25, "metallic": 0.0},
        what="a brown cardboard: rough (Disney) diffuse with a weak, broad specular lobe"),
}

mi = None  # mitsuba, imported by setup_mitsuba() once the LLVM library is chosen
dr = None


def find_llvm(min_major=17):
    """The newest libLLVM with major version >= min_major, or None."""
    best = None
    for path in (glob.glob("/usr/lib/*/libLLVM*.so*") + glob.glob("/usr/lib/llvm-*/lib/libLLVM*.so*")
                 + glob.glob("/usr/lib64/libLLVM*.so*")):
        m = re.search(r"libLLVM-(\d+)", path) or re.search(r"libLLVM\.so\.(\d+)", path)
        if m and int(m.group(1)) >= min_major and (best is None or int(m.group(1)) > best[0]):
            best = (int(m.group(1)), path)
    return best[1] if best else None


def setup_mitsuba(requested):
    global mi, dr
    variant = requested
    if requested in ("auto", "llvm_ad_rgb"):
        if "DRJIT_LIBLLVM_PATH" not in os.environ:
            lib = find_llvm()
            if lib:
                os.environ["DRJIT_LIBLLVM_PATH"] = lib
            elif requested == "llvm_ad_rgb":
                sys.exit("llvm_ad_rgb needs libLLVM >= 17 (Debian 12: apt-get install libllvm19), "
                         "or set DRJIT_LIBLLVM_PATH")
        variant = "llvm_ad_rgb" if "DRJIT_LIBLLVM_PATH" in os.environ else "scalar_rgb"
    import drjit
    import mitsuba
    mi, dr = mitsuba, drjit
    mi.set_variant(variant)
    return variant


def is_vectorised():
    return not mi.variant().startswith("scalar")


def eval_brdf(bsdf, wi, wo, chunk=400_000):
    """f_r (n, 3) in 1/sr for light direction `wi` and view direction `wo` (local frames, normal
    +z), from Mitsuba's `eval`, which returns f_r times the cosine of its `wo` argument: Mitsuba
    calls the direction towards the camera `si.wi` and the sampled one (the light, in radiance
    transport) `wo`, so the light goes in as the argument and its cosine is divided out."""
    n = len(wi)
    out = np.zeros((n, 3))
    ctx = mi.BSDFContext()
    if is_vectorised():
        for s in range(0, n, chunk):
            a, b = wi[s:s + chunk], wo[s:s + chunk]
            si = dr.zeros(mi.SurfaceInteraction3f, len(a))
            si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
            si.n = mi.Normal3f(0.0, 0.0, 1.0)
            si.wi = mi.Vector3f(b[:, 0], b[:, 1], b[:, 2])
            val = bsdf.eval(ctx, si, mi.Vector3f(a[:, 0], a[:, 1], a[:, 2]))
            out[s:s + chunk] = np.array(val).T
    else:
        si = mi.SurfaceInteraction3f()
        si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
        si.n = mi.Normal3f(0.0, 0.0, 1.0)
        for k in range(n):
            si.wi = mi.Vector3f(*wo[k])
            out[k] = np.array(bsdf.eval(ctx, si, mi.Vector3f(*wi[k])))
    cos_i = wi[:, 2:3]
    return np.where(cos_i > 0, out / np.where(cos_i > 0, cos_i, 1.0), 0.0)


def sensor_to_world(view):
    """Mitsuba's perspective camera looks along its local +z with +x left and +y up (look_at);
    COLMAP's looks along +z with x right, y down: the same frame turned half a turn about z."""
    m = np.eye(4)
    m[:3, :3] = view["R"].T @ np.diag([-1.0, -1.0, 1.0])
    m[:3, 3] = view["eye"]
    return mi.ScalarTransform4f(m.tolist())


def render(parts, camera, view, spp, integrator, seed):
    """One view. `parts`: [(PLY file, material name)], one Mitsuba shape each, each inside
    `twosided` (one part: the whole object, the one-material scenes)."""
    objects = {("object" if len(parts) == 1 else f"object_{k}"):
               {"type": "ply", "filename": ply,
                "bsdf": {"type": "twosided", "bsdf": MATERIALS[material]["bsdf"]}}
               for k, (ply, material) in enumerate(parts)}
    scene = mi.load_dict({
        "type": "scene",
        "integrator": integrator,
        "sensor": {
            "type": "perspective", "fov": camera.fov_x_deg, "fov_axis": "x",
            "to_world": sensor_to_world(view),
            "film": {"type": "hdrfilm", "width": camera.width, "height": camera.height,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "stratified", "sample_count": spp},
        },
        **objects,
        "light": {"type": "directional", "direction": (-view["light_dir_world"]).tolist(),
                  "irradiance": rgb(*view["irradiance"])},
    })
    return np.array(mi.render(scene, seed=seed), dtype=np.float32)


def write_exr(path, img, half):
    bmp = mi.Bitmap(np.ascontiguousarray(img, dtype=np.float32),
                    pixel_format=mi.Bitmap.PixelFormat.RGB)
    if half:
        bmp = bmp.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float16, False)
    tmp = path[:-4] + f".tmp{os.getpid()}.exr"
    bmp.write(tmp)
    os.replace(tmp, path)


def local_frame(n):
    """Tangent and bitangent for unit normals (n, 3) (any: the BRDFs are isotropic)."""
    a = np.where(np.abs(n[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    t = np.cross(a, n)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return t, np.cross(n, t)


def pixel_check(caster, normals, diag, camera, view, image, material, bsdf, rng,
                pixels=24, sub=4, face_labels=None, label=None):
    """Predicts rendered pixels from the truth without Mitsuba's geometry: rays through a
    sub x sub grid in each pixel (numpy ray casting, independent/raycast.py), angle-weighted
    vertex normals interpolated at the hit, a shadow ray to the light; radiance =
    E f_r cos theta_i averaged over the pixel (what a box filter integrates). Lambert: f_r = albedo / pi analytically;
    others: f_r from the BSDF's eval. Only pixels whose every sub-sample hits, is lit and is
    at most 80 degrees from the light and the camera are compared; with `face_labels` (per face
    of the exact mesh), only pixels whose every sub-sample hits a face of label `label` (an
    object of several materials: `material` is that label's), and whose corners, edge
    midpoints and centre hit that label as well."""
    lum = image.mean(axis=2)
    cand = np.argwhere(lum > 0)
    rng.shuffle(cand)
    offs = (np.arange(sub) + 0.5) / sub
    ox, oy = np.meshgrid(offs, offs)
    ox, oy = ox.reshape(-1), oy.reshape(-1)
    edge_x, edge_y = (g.reshape(-1) for g in np.meshgrid([0.0, 0.5, 1.0], [0.0, 0.5, 1.0]))
    l_w = view["light_dir_world"]
    e = np.array(view["irradiance"])
    min_cos = np.cos(np.radians(80.0))
    rows = []
    for start in range(0, len(cand), 48):
        if len(rows) >= pixels:
            break
        batch = cand[start:start + 48]
        if face_labels is not None:
            # the pixel's corners, edge midpoints and centre must hit the label too: the 4x4
            # rays leave a margin of 1/8 pixel, where another material may lie
            bx = (batch[:, 1:2] + edge_x[None]).reshape(-1)
            by = (batch[:, 0:1] + edge_y[None]).reshape(-1)
            _, fb, _, _ = caster.cast_from_camera(view["eye"], view["R"],
                                                  camera.ray_camera(bx, by) @ view["R"])
            fb = fb.reshape(len(batch), -1)
            batch = batch[((fb >= 0) & (face_labels[np.maximum(fb, 0)] == label)).all(axis=1)]
            if not len(batch):
                continue
        px = (batch[:, 1:2] + ox[None]).reshape(-1)
        py = (batch[:, 0:1] + oy[None]).reshape(-1)
        d = camera.ray_camera(px, py) @ view["R"]  # camera -> world: R^T d
        o = np.broadcast_to(view["eye"], d.shape)
        t, f, b1, b2 = caster.cast_from_camera(view["eye"], view["R"], d)
        hit = f >= 0
        fi = np.where(hit, f, 0)
        p = o + d * np.where(hit, t, 0)[:, None]
        w = np.stack([1 - b1 - b2, b1, b2], axis=1)
        fv = caster.faces[fi]
        n = np.einsum("rk,rkd->rd", w, normals[fv])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        ng = caster.face_normal[fi]
        v = -d
        flip = np.einsum("ij,ij->i", ng, v) < 0  # two-sided: the side the camera sees
        n[flip] *= -1
        ng[flip] *= -1
        cos_i = n @ l_w
        cos_o = np.einsum("ij,ij->i", n, v)
        ok = hit & (cos_i > min_cos) & (cos_o > min_cos) & (ng @ l_w > 0)
        so = p + ng * (1e-5 * diag)
        ts, _, _, _ = caster.cast_parallel(so[ok], l_w)
        lit = np.zeros_like(ok)
        lit[np.nonzero(ok)[0]] = ~np.isfinite(ts)
        if material == "lambert":
            alb = np.array(MATERIALS["lambert"]["bsdf"]["reflectance"]["value"])
            rad = (alb / np.pi)[None] * e[None] * np.maximum(cos_i, 0)[:, None]
        else:
            tt, bb = local_frame(n)
            frame = np.stack([tt, bb, n], axis=1)  # rows: the local axes, per sample
            wi = np.einsum("rij,j->ri", frame, l_w)
            wo = np.einsum("rij,rj->ri", frame, v)
            good = lit & (wi[:, 2] > 0) & (wo[:, 2] > 0)
            rad = np.zeros((len(n), 3))
            rad[good] = eval_brdf(bsdf, wi[good], wo[good]) * e[None] * wi[good, 2:3]
        per_px = sub * sub
        for k, (y, x) in enumerate(batch):
            sl = slice(k * per_px, (k + 1) * per_px)
            if lit[sl].all() and (face_labels is None or (face_labels[fi[sl]] == label).all()):
                pred = rad[sl].mean(axis=0)
                rows.append((int(x), int(y), pred.tolist(), image[y, x].astype(float).tolist()))
            if len(rows) >= pixels:
                break
    if not rows:
        return dict(pixels=0)
    pred = np.array([r[2] for r in rows])
    got = np.array([r[3] for r in rows])
    rel = np.abs(got - pred) / np.maximum(pred, 1e-12)
    ratio = got / np.maximum(pred, 1e-12)
    return dict(
        view=view["name"], pixels=len(rows),
        median_abs_rel_error=round(float(np.median(rel)), 5),
        max_abs_rel_error=round(float(rel.max()), 5),
        median_ratio_rgb=[round(float(x), 5) for x in np.median(ratio, axis=0)],
        samples=[dict(x=r[0], y=r[1], predicted=[round(c, 6) for c in r[2]],
                      rendered=[round(c, 6) for c in r[3]]) for r in rows[:6]],
    )


class Stopwatch:
    def __init__(self):
        self.times = {}

    def run(self, name, fn, *args, **kw):
        t = time.time()
        out = fn(*args, **kw)
        self.times[name] = round(self.times.get(name, 0.0) + time.time() - t, 2)
        return out


def log(msg):
    print(msg, flush=True)


def prepare_meshes(mesh_name, kinds, seed, sw):
    """The exact mesh (float32 positions, unused vertices dropped, angle-weighted normals) and
    the requested degraded variants with their normal errors against it."""
    v, f = M.read_obj(os.path.join(REPO, MESHES[mesh_name]["file"]))
    v, f = M.clean(M.as_float32(v), f)
    n = M.vertex_normals(v, f)
    surface = sw.run("mesh: exact surface samples", M.ExactSurface, v, f, n)
    out = {"exact": dict(v=v, f=f, n=n, stats=M.error_stats(surface.normal_error_deg(v, f)),
                         params=dict(what="the source mesh as it is (unused vertices dropped); "
                                          "its normals are the ones the renderer shaded with"),
                         surface=surface)}
    for kind in kinds:
        if kind == "exact":
            continue
        log(f"  {mesh_name}: degrading ({kind}), tuning to {M.DEGRADATIONS[kind]['target_deg']} deg")
        vd, fd, err, params = sw.run(f"mesh: {kind}", M.tuned_degradation, v, f, kind, surface,
                                     seed, log)
        params["what"] = M.DEGRADATIONS[kind]["what"]
        out[kind] = dict(v=vd, f=fd, n=None, stats=M.error_stats(err), params=params)
        log(f"  {mesh_name} {kind}: {len(vd)} vertices, {len(fd)} faces, {out[kind]['stats']}")
    return out


def split_faces(v, faces, n):
    """An object of `n` materials: equal-height slabs along the world up axis (+y) of the mesh's
    bounding box, planes at y_min + k (y_max - y_min) / n, k = 1..n-1. Each face's label is the
    slab of its centroid (0: the lowest). Returns the labels and the planes' y."""
    lo, hi = float(v[:, 1].min()), float(v[:, 1].max())
    planes = [lo + k * (hi - lo) / n for k in range(1, n)]
    centroid_y = v[faces][:, :, 1].mean(axis=1)
    return np.searchsorted(np.array(planes), centroid_y, side="right").astype(np.int64), planes


def face_areas(v, faces):
    p0, p1, p2 = v[faces[:, 0]], v[faces[:, 1]], v[faces[:, 2]]
    return 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)


def write_labels(path, labels):
    """One integer per line, no header."""
    M.write_atomic(path, ("\n".join(str(int(x)) for x in labels) + "\n").encode("ascii"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="output folder (one sub-folder per scene)")
    ap.add_argument("--scenes", default="bunny-1light,spot-3lights",
                    help="MESH-RIG list; meshes: spot, bunny; rigs: 1light, 3lights")
    ap.add_argument("--materials", default=",".join(MATERIALS), help="from " + ", ".join(MATERIALS))
    ap.add_argument("--meshes", default="exact,realistic,poor", help="mesh variants to write")
    ap.add_argument("--views", type=int, default=11)
    ap.add_argument("--size", default="256x192", help="image WIDTHxHEIGHT")
    ap.add_argument("--fov", type=float, default=30.0, help="horizontal field of view, degrees")
    ap.add_argument("--elevation", type=float, default=20.0, help="camera elevation, degrees")
    ap.add_argument("--spp", type=int, default=64, help="samples per pixel, direct integrator")
    ap.add_argument("--path-spp", type=int, default=256,
                    help="samples per pixel of the path-traced images (0: none)")
    ap.add_argument("--path-depth", type=int, default=4, help="path integrator max_depth")
    ap.add_argument("--half", action="store_true", help="write half-float EXR (default float)")
    ap.add_argument("--truth", default="full,subset",
                    help="full (truth.binary, 35 MB), subset (truth_subset.bin), or both")
    ap.add_argument("--subset-step", type=int, default=97)
    ap.add_argument("--check-views", type=int, default=3, help="views in the pixel check")
    ap.add_argument("--check-pixels", type=int, default=24, help="pixels per checked view")
    ap.add_argument("--variant", default="auto", choices=["auto", "llvm_ad_rgb", "scalar_rgb"])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--merl-table", action="append", default=[], metavar="NAME=PATH",
                    help="also a material of the measured kind: a MERL .binary table (e.g. "
                         "`brdf-rig merl tabulate data/merl-nbrdf/NAME.f32 PATH`), rendered "
                         "through scripts/independent/merl_bsdf.py as material merl-NAME; the "
                         "scene's index entry asks the reconstruction to leave NAME out of its "
                         "basis. Repeatable.")
    ap.add_argument("--split", action="append", default=[], metavar="A+B[+C]",
                    help="an object of two or three materials (names as --materials takes, "
                         "merl-NAME included): equal-height slabs along +y of the exact mesh's "
                         "bounding box, the lowest the first named; one scene "
                         "SCENE-split-A+B per value and --scenes entry, with per-face and "
                         "per-vertex labels and one truth table per material. With --split only "
                         "these scenes are rendered. Repeatable.")
    args = ap.parse_args()
    for spec in args.merl_table:
        name, eq, path = spec.partition("=")
        if not eq or not name or not os.path.isfile(path):
            sys.exit(f"--merl-table {spec!r}: expected NAME=PATH of an existing MERL .binary")
        MATERIALS[f"merl-{name}"] = dict(
            bsdf={"type": "merl_table", "filename": os.path.abspath(path)},
            what=f"the MERL-format table {os.path.basename(path)} (nearest-bin lookup)",
            basis_exclude=[name], in_merl_set=True)
    if args.merl_table and "--materials" not in " ".join(sys.argv):
        args.materials = ",".join(f"merl-{s.partition('=')[0]}" for s in args.merl_table)

    try:
        width, height = (int(x) for x in args.size.lower().split("x"))
    except ValueError:
        sys.exit(f"--size {args.size!r}: expected WIDTHxHEIGHT, e.g. 256x192")
    materials = [m for m in args.materials.split(",") if m]
    kinds = [k for k in args.meshes.split(",") if k]
    truth_kinds = set(args.truth.split(","))
    for m in materials:
        if m not in MATERIALS:
            sys.exit(f"--materials: unknown {m!r} (known: {', '.join(MATERIALS)})")
    splits = []
    for spec in args.split:
        names = spec.split("+")
        if not 2 <= len(names) <= 3 or any(m not in MATERIALS for m in names):
            sys.exit(f"--split {spec!r}: expected two or three materials A+B[+C] from "
                     f"{', '.join(MATERIALS)}")
        splits.append(names)
    for k in kinds:
        if k != "exact" and k not in M.DEGRADATIONS:
            sys.exit(f"--meshes: unknown {k!r} (known: exact, {', '.join(M.DEGRADATIONS)})")
    if "exact" not in kinds:
        kinds.insert(0, "exact")  # the renderer's mesh; always written
    scenes = []
    for s in args.scenes.split(","):
        mesh_name, _, rig_name = s.partition("-")
        if mesh_name not in MESHES or rig_name not in rig.RIGS:
            sys.exit(f"--scenes: {s!r} is not MESH-RIG with MESH in {list(MESHES)} and RIG in "
                     f"{list(rig.RIGS)}")
        scenes.append((s, mesh_name, rig_name))
    if not truth_kinds <= {"full", "subset"}:
        sys.exit(f"--truth {args.truth!r}: expected full, subset or full,subset")

    variant = setup_mitsuba(args.variant)
    if args.merl_table:
        importlib.import_module("independent.merl_bsdf")  # registers the merl_table plugin
    log(f"Mitsuba {mi.__version__}, variant {variant}"
        + (f" (libLLVM: {os.environ.get('DRJIT_LIBLLVM_PATH')})" if variant != "scalar_rgb" else ""))
    command = shlex.join(["scripts/render_recon_scenes.py"] + sys.argv[1:])
    os.makedirs(args.out, exist_ok=True)
    camera = rig.Camera(width, height, args.fov)
    direct = {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0}
    path = {"type": "path", "max_depth": args.path_depth, "rr_depth": 1000}

    sw_all = Stopwatch()
    wi, wo, above = sw_all.run("bin centres", merl.bin_centres)
    back = merl.bin_index(wi[above], wo[above])
    bad = int(np.count_nonzero(back != np.nonzero(above)[0]))
    log(f"MERL bin centres: {above.sum()} above the horizon, {bad} map back to another bin")
    if bad:
        sys.exit("bin centre conversion is inconsistent: refusing to write truth tables")
    subset = merl.subset_indices(above, args.subset_step)

    mesh_cache = {}
    index = {}  # scenes of earlier runs into the same folder stay listed
    index_path = os.path.join(args.out, "index.json")
    if os.path.isfile(index_path):
        with open(index_path, encoding="utf-8") as f:
            index = json.load(f).get("scenes", {})
    for scene_name, mesh_name, rig_name in scenes:
        sw = Stopwatch()
        if mesh_name not in mesh_cache:
            mesh_cache[mesh_name] = prepare_meshes(mesh_name, kinds, args.seed, sw)
        variants = mesh_cache[mesh_name]
        exact = variants["exact"]
        views, placement = rig.ring(exact["v"], camera, args.views, args.elevation, rig_name)
        caster = Caster(exact["v"], exact["f"])
        diag = float(np.linalg.norm(exact["v"].max(axis=0) - exact["v"].min(axis=0)))
        units = ([(f"split-{'+'.join(s)}", s) for s in splits] if splits
                 else [(m, [m]) for m in materials])
        for unit_name, mats in units:
            split = bool(splits)
            material = "+".join(mats)
            t0 = time.time()
            folder = os.path.join(args.out, f"{scene_name}-{unit_name}")
            what = (MATERIALS[material]["what"] if not split else
                    "slabs along +y, lowest first: "
                    + "; ".join(f"{m} ({MATERIALS[m]['what']})" for m in mats))
            log(f"{folder}: {len(views)} views {width}x{height}, {what}")
            for sub in ("light", "sparse") + (("light_path",) if args.path_spp else ()):
                os.makedirs(os.path.join(folder, sub), exist_ok=True)
            for kind in kinds:
                mv = variants[kind]
                M.write_ply(os.path.join(folder, f"mesh_{kind}.ply"), mv["v"], mv["f"], mv["n"])
            rig.write_colmap(os.path.join(folder, "sparse"), camera, views)
            bsdfs = [mi.load_dict(MATERIALS[m]["bsdf"]) for m in mats]
            mesh_ply = os.path.join(folder, "mesh_exact.ply")
            parts_dir = None
            if split:
                face_labels, planes = split_faces(exact["v"], exact["f"], len(mats))
                face_counts = np.bincount(face_labels, minlength=len(mats))
                if (face_counts == 0).any():
                    sys.exit(f"{folder}: a slab holds no face centroid ({face_counts.tolist()})")
                area = face_areas(exact["v"], exact["f"])
                area_shares = np.bincount(face_labels, weights=area,
                                          minlength=len(mats)) / area.sum()
                write_labels(os.path.join(folder, "labels_exact_faces.txt"), face_labels)
                vertex_label_counts = {}
                for kind in kinds:
                    vl = face_labels[exact["surface"].nearest_face(variants[kind]["v"])]
                    write_labels(os.path.join(folder, f"labels_{kind}.txt"), vl)
                    vertex_label_counts[kind] = np.bincount(vl, minlength=len(mats)).tolist()
                # one shape per label: the exact mesh's vertices and normals, that label's faces
                parts_dir = tempfile.mkdtemp(prefix="split-parts-")
                parts = []
                for k, m in enumerate(mats):
                    ply = os.path.join(parts_dir, f"part_{k}.ply")
                    M.write_ply(ply, exact["v"], exact["f"][face_labels == k], exact["n"])
                    parts.append((ply, m))
                log(f"  split at y = {', '.join(f'{y:.6g}' for y in planes)}: faces "
                    f"{face_counts.tolist()}, area shares "
                    f"{', '.join(f'{a:.3f}' for a in area_shares)}")
            else:
                face_labels = None
                parts = [(mesh_ply, material)]
            checks = [[] for _ in mats]  # per material
            extra = []  # (path - direct) / direct on pixels the direct light reaches
            rng = np.random.default_rng(args.seed)
            try:
                for view in views:
                    img = sw.run("render direct", render, parts, camera, view, args.spp,
                                 direct, args.seed + view["index"])
                    write_exr(os.path.join(folder, "light", view["name"]), img, args.half)
                    if args.path_spp:
                        imgp = sw.run("render path", render, parts, camera, view,
                                      args.path_spp, path, args.seed + view["index"])
                        write_exr(os.path.join(folder, "light_path", view["name"]), imgp,
                                  args.half)
                        lit = img.mean(axis=2) > 1e-3 * img.mean(axis=2).max()
                        extra.append((imgp[lit].mean(axis=1) - img[lit].mean(axis=1))
                                     / img[lit].mean(axis=1))
                    if view["index"] < args.check_views:
                        for k, m in enumerate(mats):
                            checks[k].append(sw.run(
                                "pixel check", pixel_check, caster, exact["n"], diag, camera,
                                view, img, m, bsdfs[k], rng, args.check_pixels,
                                **(dict(face_labels=face_labels, label=k) if split else {})))
                            c = checks[k][-1]
                            log(f"  {view['name']}: {m + ': ' if split else ''}pixel check on "
                                f"{c['pixels']} pixels: median |rel err| "
                                f"{c.get('median_abs_rel_error')}, max {c.get('max_abs_rel_error')}")
            finally:
                if parts_dir:
                    shutil.rmtree(parts_dir)
            jobs = {}
            for kind in kinds:
                for dir_name, suffix in (("light", ""),) + ((("light_path", "_path"),)
                                                            if args.path_spp else ()):
                    name = f"job_{kind}{suffix}.toml"
                    text = rig.job_text(
                        f"mesh_{kind}.ply", "sparse", dir_name, views,
                        f"brdf-rig reconstruction job: {scene_name}, {material}, {kind} mesh, "
                        f"{'path-traced' if suffix else 'direct-light'} images.\n"
                        f"Written by: {command}")
                    M.write_atomic(os.path.join(folder, name), text.encode("utf-8"))
                    jobs[f"{kind}{suffix}"] = name
            # every bin above the horizon for the full table, else only the subset's
            need = above if "full" in truth_kinds else np.isin(np.arange(merl.BINS), subset)
            tag = [f"_{k}" if split else "" for k in range(len(mats))]
            lambert_dev = [None] * len(mats)
            recip = []
            for k, (m, bsdf) in enumerate(zip(mats, bsdfs)):
                f = sw.run("truth: evaluate BSDF", eval_brdf, bsdf, wi[need], wo[need])
                full = np.zeros((merl.BINS, 3))
                full[need] = f
                if "full" in truth_kinds:
                    sw.run("truth: write table", merl.write_table,
                           os.path.join(folder, f"truth{tag[k]}.binary"), full, above)
                if "subset" in truth_kinds:
                    merl.write_subset(os.path.join(folder, f"truth_subset{tag[k]}.bin"), subset,
                                      wi, wo, full, args.subset_step)
                if m == "lambert":
                    alb = np.array(MATERIALS["lambert"]["bsdf"]["reflectance"]["value"])
                    lambert_dev[k] = float(np.abs(f * np.pi / alb[None] - 1.0).max())
                    log(f"  Lambertian table: max |f pi / albedo - 1| = {lambert_dev[k]:.2e}")
                swapped = eval_brdf(bsdf, wo[subset], wi[subset])
                denom = np.maximum(np.abs(full[subset]), 1e-6)
                recip.append(np.abs(swapped - full[subset]) / denom)

            def material_record(m):
                return dict(name=m, in_merl_set=MATERIALS[m].get("in_merl_set", False),
                            description=MATERIALS[m]["what"],
                            **({"basis_exclude": MATERIALS[m]["basis_exclude"]}
                               if MATERIALS[m].get("basis_exclude") else {}),
                            mitsuba_bsdf=MATERIALS[m]["bsdf"],
                            rendered_as="twosided wrapper around mitsuba_bsdf")

            truth_how = ("Mitsuba's bsdf.eval at every MERL bin centre (phi_h = 0; directions "
                         "from the Rusinkiewicz angles in scripts/independent/merl.py), divided "
                         "by the light's cosine; no data (-1) below the horizon")
            truth_units = "f_r in 1/sr, linear RGB, no MERL scale applied in the subset"
            pixel_what = ("rendered pixels against E f_r cos theta_i averaged over 4x4 sub-pixel "
                          "rays cast in numpy (scripts/independent/raycast.py); lit, unclipped "
                          "pixels only")
            if not split:
                material_json = material_record(material)
                truth_json = dict(
                    table="truth.binary" if "full" in truth_kinds else None,
                    subset=(dict(file="truth_subset.bin", step=args.subset_step,
                                 count=int(len(subset))) if "subset" in truth_kinds else None),
                    bins_above_horizon=int(above.sum()),
                    how=truth_how,
                    reciprocity_max_rel=float(f"{recip[0].max():.3g}"),
                    reciprocity_median_rel=float(f"{np.median(recip[0]):.3g}"),
                    units=truth_units,
                )
                lambert_json = (float(f"{lambert_dev[0]:.3g}") if material == "lambert" else None)
                pixel_json = checks[0]
            else:
                tables = ([f"truth{t}.binary" for t in tag] if "full" in truth_kinds else None)
                material_json = dict(
                    name=material,
                    description=what,
                    parts=[dict(label=k, **material_record(m),
                                truth_table=tables[k] if tables else None,
                                truth_subset=(f"truth_subset{tag[k]}.bin"
                                              if "subset" in truth_kinds else None))
                           for k, m in enumerate(mats)],
                    rendered_as="one Mitsuba ply shape per label (the exact mesh's vertices and "
                                "vertex normals, the faces of that label), each a twosided "
                                "wrapper around its part's mitsuba_bsdf")
                truth_json = dict(
                    tables=tables,
                    subsets=(dict(files=[f"truth_subset{t}.bin" for t in tag],
                                  step=args.subset_step, count=int(len(subset)))
                             if "subset" in truth_kinds else None),
                    per_label="truth_K.binary and truth_subset_K.bin are the material of label K "
                              "(split.materials[K])",
                    bins_above_horizon=int(above.sum()),
                    how=truth_how,
                    reciprocity_max_rel=[float(f"{r.max():.3g}") for r in recip],
                    reciprocity_median_rel=[float(f"{np.median(r):.3g}") for r in recip],
                    units=truth_units,
                )
                lambert_json = [float(f"{d:.3g}") if d is not None else None
                                for d in lambert_dev]
                pixel_json = []
                for k, m in enumerate(mats):
                    rel = [c["median_abs_rel_error"] for c in checks[k] if c["pixels"]]
                    worst = [c["max_abs_rel_error"] for c in checks[k] if c["pixels"]]
                    pixel_json.append(dict(
                        label=k, material=m,
                        pixels=int(sum(c["pixels"] for c in checks[k])),
                        median_abs_rel_error_per_view=rel,
                        max_abs_rel_error=max(worst) if worst else None,
                        views=checks[k]))
            truth = dict(
                format="brdf-rig independent scene, version 1 (docs/independent-scenes.md)",
                command=command,
                renderer=dict(name="Mitsuba 3", version=mi.__version__, variant=variant,
                              jobs_use="light/ (direct integrator: direct light and shadows)",
                              direct=dict(integrator=direct, spp=args.spp),
                              path=(dict(integrator=path, spp=args.path_spp) if args.path_spp
                                    else None),
                              film="hdrfilm, box reconstruction filter (each pixel the mean "
                                   "radiance over its square), stratified sampler",
                              exr="half" if args.half else "float"),
                mesh=dict(name=mesh_name, source=MESHES[mesh_name]["file"],
                          provenance=MESHES[mesh_name]["provenance"],
                          up_axis="+y", units="those of the source file"),
                mesh_variants={
                    kind: dict(file=f"mesh_{kind}.ply", job=jobs[kind],
                               vertices=len(variants[kind]["v"]), faces=len(variants[kind]["f"]),
                               **variants[kind]["stats"], params=variants[kind]["params"])
                    for kind in kinds},
                normal_error_definition="per vertex of the variant: angle between its "
                                        "angle-weighted vertex normal and the exact surface's "
                                        "interpolated normal at the nearest of ~1e6 samples of "
                                        "the exact surface",
                material=material_json,
                **({"split": dict(
                    axis=[0, 1, 0],
                    planes_y=[float(y) for y in planes],
                    materials=mats,
                    face_counts=face_counts.tolist(),
                    area_shares=[float(f"{a:.6g}") for a in area_shares],
                    rule="equal-height slabs along the world up axis (+y) of the exact mesh's "
                         "bounding box, planes at y_min + k (y_max - y_min) / n, k = 1..n-1; a "
                         "face's label is the slab of its centroid, 0 the lowest slab, label K "
                         "is materials[K]",
                    face_labels="labels_exact_faces.txt",
                    vertex_labels={kind: f"labels_{kind}.txt" for kind in kinds},
                    vertex_label_rule="per vertex of mesh_<variant>.ply, in vertex order: the "
                                      "label of the exact face whose surface sample (of the "
                                      "~1e6 of the normal error) is nearest to the vertex",
                    vertex_label_counts=vertex_label_counts,
                    label_files="one integer per line, no header")} if split else {}),
                truth=truth_json,
                rig=dict(name=rig_name, lights=[
                    dict(index=i, dir_camera=rig.light_dir_camera(L["angle_deg"], L["azimuth_deg"]).tolist(),
                         angle_from_view_deg=L["angle_deg"], image_azimuth_deg=L["azimuth_deg"],
                         irradiance=L["irradiance"]) for i, L in enumerate(rig.RIGS[rig_name])],
                    views=len(views), **placement,
                    description=("one light fixed to the camera (one theta_d)"
                                 if rig_name == "1light" else
                                 "three light directions fixed in camera axes; view k is lit by "
                                 "light k mod 3")),
                camera=dict(model="PINHOLE", width=width, height=height, fx=camera.f, fy=camera.f,
                            cx=camera.cx, cy=camera.cy, fov_x_deg=args.fov),
                views=[dict(name=v["name"], light=v["light"], azimuth_deg=round(v["azimuth_deg"], 6),
                            camera_centre=v["eye"].tolist(),
                            light_dir_camera=v["light_dir_camera"].tolist(),
                            light_dir_world=v["light_dir_world"].tolist(),
                            irradiance=v["irradiance"]) for v in views],
                jobs=jobs,
                checks=dict(
                    merl_bin_centres_map_back=True,
                    lambert_table_max_deviation=lambert_json,
                    interreflection=(dict(
                        what="(path - direct) / direct over the pixels the direct light reaches, "
                             "all views",
                        median=float(f"{np.median(np.concatenate(extra)):.3g}"),
                        p95=float(f"{np.percentile(np.concatenate(extra), 95):.3g}"))
                        if extra else None),
                    pixel_prediction=pixel_json,
                    pixel_prediction_what=(pixel_what if not split else
                                           pixel_what + "; per material, on pixels whose every "
                                           "sub-pixel ray hits a face of its label"),
                ),
                seconds=dict(**sw_all.times, **sw.times, total_this_scene=round(time.time() - t0, 1)),
            )
            M.write_atomic(os.path.join(folder, "truth.json"),
                           (json.dumps(truth, indent=1) + "\n").encode("utf-8"))
            exclude = []
            for m in mats:
                exclude += [x for x in MATERIALS[m].get("basis_exclude", []) if x not in exclude]
            if not split:
                entry = dict(
                    mesh=mesh_name, rig=rig_name, material=material, jobs=jobs, command=command,
                    **({"basis_exclude": exclude} if exclude else {}),
                    median_normal_error_deg={k: truth["mesh_variants"][k]["median_normal_error_deg"]
                                             for k in kinds},
                    truth_table=truth["truth"]["table"])
            else:
                entry = dict(
                    mesh=mesh_name, rig=rig_name, material=material, materials=mats, jobs=jobs,
                    command=command,
                    **({"basis_exclude": exclude} if exclude else {}),
                    median_normal_error_deg={k: truth["mesh_variants"][k]["median_normal_error_deg"]
                                             for k in kinds},
                    truth_tables=truth["truth"]["tables"],
                    labels={kind: f"labels_{kind}.txt" for kind in kinds})
            index[os.path.basename(folder)] = entry
            M.write_atomic(index_path,
                           (json.dumps(dict(scenes=index), indent=1)
                            + "\n").encode("utf-8"))
            sw.times = {k: v for k, v in sw.times.items() if k.startswith("mesh")}
            log(f"  done in {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
