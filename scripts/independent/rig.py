"""The turntable rig of the independent scenes: camera poses on a ring, light directions fixed in
camera axes, and the COLMAP text model and brdf-rig job files that describe them.

Conventions (COLMAP's, and brdf-rig's job format, docs/reconstruction.md): camera axes x right,
y down, z forward; a pose is `camera_from_world`: p_cam = R p_world + t, written as the Hamilton
quaternion (QW QX QY QZ) of R and TX TY TZ; pixel (i, j) covers [i, i+1] x [j, j+1] with its
centre at (i + 0.5, j + 0.5), the principal point of a centred camera is (W/2, H/2).
`light_dir_camera` is the unit vector from the surface towards the light, in camera axes.
World up is +y (both meshes stand on y). On a turntable the object turns under a fixed camera and
light; in the object frame, which is the world here, the camera circles the object and the light
circles with it, fixed in camera axes.
"""

import numpy as np

from .meshes import write_atomic

# Light directions in camera axes, as (angle from the direction towards the camera, azimuth in
# the image plane from +x (right) towards +y (down)), degrees, and irradiance (RGB, in the image
# unit: a white Lambertian of albedo a facing the light has radiance a E / pi). The irradiances
# differ per light and per channel on purpose: a reconstruction that mixes up lights or
# channels shows it.
RIGS = {
    "1light": [
        dict(angle_deg=20.0, azimuth_deg=-45.0, irradiance=[2.4, 2.2, 1.9]),
    ],
    "3lights": [
        dict(angle_deg=20.0, azimuth_deg=-45.0, irradiance=[2.4, 2.2, 1.9]),
        dict(angle_deg=55.0, azimuth_deg=-160.0, irradiance=[2.0, 2.1, 2.3]),
        dict(angle_deg=90.0, azimuth_deg=-20.0, irradiance=[2.6, 2.6, 2.6]),
    ],
}


def light_dir_camera(angle_deg, azimuth_deg):
    """Unit vector towards the light, camera axes: `angle_deg` away from -z (the direction from
    the object to the camera), tilted towards image azimuth `azimuth_deg`."""
    a, b = np.radians(angle_deg), np.radians(azimuth_deg)
    return np.array([np.sin(a) * np.cos(b), np.sin(a) * np.sin(b), -np.cos(a)])


def look_at(eye, target, up):
    """`camera_from_world` (R, t) of a camera at `eye` looking at `target`, image-up near `up`."""
    z = target - eye
    z = z / np.linalg.norm(z)
    x = np.cross(z, up)
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    r = np.stack([x, y, z])  # rows: camera axes in world coordinates
    return r, -r @ eye


def quaternion(r):
    """Hamilton quaternion (w, x, y, z), w >= 0, of a rotation matrix (Shepperd's method)."""
    tr = np.trace(r)
    if tr > 0:
        s = 2.0 * np.sqrt(1.0 + tr)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
        s = 2.0 * np.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        q = [(r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s]
    elif r[1, 1] > r[2, 2]:
        s = 2.0 * np.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
        q = [(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
        q = [(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def rotation(q):
    """Rotation matrix of a Hamilton quaternion (w, x, y, z): the inverse of `quaternion`."""
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


class Camera:
    """A centred pinhole camera with square pixels."""

    def __init__(self, width, height, fov_x_deg):
        self.width, self.height = width, height
        self.fov_x_deg = fov_x_deg
        self.f = 0.5 * width / np.tan(0.5 * np.radians(fov_x_deg))
        self.cx, self.cy = 0.5 * width, 0.5 * height

    def ray_camera(self, px, py):
        """Unit ray directions (camera axes) through image positions (px, py) (pixel units)."""
        d = np.stack([(px - self.cx) / self.f, (py - self.cy) / self.f, np.ones_like(px)], axis=-1)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def fov_y_rad(self):
        return 2.0 * np.arctan(0.5 * self.height / self.f)


def ring(vertices, camera, views, elevation_deg, rig, azimuth0_deg=0.0, margin=1.1):
    """Views on a turntable ring around the object's bounding-box centre, far enough that the
    bounding sphere fits the smaller field of view with `margin`. View k is lit by light
    k mod (number of lights)."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = float(np.linalg.norm(vertices - centre, axis=1).max())
    half_fov = 0.5 * min(np.radians(camera.fov_x_deg), camera.fov_y_rad())
    dist = margin * radius / np.sin(half_fov)
    lights = RIGS[rig]
    out = []
    for k in range(views):
        az = np.radians(azimuth0_deg + 360.0 * k / views)
        el = np.radians(elevation_deg)
        eye = centre + dist * np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
        r, t = look_at(eye, centre, np.array([0.0, 1.0, 0.0]))
        li = k % len(lights)
        l_cam = light_dir_camera(lights[li]["angle_deg"], lights[li]["azimuth_deg"])
        out.append(dict(name=f"view_{k:02d}.exr", index=k, azimuth_deg=float(np.degrees(az)),
                        R=r, t=t, eye=eye, light=li, light_dir_camera=l_cam,
                        light_dir_world=r.T @ l_cam, irradiance=lights[li]["irradiance"]))
    return out, dict(centre=centre.tolist(), bounding_radius=radius, distance=dist,
                     elevation_deg=elevation_deg)


def write_colmap(folder, camera, views):
    """`cameras.txt` (one PINHOLE camera), `images.txt` (no 2D points), empty `points3D.txt`."""
    cams = ("# Camera list with one line of data per camera:\n"
            "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n# Number of cameras: 1\n"
            f"1 PINHOLE {camera.width} {camera.height} {float(camera.f)!r} {float(camera.f)!r} "
            f"{float(camera.cx)!r} {float(camera.cy)!r}\n")
    imgs = ["# Image list with two lines of data per image:",
            "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
            "#   POINTS2D[] as (X, Y, POINT3D_ID)",
            f"# Number of images: {len(views)}, mean observations per image: 0"]
    for v in views:
        q = quaternion(v["R"])
        nums = " ".join(repr(float(x)) for x in (*q, *v["t"]))
        imgs += [f"{v['index'] + 1} {nums} 1 {v['name']}", ""]
    pts = ("# 3D point list with one line of data per point:\n"
           "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
           "# Number of points: 0, mean track length: 0\n")
    for name, text in (("cameras.txt", cams), ("images.txt", "\n".join(imgs) + "\n"),
                       ("points3D.txt", pts)):
        write_atomic(f"{folder}/{name}", text.encode("utf-8"))


def job_text(mesh, cameras, image_dir, views, comment):
    """A brdf-rig job (docs/reconstruction.md), paths relative to the job's folder."""
    lines = [f"# {line}" for line in comment.splitlines()]
    lines += [f'mesh = "{mesh}"', f'cameras = "{cameras}"']
    for v in views:
        d = ", ".join(repr(float(x)) for x in v["light_dir_camera"])
        e = ", ".join(repr(float(x)) for x in v["irradiance"])
        lines += ["", "[[light_image]]", f'file = "{image_dir}/{v["name"]}"',
                  f'camera = "{v["name"]}"', f"light_dir_camera = [{d}]", f"irradiance = [{e}]"]
    return "\n".join(lines) + "\n"
