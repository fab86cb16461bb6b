#!/usr/bin/env python3
"""Render the calibration fixture corpus with Mitsuba 3, a renderer independent of brdf-rig.

The fixtures in tests/fixtures/calibration/ are images of a glossy black sphere (light
direction) and of a white board (irradiance) that brdf-rig's own simulator (src/sim) did not
make, each with its truth in a JSON file beside it. tests/calib_fixtures.rs runs
`brdf-rig calibrate sphere` and `brdf-rig calibrate white` on every one. This script is not run
by the tests or CI: the rendered files are committed. Regenerate them with

    python3 -m venv /work/venv-mitsuba
    /work/venv-mitsuba/bin/pip install mitsuba==3.9.1 numpy
    /work/venv-mitsuba/bin/python scripts/render_calibration_fixtures.py

(about 10 minutes on 2 cores; `--only NAME` renders one fixture, `--out DIR` writes elsewhere).
Renders are seeded, so a re-run gives the same images up to Mitsuba's thread scheduling.

Conventions of the truth files (those of docs/calibration.md and src/geometry/camera.rs):
- Camera axes x right, y down, z forward (COLMAP); the Mitsuba world frame *is* that camera
  frame: the sensor sits at the origin looking along +z with image-up along -y. The script checks
  it on every render: a ray Mitsuba's sensor shoots through a pixel must match the pinhole ray
  `((px - cx) / fx, (py - cy) / fy, 1)` with pixel centres at half-integers.
- `light_dir_camera` points from the object (the sphere's or the board's centre) towards the
  light; Mitsuba's directional emitter takes the opposite, the direction light travels.
- `irradiance` is per colour channel on a surface facing the light (Mitsuba's `irradiance` of a
  directional emitter, `pi L sin^2(delta)` for a spherical emitter of radiance L and angular
  radius delta, `I / d^2` for a point light of intensity I at distance d).
- Image values are radiance in the units Mitsuba renders (EXR), or for PNG files
  `radiance * exposure` encoded (linear 16-bit, or sRGB 8-bit): `scale = 1 / exposure` turns
  them back (`--scale`), and the clip level is the format's largest code.
- Every sphere fixture is checked against Mitsuba's own geometry: the mirror point of the
  true light (where n = (l + v) / |l + v|, found by fixed-point iteration on the sphere) is
  projected with the pinhole model and must lie within a pixel of the rendered highlight's
  peak (`check.highlight_*` in the truth file).

Each fixture is a folder with `light.exr` (or `.png`), optionally `outline.exr` (the sphere
under ambient light, to find its outline in), or `board.exr`, and `truth.json`. Fixtures meant
to be unusable say so (`unusable`: why, and a phrase the error must contain).
"""

import argparse
import json
import math
import os
import struct
import sys
import time
import zlib

import numpy as np

import mitsuba as mi

mi.set_variant("scalar_rgb")

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_OUT = os.path.join(ROOT, "tests", "fixtures", "calibration")

# Default camera: 320x240, f = 600 px, principal point at the image centre.
W, H, F = 320, 240, 600.0
SPHERE_R = 0.025  # 5 cm diameter
SPHERE_C = (0.0, 0.0, 0.35)


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def light_from_angles(theta_deg, phi_deg):
    """Unit vector towards the light, `theta` from the direction towards the camera (-z), `phi`
    the azimuth in the image plane from +x (right) towards +y (down): phi = -90 is above."""
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return unit([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), -math.cos(t)])


def rgb(v):
    if np.isscalar(v):
        v = [v, v, v]
    return {"type": "rgb", "value": [float(x) for x in v]}


def sensor_dict(cam, spp):
    w, h, f = cam["width"], cam["height"], cam["f"]
    fov = math.degrees(2.0 * math.atan(w / 2.0 / f))
    d = {
        "type": "perspective",
        "fov": fov,
        "fov_axis": "x",
        "near_clip": 0.01,
        "far_clip": 100.0,
        "to_world": mi.ScalarTransform4f().look_at(
            origin=[0, 0, 0], target=[0, 0, 1], up=[0, -1, 0]
        ),
        "film": {
            "type": "hdrfilm",
            "width": w,
            "height": h,
            "pixel_format": "rgb",
            # pixel-area integration, as a sensor pixel does
            "rfilter": {"type": "box"},
        },
        "sampler": {"type": "independent", "sample_count": spp},
    }
    if cam.get("aperture_radius"):
        d["type"] = "thinlens"
        d["aperture_radius"] = cam["aperture_radius"]
        d["focus_distance"] = cam["focus_distance"]
    return d


def plane(centre, normal, half_w, half_h, bsdf):
    """A rectangle centred at `centre` facing `normal`, two-sided diffuse."""
    n = unit(normal)
    up = np.array([0.0, -1.0, 0.0]) if abs(n[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    to_world = (
        mi.ScalarTransform4f()
        .look_at(origin=list(centre), target=list(np.asarray(centre) + n), up=list(up))
        .scale([half_w, half_h, 1.0])
    )
    return {"type": "rectangle", "to_world": to_world, "bsdf": {"type": "twosided", "bsdf": bsdf}}


def texture_dict(kind, seed):
    """Backdrop reflectance textures (numpy, seeded): a left-to-right gradient or a printed
    pattern (checker plus soft blobs)."""
    n = 256
    u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    if kind == "gradient":
        a = 0.15 + 0.7 * u + 0.1 * v
    else:
        rng = np.random.default_rng(seed)
        checker = ((np.floor(u * 14) + np.floor(v * 14)) % 2) * 0.3 + 0.35
        blobs = np.zeros_like(u)
        for _ in range(25):
            x0, y0, s, amp = rng.uniform(0, 1), rng.uniform(0, 1), rng.uniform(0.02, 0.08), rng.uniform(-0.2, 0.2)
            blobs += amp * np.exp(-((u - x0) ** 2 + (v - y0) ** 2) / (2 * s * s))
        a = np.clip(checker + blobs, 0.05, 0.95)
    arr = np.repeat(a[:, :, None], 3, axis=2).astype(np.float32)
    return {"type": "bitmap", "bitmap": mi.Bitmap(arr), "raw": True, "filter_type": "bilinear"}


def sphere_scene(fx):
    """Scene dictionary of a sphere fixture and the emitters of its light or outline image."""
    cam = fx["camera"]
    c, r = fx["sphere_centre"], fx["sphere_radius"]
    coat = {
        "type": "roughplastic",
        "distribution": "ggx",
        "alpha": fx["alpha"],
        "int_ior": fx["ior"],
        "diffuse_reflectance": rgb(fx.get("base_albedo", 0.02)),
    }
    if fx["alpha"] == 0:
        coat = {
            "type": "plastic",
            "int_ior": fx["ior"],
            "diffuse_reflectance": rgb(fx.get("base_albedo", 0.02)),
        }
    objects = {"ball": {"type": "sphere", "center": list(c), "radius": r, "bsdf": coat}}
    bd = fx.get("backdrop")
    if bd is not None:
        if bd["kind"] == "uniform":
            refl = rgb(bd["albedo"])
        else:
            refl = texture_dict(bd["kind"], 7)
        objects["backdrop"] = plane(
            [0.0, 0.0, bd["z"]], [0, 0, -1], bd.get("half", 0.4), bd.get("half", 0.4),
            {"type": "diffuse", "reflectance": refl},
        )
    holder = fx.get("holder")
    if holder is not None:
        cx, cy, cz = c
        if holder["kind"] == "post":
            objects["post"] = {
                "type": "cylinder",
                "p0": [cx, cy, cz],
                "p1": [cx, cy + 0.3, cz],
                "radius": holder["radius_frac"] * r,
                "bsdf": {"type": "diffuse", "reflectance": rgb(holder["albedo"])},
            }
        else:  # a cup the sphere sits in: a tube whose rim meets the sphere below its centre
            top = cy + holder["top_frac"] * r
            rad = r * math.sqrt(1.0 - holder["top_frac"] ** 2)
            objects["cup"] = {
                "type": "cylinder",
                "p0": [cx, top, cz],
                "p1": [cx, cy + 0.3, cz],
                "radius": rad,
                "bsdf": {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": rgb(holder["albedo"])}},
            }
    return objects


def emitters_dict(lights):
    out = {}
    for i, lt in enumerate(lights):
        key = f"light{i}"
        if lt["kind"] == "directional":
            out[key] = {"type": "directional", "direction": list(-unit(lt["dir"])), "irradiance": rgb(lt["irradiance"])}
        elif lt["kind"] == "env":
            out[key] = {"type": "constant", "radiance": rgb(lt["radiance"])}
        elif lt["kind"] == "sphere":
            # radiance that gives irradiance E at the target: E = pi L sin^2(delta)
            pos = np.asarray(lt["pos"])
            dist = np.linalg.norm(pos - np.asarray(lt["target"]))
            sin_d = lt["radius"] / dist
            radiance = np.asarray(lt["irradiance"], dtype=float) / (math.pi * sin_d * sin_d)
            out[key] = {
                "type": "sphere",
                "center": list(pos),
                "radius": lt["radius"],
                "emitter": {"type": "area", "radiance": rgb(list(radiance))},
            }
        elif lt["kind"] == "point":
            pos = np.asarray(lt["pos"])
            dist = np.linalg.norm(pos - np.asarray(lt["target"]))
            intensity = np.asarray(lt["irradiance"], dtype=float) * dist * dist
            out[key] = {"type": "point", "position": list(pos), "intensity": rgb(list(intensity))}
        else:
            raise ValueError(lt["kind"])
    return out


def render(objects, lights, cam, spp, seed, max_depth):
    d = {"type": "scene", "integrator": {"type": "path", "max_depth": max_depth}, "sensor": sensor_dict(cam, spp)}
    d.update(objects)
    d.update(emitters_dict(lights))
    scene = mi.load_dict(d)
    check_camera(scene, cam)
    img = np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64)
    return img[:, :, :3]


def check_camera(scene, cam):
    """The sensor's rays must be the pinhole rays of the truth's intrinsics (COLMAP axes)."""
    if cam.get("aperture_radius"):
        return  # a thin lens samples its aperture; its chief ray is the same pinhole ray
    s = scene.sensors()[0]
    w, h, f = cam["width"], cam["height"], cam["f"]
    for px, py in [(0.5, 0.5), (w - 10.5, 17.5), (w / 2 + 3.25, h / 2 - 40.75)]:
        ray, _ = s.sample_ray(0.0, 0.5, mi.ScalarPoint2f(px / w, py / h), mi.ScalarPoint2f(0.5, 0.5))
        want = unit([(px - w / 2) / f, (py - h / 2) / f, 1.0])
        got = np.array([ray.d[0], ray.d[1], ray.d[2]])
        if np.linalg.norm(got - want) > 1e-5:
            raise SystemExit(f"camera convention broken at pixel ({px}, {py}): {got} vs {want}")


def project(p, cam):
    return (cam["f"] * p[0] / p[2] + cam["width"] / 2.0, cam["f"] * p[1] / p[2] + cam["height"] / 2.0)


def sphere_outline_truth(c, r, cam):
    """The true outline (tangent cone) projected: centre projection, a circle fitted to 720
    outline points (what a user would draw), and the ellipse's extreme radii."""
    c = np.asarray(c, dtype=float)
    d = unit(c)
    alpha = math.asin(r / np.linalg.norm(c))
    helper = np.array([1.0, 0, 0]) if abs(d[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = unit(np.cross(d, helper))
    e2 = np.cross(d, e1)
    pts = []
    for k in range(720):
        a = 2 * math.pi * k / 720
        ray = d * math.cos(alpha) + (e1 * math.cos(a) + e2 * math.sin(a)) * math.sin(alpha)
        pts.append(project(ray, cam))
    pts = np.array(pts)
    # algebraic circle fit
    A = np.c_[pts[:, 0], pts[:, 1], np.ones(len(pts))]
    b = -(pts[:, 0] ** 2 + pts[:, 1] ** 2)
    D, E, Fc = np.linalg.lstsq(A, b, rcond=None)[0]
    ccx, ccy = -D / 2, -E / 2
    cr = math.sqrt(ccx * ccx + ccy * ccy - Fc)
    dist = np.hypot(pts[:, 0] - ccx, pts[:, 1] - ccy)
    return {
        "centre_camera_m": list(c),
        "radius_m": r,
        "angular_radius_deg": math.degrees(alpha),
        "centre_px": list(project(c, cam)),
        "outline_radius_px": math.tan(alpha) * cam["f"],
        "outline_circle_px": [ccx, ccy, cr],
        "outline_radius_range_px": [float(dist.min()), float(dist.max())],
        "outline_bbox_px": [float(pts[:, 0].min()), float(pts[:, 1].min()), float(pts[:, 0].max()), float(pts[:, 1].max())],
    }


def mirror_point(c, r, light):
    """Point on the sphere whose normal is the half vector of the light and the camera."""
    c = np.asarray(c, dtype=float)
    n = -unit(c)
    for _ in range(200):
        p = c + r * n
        v = unit(-p)
        l = unit(light["pos"] - p) if "pos" in light else unit(light["dir"])
        n_new = unit(l + v)
        if np.linalg.norm(n_new - n) < 1e-14:
            break
        n = n_new
    return c + r * n


def highlight_check(img, fx, light):
    """Predicted highlight pixel (mirror point through the pinhole model) against the rendered
    peak: the brightest pixel's neighbourhood centroid (3x3, above the local minimum)."""
    cam = fx["camera"]
    p = mirror_point(fx["sphere_centre"], fx["sphere_radius"], light)
    px, py = project(p, cam)
    lum = img.mean(axis=2)
    # look for the peak within 6 px of the prediction: a brighter lamp elsewhere is not it
    x0, x1 = max(int(px) - 6, 1), min(int(px) + 7, cam["width"] - 1)
    y0, y1 = max(int(py) - 6, 1), min(int(py) + 7, cam["height"] - 1)
    win = lum[y0:y1, x0:x1]
    iy, ix = np.unravel_index(np.argmax(win), win.shape)
    iy, ix = iy + y0, ix + x0
    nb = lum[iy - 1 : iy + 2, ix - 1 : ix + 2]
    wts = nb - nb.min()
    gy, gx = np.mgrid[iy - 1 : iy + 2, ix - 1 : ix + 2]
    cxp = float((wts * (gx + 0.5)).sum() / wts.sum())
    cyp = float((wts * (gy + 0.5)).sum() / wts.sum())
    dist = math.hypot(cxp - px, cyp - py)
    return {
        "highlight_predicted_px": [px, py],
        "highlight_rendered_px": [cxp, cyp],
        "highlight_distance_px": dist,
        "mirror_point_camera_m": list(p),
    }


# ---------------------------------------------------------------- post-processing

def vignette(img, cam, strength):
    """Multiply by 1 - strength * (r / r_corner)^2, r the distance from the image centre."""
    h, w = img.shape[:2]
    y, x = np.mgrid[0:h, 0:w]
    rr = ((x + 0.5 - w / 2) ** 2 + (y + 0.5 - h / 2) ** 2) / ((w / 2) ** 2 + (h / 2) ** 2)
    return img * (1.0 - strength * rr)[:, :, None]


def sensor_noise(img, rng, gain, read):
    """Poisson-Gaussian sensor noise: variance gain * value + read^2 (value in image units)."""
    sigma = np.sqrt(np.maximum(img, 0) * gain + read * read)
    return img + rng.normal(size=img.shape) * sigma


def srgb_encode(v):
    v = np.clip(v, 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)


def write_png(path, codes, bits):
    """Minimal PNG writer (RGB, 8 or 16 bits, no filtering): numpy and zlib only."""
    h, w, _ = codes.shape
    if bits == 16:
        raw = codes.astype(">u2").tobytes()
        row = w * 6
    else:
        raw = codes.astype(np.uint8).tobytes()
        row = w * 3
    data = b"".join(b"\x00" + raw[y * row : (y + 1) * row] for y in range(h))

    def chunk(tag, body):
        return struct.pack(">I", len(body)) + tag + body + struct.pack(">I", zlib.crc32(tag + body) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n"
    png += chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, bits, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(data, 9))
    png += chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)


def write_exr(path, img):
    """Half-float RGB EXR, lossless PIZ compression (Mitsuba's default for EXR)."""
    if np.nanmax(img) > 60000:
        raise SystemExit(f"{path}: values above the half-float range")
    mi.Bitmap(img.astype(np.float16)).write(path)


def encode(img, fmt, exposure):
    """Returns (codes, bits) for a PNG: linear 16-bit or sRGB 8-bit of `img * exposure`."""
    v = img * exposure
    if fmt == "png16":
        return np.round(np.clip(v, 0, 1) * 65535).astype(np.uint16), 16
    return np.round(srgb_encode(v) * 255).astype(np.uint8), 8


# ---------------------------------------------------------------- the corpus

def sphere_with_margins(left=None, top=None, right=None, z=SPHERE_C[2], r=SPHERE_R, cam=None):
    """A sphere centre (camera axes, depth z) whose projected outline lies `left`/`top`/`right`
    pixels from those frame edges (bisection on the exact outline)."""
    cam = cam or cam_default()
    x, y = 0.0, 0.0

    def solve(get, want, lo, hi):
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if get(mid) < want:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)

    if left is not None:
        x = solve(lambda v: sphere_outline_truth((v, y, z), r, cam)["outline_bbox_px"][0], left, -0.5 * z, 0.0)
    if right is not None:
        x = solve(lambda v: sphere_outline_truth((v, y, z), r, cam)["outline_bbox_px"][2], cam["width"] - right, 0.0, 0.5 * z)
    if top is not None:
        y = solve(lambda v: sphere_outline_truth((x, v, z), r, cam)["outline_bbox_px"][1], top, -0.5 * z, 0.0)
    return (x, y, z)


def cam_default(**kw):
    c = {"width": W, "height": H, "f": F}
    c.update(kw)
    return c


def sphere_fixture(name, description, **kw):
    fx = {
        "name": name,
        "kind": "sphere",
        "description": description,
        "camera": cam_default(),
        "sphere_centre": SPHERE_C,
        "sphere_radius": SPHERE_R,
        "alpha": 0.03,
        "ior": 1.5,
        "backdrop": {"kind": "uniform", "albedo": 0.6, "z": 0.9, "half": 0.5},
        "light": {"kind": "directional", "dir": light_from_angles(40, -130), "irradiance": [3.0, 3.0, 3.0]},
        "extra_lights": [],
        "light_ambient": 0.0,  # constant environment radiance in the light image
        "outline": {"ambient": 0.5},  # None: find the outline in the light image
        "outline_of": None,  # another fixture (same scene) whose outline image this one uses
        "spp": 96,
        "spp_outline": 128,
        "max_depth": 4,
        "format": "exr",
        "exposure": None,
        "post": {},
        "unusable": None,
        "rim_f0": None,  # the --rim-f0 a user would give (None: the default 0.04)
    }
    fx.update(kw)
    return fx


def corpus():
    """The fixtures. Spheres share a scene (material, backdrop, position) where they can, and then
    its outline image (`outline_of`), to keep the corpus small; some find their outline in the
    light image itself (`outline=None`), as a user without an ambient image would."""
    cam640 = cam_default(width=640, height=480, f=1200.0)
    d = lambda theta, phi: {"kind": "directional", "dir": light_from_angles(theta, phi), "irradiance": [3, 3, 3]}
    s = []
    # glossiness and Fresnel strength; sphere_gloss_a020 is the base scene the others vary
    s.append(sphere_fixture("sphere_gloss_a020", "glossy coat (GGX alpha 0.02, ior 1.5) before a uniform grey backdrop; the base scene",
                            alpha=0.02, light=d(40, -130)))
    s.append(sphere_fixture("sphere_gloss_a010", "glossier coat (GGX alpha 0.01)", alpha=0.01, light=d(30, -150)))
    s.append(sphere_fixture("sphere_gloss_a080", "rough coat (GGX alpha 0.08): a wide highlight lobe", alpha=0.08, light=d(35, 20)))
    s.append(sphere_fixture("sphere_ior130", "weak Fresnel (ior 1.3, f0 = 0.017); outline from the light image",
                            alpha=0.02, ior=1.3, light=d(45, -100), outline=None))
    s.append(sphere_fixture("sphere_ior200", "strong Fresnel (ior 2.0, f0 = 0.111)", alpha=0.02, ior=2.0, light=d(25, 160)))
    # surrounds
    s.append(sphere_fixture("sphere_bright_surround", "no backdrop: the sphere before a bright uniform surround (the room), its rim fading into it",
                            backdrop=None, alpha=0.015, light=d(40, -120), outline={"ambient": 1.0}))
    s.append(sphere_fixture("sphere_dark_backdrop", "black velvet backdrop (albedo 0.003) in a lit room: the sphere (diffuse base 0.03) brighter than its surround, its rim fading to the velvet, a bright ring further in where it mirrors the room",
                            backdrop={"kind": "uniform", "albedo": 0.003, "z": 0.6, "half": 0.4}, alpha=0.02, base_albedo=0.03,
                            light=d(35, -45)))
    s.append(sphere_fixture("sphere_gradient_backdrop", "backdrop with a strong left-to-right gradient; outline from the light image (lit backdrop)",
                            backdrop={"kind": "gradient", "z": 0.7, "half": 0.4}, alpha=0.02, light=d(30, -90), outline=None))
    s.append(sphere_fixture("sphere_textured_backdrop", "printed pattern backdrop (checker and blobs), close behind the sphere so its rim mirrors the pattern",
                            backdrop={"kind": "pattern", "z": 0.5, "half": 0.3}, alpha=0.02, light=d(45, 170)))
    # holders
    s.append(sphere_fixture("sphere_post", "a dark post (0.4 sphere radii) holding the sphere from below, down to the frame edge",
                            holder={"kind": "post", "radius_frac": 0.4, "albedo": 0.08}, alpha=0.02, light=d(40, -140)))
    s.append(sphere_fixture("sphere_cup", "the sphere sits in a grey cup that hides the bottom quarter of its outline",
                            holder={"kind": "cup", "top_frac": 0.55, "albedo": 0.35}, alpha=0.02, light=d(35, -70)))
    # framing
    s.append(sphere_fixture("sphere_corner", "off-centre, 4 px from the top and left frame edges (perspective: the outline is an ellipse)",
                            sphere_centre=sphere_with_margins(left=4, top=4), alpha=0.02, light=d(40, -20)))
    s.append(sphere_fixture("sphere_right_edge", "3 px from the right frame edge; outline from the light image",
                            sphere_centre=sphere_with_margins(right=3), alpha=0.02, outline=None, light=d(30, 180)))
    # light shapes and directions (the base scene's outline image)
    s.append(sphere_fixture("sphere_area_light", "an area light (a lamp subtending 3 deg radius): the highlight has extent",
                            alpha=0.02, outline_of="sphere_gloss_a020",
                            light={"kind": "sphere", "pos": list(np.asarray(SPHERE_C) + 5.0 * light_from_angles(40, -110)),
                                   "radius": 5.0 * math.sin(math.radians(3.0)), "target": SPHERE_C, "irradiance": [3, 3, 3]}))
    s.append(sphere_fixture("sphere_second_highlight", "a second, weaker highlight from a room lamp (a sixth of the irradiance)",
                            alpha=0.02, outline_of="sphere_gloss_a020", spp=192, light=d(35, -140),
                            extra_lights=[{"kind": "sphere", "pos": list(np.asarray(SPHERE_C) + 2.0 * light_from_angles(50, -20)), "radius": 0.03,
                                           "target": SPHERE_C, "irradiance": [0.5, 0.5, 0.5]}]))
    s.append(sphere_fixture("sphere_grazing_light", "light 80 deg from the camera: the highlight 40 deg from the sphere's centre",
                            alpha=0.02, outline_of="sphere_gloss_a020", light=d(80, -150)))
    # camera effects
    s.append(sphere_fixture("sphere_noise", "strong sensor noise (Poisson-Gaussian, about 4 % on the backdrop); outline from the light image",
                            alpha=0.02, light=d(45, -160), outline=None, post={"noise": {"gain": 0.004, "read": 0.004}}))
    s.append(sphere_fixture("sphere_vignetting", "strong vignetting (corners at 50 %), sphere off-centre; outline from the light image",
                            sphere_centre=(0.04, 0.025, 0.35), alpha=0.02, light=d(30, 60), outline=None, post={"vignetting": 0.5}))
    s.append(sphere_fixture("sphere_defocus", "defocused: thin lens focused 5 cm in front of the sphere (blur circle about 2 px); outline from the light image",
                            camera=cam_default(aperture_radius=0.006, focus_distance=0.30), alpha=0.02, light=d(40, -80), outline=None))
    s.append(sphere_fixture("sphere_640", "640x480 (sphere radius 86 px); outline from the light image",
                            camera=cam640, alpha=0.02, outline=None, spp=48, light=d(50, -120)))
    # formats (the highlight clips in both)
    s.append(sphere_fixture("sphere_png16", "16-bit linear PNG, clipping at code 65535; outline from the light image",
                            alpha=0.03, light=d(35, -120), outline=None, format="png16", exposure=1.5))
    s.append(sphere_fixture("sphere_srgb8", "8-bit sRGB PNG, clipping at code 255, coarse codes in the dark; outline from the light image",
                            alpha=0.03, light=d(35, -120), outline=None, format="srgb8", exposure=1.5,
                            post={"noise": {"gain": 0.0005, "read": 0.0005}}))
    # meant to be unusable
    s.append(sphere_fixture("sphere_cut", "the sphere is cut by the right frame edge; outline from the light image",
                            sphere_centre=sphere_with_margins(right=-15), alpha=0.02, outline=None, light=d(30, -150),
                            unusable={"reason": "the sphere is cut by the frame: its outline cannot be measured", "error": "cut by the frame edge"}))
    s.append(sphere_fixture("sphere_backlit", "the light almost behind the sphere (165 deg from the camera), no backdrop: the highlight sits on the rim",
                            backdrop=None, alpha=0.015, outline_of="sphere_bright_surround", light=d(165, -90),
                            unusable={"reason": "the highlight lies on the rim, where its normal cannot be measured", "error": "rim"}))

    b = []
    bl = light_from_angles(30, -120)
    cam_board = cam_default(width=240, height=180, f=450.0)
    board_common = {
        "kind": "white",
        "camera": cam_board,
        "board_centre": (0.0, 0.0, 0.5),
        "board_normal": (0.0, 0.0, -1.0),
        "board_half": (0.09, 0.065),
        "albedo": [0.85, 0.82, 0.78],
        "surround_albedo": 0.05,
        "light": {"kind": "directional", "dir": bl, "irradiance": [1.1, 1.0, 0.85]},
        "spp": 16,
        "format": "exr",
        "exposure": None,
        "post": {},
        "unusable": None,
    }

    def board(name, description, **kw):
        d = dict(board_common)
        d.update(name=name, description=description)
        d.update(kw)
        return d

    b.append(board("white_flat_noiseless", "a flat board facing the camera, noiseless linear EXR (every board pixel the same value)"))
    b.append(board("white_noise", "the same with sensor noise and a few hot pixels", post={"noise": {"gain": 0.003, "read": 0.002}, "hot": 12}))
    b.append(board("white_falloff", "a lamp 0.6 m from the board: irradiance falls off by 7 % towards the corners (truth at the board's centre)",
                   light={"kind": "point", "pos": list(np.asarray([0.0, 0.0, 0.5]) + 0.6 * light_from_angles(25, -100)), "target": (0.0, 0.0, 0.5), "irradiance": [1.1, 1.0, 0.85]},
                   post={"noise": {"gain": 0.002, "read": 0.002}}))
    b.append(board("white_tilted", "board turned 35 deg about the vertical axis, light 20 deg from the camera",
                   board_normal=tuple(unit([math.sin(math.radians(35)), 0.0, -math.cos(math.radians(35))])),
                   light={"kind": "directional", "dir": light_from_angles(20, 170), "irradiance": [1.1, 1.0, 0.85]},
                   post={"noise": {"gain": 0.002, "read": 0.002}}))
    b.append(board("white_png16", "16-bit linear PNG of the noisy board", format="png16", exposure=2.0,
                   post={"noise": {"gain": 0.002, "read": 0.002}}))
    b.append(board("white_srgb8", "8-bit sRGB PNG of the noisy board", format="srgb8", exposure=2.0,
                   post={"noise": {"gain": 0.002, "read": 0.002}}))
    b.append(board("white_srgb8_clipped", "8-bit sRGB PNG exposed so the board clips", format="srgb8", exposure=8.0,
                   post={"noise": {"gain": 0.002, "read": 0.002}},
                   unusable={"reason": "the board is clipped in the 8-bit file: its radiance is unknown", "error": "clipped"}))
    b.append({"name": "white_pure_noise", "kind": "white", "description": "pure noise (uniform random values, no board)",
              "camera": cam_default(width=160, height=120, f=300.0), "noise_only": True, "albedo": [0.85, 0.82, 0.78],
              "light": {"kind": "directional", "dir": bl, "irradiance": [1.1, 1.0, 0.85]},
              "board_normal": (0.0, 0.0, -1.0), "board_centre": (0.0, 0.0, 0.5), "format": "exr",
              "unusable": {"reason": "there is no board in the image", "error": "no white board found"}})
    return s + b


# ---------------------------------------------------------------- writing a fixture

def light_truth(light, target):
    target = np.asarray(target, dtype=float)
    if "pos" in light:
        d = unit(np.asarray(light["pos"]) - target)
    else:
        d = unit(light["dir"])
    return {
        "light_dir_camera": list(d),
        "light_kind": light["kind"],
        "irradiance": [float(x) for x in light["irradiance"]],
    }


def camera_truth(cam):
    return {
        "width": cam["width"],
        "height": cam["height"],
        "fx": cam["f"],
        "fy": cam["f"],
        "cx": cam["width"] / 2.0,
        "cy": cam["height"] / 2.0,
        "model": "pinhole, pixel centres at half-integers, axes x right y down z forward",
        **({"thin_lens": {"aperture_radius_m": cam["aperture_radius"], "focus_distance_m": cam["focus_distance"]}} if cam.get("aperture_radius") else {}),
    }


def finish(img, fx, rng, path_noext):
    """Camera effects, then the file in its format; returns (file name, clip level, scale)."""
    post = fx.get("post", {})
    if "vignetting" in post:
        img = vignette(img, fx["camera"], post["vignetting"])
    if "noise" in post:
        img = sensor_noise(img, rng, post["noise"]["gain"], post["noise"]["read"])
    if post.get("hot"):
        h, w = img.shape[:2]
        for _ in range(post["hot"]):
            img[rng.integers(0, h), rng.integers(0, w), :] *= 4.0
    if fx["format"] == "exr":
        write_exr(path_noext + ".exr", img)
        return os.path.basename(path_noext) + ".exr", None, None
    codes, bits = encode(img, fx["format"], fx["exposure"])
    write_png(path_noext + ".png", codes, bits)
    return os.path.basename(path_noext) + ".png", 1.0 / fx["exposure"], 1.0 / fx["exposure"]


def write_truth(out, truth):
    with open(os.path.join(out, "truth.json"), "w") as f:
        json.dump(truth, f, indent=2)
        f.write("\n")


def write_sphere(fx, out):
    cam = fx["camera"]
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(abs(hash(fx["name"])) % (2**32) if False else zlib.crc32(fx["name"].encode()))
    objects = sphere_scene(fx)
    lights = [fx["light"]] + fx["extra_lights"]
    if fx["light_ambient"]:
        lights = lights + [{"kind": "env", "radiance": fx["light_ambient"]}]
    t0 = time.time()
    light_img = render(objects, lights, cam, fx["spp"], 1, fx["max_depth"])
    check = highlight_check(light_img, fx, fx["light"])
    if fx["unusable"] is None and check["highlight_distance_px"] > 1.0:
        raise SystemExit(f"{fx['name']}: rendered highlight {check['highlight_rendered_px']} is "
                         f"{check['highlight_distance_px']:.2f} px from the predicted {check['highlight_predicted_px']}")
    light_file, clip, scale = finish(light_img, fx, rng, os.path.join(out, "light"))
    outline_file = None
    if fx["outline_of"] is not None:
        outline_file = f"../{fx['outline_of']}/outline.exr"
        if not os.path.exists(os.path.join(out, outline_file)):
            raise SystemExit(f"{fx['name']}: render {fx['outline_of']} first (its outline image is shared)")
    elif fx["outline"] is not None:
        amb = render(objects, [{"kind": "env", "radiance": fx["outline"]["ambient"]}], cam, fx["spp_outline"], 2, fx["max_depth"])
        outline_file, _, _ = finish(amb, fx, rng, os.path.join(out, "outline"))
    truth = {
        "name": fx["name"],
        "kind": "sphere",
        "description": fx["description"],
        "renderer": f"Mitsuba {mi.__version__} scalar_rgb, path tracer (max depth {fx['max_depth']}), box pixel filter",
        "light_image": light_file,
        "outline_image": outline_file,
        "intrinsics": camera_truth(cam),
        **light_truth(fx["light"], fx["sphere_centre"]),
        "sphere": {
            **sphere_outline_truth(fx["sphere_centre"], fx["sphere_radius"], cam),
            "material": f"Mitsuba roughplastic: GGX alpha {fx['alpha']}, interior ior {fx['ior']} (f0 = {((fx['ior'] - 1) / (fx['ior'] + 1)) ** 2:.4f}), diffuse base {fx.get('base_albedo', 0.02)}",
            "alpha": fx["alpha"],
            "ior": fx["ior"],
            "f0": ((fx["ior"] - 1) / (fx["ior"] + 1)) ** 2,
        },
        "scene": {
            "backdrop": fx["backdrop"],
            "holder": fx.get("holder"),
            "extra_lights": [light_truth(x, fx["sphere_centre"]) for x in fx["extra_lights"]],
            "light_image_ambient_radiance": fx["light_ambient"],
            "outline_image_ambient_radiance": fx["outline"]["ambient"] if fx["outline"] else None,
            "outline_image_shared_with": fx["outline_of"],
            "post": fx["post"],
            "spp": fx["spp"],
        },
        "format": fx["format"],
        "transfer": "srgb" if fx["format"] == "srgb8" else "linear",
        "scale": scale,
        "clip_level": clip,
        "check": check,
        "unusable": fx["unusable"],
    }
    write_truth(out, truth)
    print(f"{fx['name']}: {time.time() - t0:.0f} s, highlight {check['highlight_distance_px']:.2f} px from the predicted")


def write_white(fx, out):
    cam = fx["camera"]
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(zlib.crc32(fx["name"].encode()))
    t0 = time.time()
    if fx.get("noise_only"):
        img = rng.uniform(0.0, 0.5, size=(cam["height"], cam["width"], 3))
        file, clip, scale = finish(img, {"format": "exr", "post": {}}, rng, os.path.join(out, "board"))
        board = {"normal_camera": list(fx["board_normal"]), "centre_camera_m": list(fx["board_centre"])}
    else:
        bc = np.asarray(fx["board_centre"], dtype=float)
        n = unit(fx["board_normal"])
        objects = {
            "board": plane(bc, n, fx["board_half"][0], fx["board_half"][1], {"type": "diffuse", "reflectance": rgb(fx["albedo"])}),
            "surround": plane([0.0, 0.0, 0.8], [0, 0, -1], 0.6, 0.6, {"type": "diffuse", "reflectance": rgb(fx["surround_albedo"])}),
        }
        # direct light only: no inter-reflection from the surround adds to the board's irradiance
        img = render(objects, [fx["light"]], cam, fx["spp"], 3, 2)
        file, clip, scale = finish(img, fx, rng, os.path.join(out, "board"))
        corners = [bc + n * 0 + sx * fx["board_half"][0] * unit(np.cross([0, -1, 0], n)) + sy * fx["board_half"][1] * unit(np.cross(n, np.cross([0, -1, 0], n)))
                   for sx in (-1, 1) for sy in (-1, 1)]
        board = {
            "normal_camera": list(n),
            "centre_camera_m": list(bc),
            "half_size_m": list(fx["board_half"]),
            "centre_px": list(project(bc, cam)),
            "corners_px": [list(project(c, cam)) for c in corners],
            "surround_albedo": fx["surround_albedo"],
        }
        if fx["light"]["kind"] == "point":
            # the irradiance over the board, for the record: centre (the truth) and mean
            pos = np.asarray(fx["light"]["pos"])
            e0 = np.asarray(fx["light"]["irradiance"])
            d0 = np.linalg.norm(pos - bc)
            vals = []
            for u in np.linspace(-1, 1, 41):
                for v in np.linspace(-1, 1, 41):
                    p = bc + u * fx["board_half"][0] * unit(np.cross([0, -1, 0], n)) + v * fx["board_half"][1] * unit(np.cross(n, np.cross([0, -1, 0], n)))
                    dl = pos - p
                    r = np.linalg.norm(dl)
                    vals.append((d0 / r) ** 2 * max(0.0, np.dot(dl / r, n)) / max(1e-9, np.dot(unit(pos - bc), n)))
            board["falloff_min_over_centre"] = float(min(vals))
            board["irradiance_board_mean_over_centre"] = float(np.mean(vals))
    truth = {
        "name": fx["name"],
        "kind": "white",
        "description": fx["description"],
        "renderer": "numpy (seeded uniform noise)" if fx.get("noise_only") else f"Mitsuba {mi.__version__} scalar_rgb, direct light only, box pixel filter",
        "board_image": file,
        "intrinsics": camera_truth(cam),
        **light_truth(fx["light"], fx["board_centre"]),
        "albedo": fx["albedo"],
        "board": board,
        "post": fx.get("post", {}),
        "format": fx["format"],
        "transfer": "srgb" if fx["format"] == "srgb8" else "linear",
        "scale": scale,
        "clip_level": clip,
        "unusable": fx["unusable"],
    }
    write_truth(out, truth)
    print(f"{fx['name']}: {time.time() - t0:.0f} s")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=DEFAULT_OUT)
    ap.add_argument("--only", action="append", help="render only this fixture (repeatable)")
    args = ap.parse_args()
    for fx in corpus():
        if args.only and fx["name"] not in args.only:
            continue
        out = os.path.join(args.out, fx["name"])
        if fx["kind"] == "sphere":
            write_sphere(fx, out)
        else:
            write_white(fx, out)


if __name__ == "__main__":
    sys.exit(main())
