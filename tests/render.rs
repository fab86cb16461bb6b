//! Rendering against closed forms: Lambertian radiance `albedo / pi * E * cos`, the apparent
//! size of a sphere and a board, shadows, the uniform environment, and the BRDF frame.

use crate::geometry::{grid, uv_sphere};
use brdf_rig::brdf::Brdf;
use brdf_rig::geometry::bvh::Bvh;
use brdf_rig::geometry::camera::{Intrinsics, Pose};
use brdf_rig::geometry::mesh::Mesh;
use brdf_rig::geometry::raster::{Rasteriser, rasterise};
use brdf_rig::render::board::{Board, render_board};
use brdf_rig::render::light::{DirectionalLight, UniformEnvironment};
use brdf_rig::render::raytraced::{SceneObject, render_analytic};
use brdf_rig::render::shade::{ShadeOptions, render_mesh, shade, shade_fragment};
use brdf_rig::render::sphere::{Sphere, render_sphere};
use nalgebra::{Point3, Vector3};
use std::f64::consts::PI;

/// Lambertian BRDF `albedo / pi` (the simulator's).
use brdf_rig::sim::imaging::Lambertian as Lambert;

/// A probe "BRDF" that reports the local cosines it was given, to check the shading frame:
/// R = cos(theta_o), G = 1, B = |wi x wo| (the sine of the angle between them).
struct Probe;

impl Brdf for Probe {
    fn eval_local(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
        [wo.z, 1.0, wi.cross(wo).norm()]
    }
}

/// A mirror-like Phong lobe: f = (n+2)/(2 pi) (r . wo)^n, r = wi mirrored about +z.
struct Phong(f64);

impl Brdf for Phong {
    fn eval_local(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        let r = Vector3::new(-wi.x, -wi.y, wi.z);
        let v = (self.0 + 2.0) / (2.0 * PI) * r.dot(wo).max(0.0).powf(self.0);
        [v; 3]
    }
}

const E: [f64; 3] = [2.0, 3.0, 4.0];

fn camera(eye: Point3<f64>, target: Point3<f64>) -> (Intrinsics, Pose) {
    (
        Intrinsics::pinhole(96, 72, 90.0, 90.0, 48.0, 36.0),
        Pose::look_at(eye, target, Vector3::y()),
    )
}

#[test]
fn lambertian_sphere_radiance_is_albedo_over_pi_e_cos_and_its_outline_is_exact() {
    let sphere = Sphere {
        centre: Point3::new(0.2, -0.1, 0.0),
        radius: 0.5,
    };
    let eye = Point3::new(0.2, -0.1, 4.0);
    let (k, pose) = camera(eye, sphere.centre);
    let light = DirectionalLight::new(Vector3::new(0.3, 0.4, 1.0), E).unwrap();
    let albedo = [0.8, 0.5, 0.2];
    let img = render_sphere(&sphere, &Lambert(albedo), &light, &k, &pose, [-1.0; 3]);
    // outline: a pixel centre is covered iff its ray's angle to the axis < asin(r / d)
    let half_angle = (0.5f64 / 4.0).asin();
    let mut covered = 0;
    for y in 0..72 {
        for x in 0..96 {
            let ray = k.ray(x as f64 + 0.5, y as f64 + 0.5);
            let angle = ray.z.clamp(-1.0, 1.0).acos();
            let rgb = img.get(x, y);
            if (angle - half_angle).abs() < 1e-3 {
                continue; // on the outline, to within rounding
            }
            if angle > half_angle {
                assert_eq!(rgb, [-1.0; 3], "background at {x},{y}");
                continue;
            }
            covered += 1;
            // closed form: the visible point's normal from the law of sines on the triangle
            // (eye, centre, point): distance along the ray t = d cos a - sqrt(r^2 - d^2 sin^2 a)
            let d = 4.0;
            let t = d * angle.cos() - (0.25 - d * d * angle.sin().powi(2)).sqrt();
            let p = eye + pose.dir_to_world(&ray) * t;
            let n = (p - sphere.centre) / 0.5;
            let cos = n.dot(&light.to_light).max(0.0);
            for c in 0..3 {
                let want = albedo[c] / PI * E[c] * cos;
                assert!(
                    (rgb[c] as f64 - want).abs() < 1e-5 * E[c],
                    "{x},{y} c{c}: {} vs {want}",
                    rgb[c]
                );
            }
        }
    }
    // the disk's area in pixels: pi (f tan a)^2
    let area = PI * (90.0 * half_angle.tan()).powi(2);
    assert!(
        (covered as f64 - area).abs() < 0.05 * area,
        "{covered} vs {area}"
    );
}

#[test]
fn tessellated_sphere_shading_agrees_with_the_analytic_sphere() {
    // second implementation: mesh raster + shade against ray-sphere, Lambertian and glossy
    let mesh = uv_sphere(0.5, 48, 96);
    let bvh = Bvh::build(&mesh);
    let sphere = Sphere {
        centre: Point3::origin(),
        radius: 0.5,
    };
    let (k, pose) = camera(Point3::new(0.0, 1.0, 3.5), Point3::origin());
    let light = DirectionalLight::new(Vector3::new(-0.2, 0.6, 1.0), E).unwrap();
    for brdf in [&Lambert([0.7; 3]) as &dyn Brdf, &Phong(30.0)] {
        let a = render_sphere(&sphere, brdf, &light, &k, &pose, [0.0; 3]);
        let b = render_mesh(
            &mesh,
            &bvh,
            &k,
            &pose,
            brdf,
            &ShadeOptions::single_light(light),
        );
        let (mut diff, mut norm) = (0.0, 0.0);
        for (x, y) in a.data().iter().zip(b.data()) {
            diff += ((x - y) as f64).powi(2);
            norm += (*x as f64).powi(2);
        }
        let rel = (diff / norm).sqrt();
        // tessellation moves the outline by under a pixel and bends normals by < 1 degree
        assert!(rel < 0.08, "relative L2 difference {rel}");
    }
}

#[test]
fn lit_plane_shadow_and_background_follow_the_closed_form() {
    // floor [-2, 2]^2 facing +z plus a raised occluder; light at 60 degrees from the normal
    let (mut p, mut f) = grid(-2.0, 2.0, -2.0, 2.0, 0.0, 6);
    let (p2, f2) = grid(-0.4, 0.4, -0.4, 0.4, 0.8, 1);
    let base = p.len() as i64;
    p.extend(p2);
    f.extend(f2.into_iter().map(|t| t.map(|i| i + base)));
    let (mesh, _) = Mesh::new(p, f, "<floor>").unwrap();
    let bvh = Bvh::build(&mesh);
    let eye = Point3::new(0.0, -3.0, 3.5);
    let (k, pose) = camera(eye, Point3::origin());
    let theta = 60f64.to_radians();
    let light = DirectionalLight::new(Vector3::new(theta.sin(), 0.0, theta.cos()), E).unwrap();
    let mut opts = ShadeOptions::single_light(light);
    opts.background = [0.25, 0.5, 0.75];
    let albedo = [0.9, 0.6, 0.3];
    let g = rasterise(&mesh, &bvh, &k, &pose, None);
    let img = shade(&mesh, &bvh, &g, &pose.centre(), &Lambert(albedo), &opts);
    let (mut lit, mut dark) = (0, 0);
    for y in 0..72 {
        for x in 0..96 {
            let rgb = img.get(x, y);
            let Some(fr) = g.get(x, y) else {
                assert_eq!(rgb, [0.25, 0.5, 0.75]);
                continue;
            };
            let q = fr.position;
            if q.z > 0.4 {
                continue;
            }
            // the occluder's shadow on the floor: the square shifted by -0.8 tan(theta) in x
            let sx = q.x + 0.8 * theta.tan();
            let margin = (sx.abs().max(q.y.abs()) - 0.4).abs();
            if margin < 0.03 {
                continue;
            }
            let shadowed = sx.abs() < 0.4 && q.y.abs() < 0.4;
            for c in 0..3 {
                let want = if shadowed {
                    0.0
                } else {
                    albedo[c] / PI * E[c] * theta.cos()
                };
                assert!((rgb[c] as f64 - want).abs() < 1e-5, "{x},{y}: {rgb:?}");
            }
            if shadowed { dark += 1 } else { lit += 1 }
        }
    }
    assert!(lit > 500 && dark > 10, "lit {lit} dark {dark}");
    // without cast shadows the shadowed pixels light up, nothing else changes
    opts.shadows = false;
    let open = shade(&mesh, &bvh, &g, &pose.centre(), &Lambert(albedo), &opts);
    let brighter = img
        .data()
        .iter()
        .zip(open.data())
        .filter(|(a, b)| b > a)
        .count();
    assert!(brighter >= 3 * dark);
}

#[test]
fn shading_frame_gives_the_brdf_the_true_view_and_light_cosines() {
    let (p, f) = grid(-1.0, 1.0, -1.0, 1.0, 0.0, 2);
    let (mesh, _) = Mesh::new(p, f, "<plane>").unwrap();
    let bvh = Bvh::build(&mesh);
    let eye = Point3::new(0.5, -2.0, 2.0);
    let (k, pose) = camera(eye, Point3::origin());
    let l = Vector3::new(0.3, 0.5, 0.8).normalize();
    let light = DirectionalLight::new(l, [1.0; 3]).unwrap();
    let g = rasterise(&mesh, &bvh, &k, &pose, None);
    let img = shade(
        &mesh,
        &bvh,
        &g,
        &eye,
        &Probe,
        &ShadeOptions::single_light(light),
    );
    let mut n = 0;
    for y in 0..72 {
        for x in 0..96 {
            let Some(fr) = g.get(x, y) else { continue };
            n += 1;
            let v = (eye - fr.position).normalize();
            let rgb = img.get(x, y);
            // L = f * E * cos_i, and the probe's G channel is 1, so G = n . l
            assert!((rgb[1] as f64 - l.z).abs() < 1e-6);
            assert!((rgb[0] as f64 / l.z - v.z).abs() < 1e-6);
            assert!((rgb[2] as f64 / l.z - l.cross(&v).norm()).abs() < 1e-6);
        }
    }
    assert!(n > 1000);
    // the per-pixel kernel gives what the image holds, for a pixel asked on its own
    let f = Rasteriser::new(&mesh, &bvh, &k, &pose, None)
        .fragment(40.5, 30.5)
        .unwrap();
    let opts = ShadeOptions::single_light(light);
    let one = shade_fragment(&mesh, &bvh, &f, &eye, &Probe, &opts, 0);
    assert_eq!(one.map(|v| v as f32), img.get(40, 30));
}

#[test]
fn uniform_environment_gives_albedo_times_radiance_on_a_lambertian_sphere() {
    let mesh = uv_sphere(0.5, 24, 48);
    let bvh = Bvh::build(&mesh);
    let (k, pose) = camera(Point3::new(0.0, 0.0, 3.0), Point3::origin());
    let env = UniformEnvironment {
        radiance: [1.5, 1.0, 0.5],
        samples: 9,
        occlusion: false,
        seed: 1,
    };
    let opts = ShadeOptions {
        light: None,
        environment: Some(env),
        shadows: true,
        background: [0.0; 3],
    };
    let albedo = [0.6, 0.4, 0.2];
    let img = render_mesh(&mesh, &bvh, &k, &pose, &Lambert(albedo), &opts);
    let g = rasterise(&mesh, &bvh, &k, &pose, None);
    let mut n = 0;
    for y in 0..72 {
        for x in 0..96 {
            let Some(fr) = g.get(x, y) else { continue };
            // pixels whose interpolated normal faces away from the camera render black
            if fr.normal.dot(&(pose.centre() - fr.position)) <= 0.0 {
                continue;
            }
            n += 1;
            let rgb = img.get(x, y);
            for c in 0..3 {
                assert!((rgb[c] as f64 - albedo[c] * env.radiance[c]).abs() < 1e-6);
            }
        }
    }
    assert!(n > 300);
    // with occlusion, a convex sphere sees its whole hemisphere: the same image on average
    // (samples grazing the tessellated surface can hit a neighbouring face, so not per pixel)
    let mut occ = opts;
    occ.environment = Some(UniformEnvironment {
        occlusion: true,
        ..env
    });
    let img2 = render_mesh(&mesh, &bvh, &k, &pose, &Lambert(albedo), &occ);
    let (s1, s2): (f64, f64) = (
        img.data().iter().map(|v| *v as f64).sum(),
        img2.data().iter().map(|v| *v as f64).sum(),
    );
    assert!(s2 <= s1 && s2 > 0.97 * s1, "{s2} vs {s1}");
}

/// Form factor from a differential area to a parallel rectangle of sides `a`, `b` at height
/// `c` with one corner straight above it (Howell's catalogue, configuration B-3).
fn corner_form_factor(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * PI)
}

#[test]
fn ambient_occlusion_under_a_square_matches_the_form_factor() {
    // floor point under a square roof [-0.4, 0.4]^2 at height 0.8: the roof hides the fraction
    // F of the cosine-weighted hemisphere, so L = albedo * L_env * (1 - F)
    let (mut p, mut f) = grid(-3.0, 3.0, -3.0, 3.0, 0.0, 4);
    let (p2, f2) = grid(-0.4, 0.4, -0.4, 0.4, 0.8, 1);
    let base = p.len() as i64;
    p.extend(p2);
    f.extend(f2.into_iter().map(|t| t.map(|i| i + base)));
    let (mesh, _) = Mesh::new(p, f, "<roof>").unwrap();
    let bvh = Bvh::build(&mesh);
    let k = Intrinsics::pinhole(8, 6, 800.0, 800.0, 4.0, 3.0);
    let pose = Pose::look_at(Point3::new(4.0, 0.0, 0.5), Point3::origin(), Vector3::z());
    let env = UniformEnvironment {
        radiance: [1.0; 3],
        samples: 4096,
        occlusion: true,
        seed: 3,
    };
    let opts = ShadeOptions {
        light: None,
        environment: Some(env),
        shadows: true,
        background: [0.0; 3],
    };
    let g = rasterise(&mesh, &bvh, &k, &pose, None);
    let img = shade(&mesh, &bvh, &g, &pose.centre(), &Lambert([0.5; 3]), &opts);
    let (mut n, mut mean_rel) = (0, 0.0);
    for y in 0..6 {
        for x in 0..8 {
            let fr = g.get(x, y).unwrap();
            let q = fr.position;
            // the grazing view stretches pixels along x: every one still lands under the roof
            assert!(
                q.z.abs() < 1e-9 && q.x.abs() < 0.35 && q.y.abs() < 0.05,
                "{q:?}"
            );
            let ff: f64 = [
                (0.4 - q.x, 0.4 - q.y),
                (q.x + 0.4, 0.4 - q.y),
                (0.4 - q.x, q.y + 0.4),
                (q.x + 0.4, q.y + 0.4),
            ]
            .iter()
            .map(|&(a, b)| corner_form_factor(a, b, 0.8))
            .sum();
            let want = 0.5 * (1.0 - ff);
            let got = img.get(x, y)[0] as f64;
            // 64 x 64 jittered strata: only the ~100 strata the roof's outline cuts add noise,
            // a few tenths of a percent per pixel; over the pixels it averages out (no bias)
            assert!(
                (got - want).abs() < 0.01 * want,
                "{x},{y}: {got} vs {want} (F = {ff})"
            );
            mean_rel += (got / want - 1.0) / 48.0;
            n += 1;
        }
    }
    assert_eq!(n, 48);
    assert!(mean_rel.abs() < 0.002, "mean relative error {mean_rel}");
}

#[test]
fn board_is_uniformly_lit_and_covers_its_projection() {
    let board = Board {
        centre: Point3::origin(),
        half_u: Vector3::new(0.5, 0.0, 0.0),
        half_v: Vector3::new(0.0, 0.3, 0.0),
    };
    let (k, pose) = camera(Point3::new(0.0, 0.0, 3.0), Point3::origin());
    let l = Vector3::new(0.0, 0.6, 0.8);
    let light = DirectionalLight::new(l, E).unwrap();
    let img = render_board(&board, &Lambert([0.99; 3]), &light, &k, &pose, [0.0; 3]);
    let (mut n, hw, hh) = (0, 90.0 * 0.5 / 3.0, 90.0 * 0.3 / 3.0);
    for y in 0..72 {
        for x in 0..96 {
            let (dx, dy) = ((x as f64 + 0.5 - 48.0).abs(), (y as f64 + 0.5 - 36.0).abs());
            if (dx - hw).abs() < 1e-6 || (dy - hh).abs() < 1e-6 {
                continue;
            }
            let rgb = img.get(x, y);
            if dx < hw && dy < hh {
                n += 1;
                for c in 0..3 {
                    assert!((rgb[c] as f64 - 0.99 / PI * E[c] * 0.8).abs() < 1e-5);
                }
            } else {
                assert_eq!(rgb, [0.0; 3]);
            }
        }
    }
    assert_eq!(n, 30 * 18);
    // seen from behind, the one-sided board vanishes
    let (_, back) = camera(Point3::new(0.0, 0.0, -3.0), Point3::origin());
    let img = render_board(&board, &Lambert([0.99; 3]), &light, &k, &back, [0.0; 3]);
    assert!(img.data().iter().all(|v| *v == 0.0));
}

#[test]
fn sphere_casts_a_shadow_on_the_board_in_an_analytic_scene() {
    let board = Board {
        centre: Point3::origin(),
        half_u: Vector3::new(2.0, 0.0, 0.0),
        half_v: Vector3::new(0.0, 2.0, 0.0),
    };
    let sphere = Sphere {
        centre: Point3::new(0.0, 0.0, 1.0),
        radius: 0.3,
    };
    let (k, pose) = camera(Point3::new(0.0, -1.0, 5.0), Point3::origin());
    let light = DirectionalLight::new(Vector3::z(), E).unwrap();
    let white = Lambert([1.0; 3]);
    let black = Phong(200.0);
    let objs = [
        SceneObject {
            shape: &board,
            brdf: &white,
            coat_f0: None,
        },
        SceneObject {
            shape: &sphere,
            brdf: &black,
            coat_f0: None,
        },
    ];
    let img = render_analytic(&objs, &light, &k, &pose, [0.0; 3]);
    // light straight down: the sphere's shadow is the disk of radius 0.3 about the origin;
    // both floor points project outside the sphere's silhouette from this camera
    for (q, lit) in [
        (Point3::new(0.6, 0.0, 0.0), true),
        (Point3::new(0.2, 0.1, 0.0), false),
    ] {
        let (px, py) = k.project(&pose.camera_from_world(&q)).unwrap();
        let rgb = img.get(px as usize, py as usize);
        let want = if lit { E[0] / PI } else { 0.0 };
        assert!((rgb[0] as f64 - want).abs() < 1e-5, "{q:?}: {rgb:?}");
    }
}
