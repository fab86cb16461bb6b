//! The observation stage at camera resolution (issue #14): the z-buffer sweep against the
//! ray caster it replaced, and the reduction of redundant pixels.

use crate::reconstruct::materials;
use crate::util;
use brdf_rig::geometry::bvh::Bvh;
use brdf_rig::geometry::curvature::principal_curvatures;
use brdf_rig::geometry::mesh_io::load_mesh;
use brdf_rig::geometry::raster::Rasteriser;
use brdf_rig::geometry::shadow::shadow_mask;
use brdf_rig::reconstruct::Settings;
use brdf_rig::reconstruct::observe::{ObserveSettings, SurfacePixel, ViewInput, observe_view};
use brdf_rig::reconstruct::prepare::{load_scene, observe_scene, prepare};
use brdf_rig::reconstruct::reduce::Reduction;
use brdf_rig::sim::job_scene::{SceneSpec, write_scene};
use std::collections::HashMap;

#[test]
fn sweep_matches_the_ray_cast_observations_up_to_edge_pixels() {
    let dir = tempfile::tempdir().unwrap();
    // the Spot at 160x120 from 3 views, lit from three sides (cast shadows on the ears)
    let mats = materials();
    let truth = &mats.iter().find(|(n, _)| n == "blue-acrylic").unwrap().1;
    let mesh = load_mesh(&util::shared_data().join("meshes/spot_triangulated.obj"))
        .unwrap()
        .0;
    let spec = SceneSpec {
        views: 3,
        width: 160,
        height: 120,
        ..SceneSpec::default()
    };
    let job = write_scene(dir.path(), &mesh, &mesh, truth, &spec).unwrap();
    let scene = load_scene(&job, &Settings::default()).unwrap();
    let full = ObserveSettings {
        reduce: None,
        ..Default::default()
    };
    // the reference: one BVH ray per pixel, a shadow ray per pixel, every pixel kept
    let bvh = Bvh::build(&scene.mesh);
    let curv = principal_curvatures(&scene.mesh).mean;
    let mut reference = HashMap::new();
    for v in &scene.views {
        let r = Rasteriser::new(&scene.mesh, &bvh, &v.intrinsics, &v.pose, Some(&curv));
        let g = r.gbuffer_ray_cast();
        let centre = v.pose.centre();
        let lit = shadow_mask(&scene.mesh, &bvh, &g, &centre, &v.light_world);
        let surface: Vec<SurfacePixel> = g
            .fragments()
            .iter()
            .zip(&lit)
            .enumerate()
            .filter_map(|(i, (f, l))| {
                let f = f.as_ref()?;
                Some(SurfacePixel {
                    x: (i % g.width()) as u32,
                    y: (i / g.width()) as u32,
                    position: f.position,
                    normal: f.normal,
                    mean_curvature: f.mean_curvature.unwrap(),
                    face: f.face,
                    lit: l.unwrap(),
                })
            })
            .collect();
        let input = ViewInput {
            image_index: v.index,
            image: v.image.as_ref().unwrap(),
            mask: None,
            camera_centre: centre,
            light_world: v.light_world,
            irradiance: v.irradiance,
        };
        for o in observe_view(&input, &surface, &full).0 {
            reference.insert((o.image, o.x, o.y), o);
        }
    }
    let swept = observe_scene(&scene, &full);
    let mut same = 0;
    for o in &swept.observations {
        let Some(r) = reference.get(&(o.image, o.x, o.y)) else {
            continue;
        };
        same += 1;
        assert_eq!(o.bin, r.bin);
        assert!((o.position - r.position).norm() < 1e-9 * scene.mesh.diagonal());
        assert!((o.normal - r.normal).norm() < 1e-9);
        assert!(
            (o.mean_curvature - r.mean_curvature).abs() < 1e-6 * r.mean_curvature.abs().max(1.0)
        );
        assert_eq!(o.reflectance, r.reflectance);
    }
    // the two disagree only on silhouette pixels: a handful of hundreds
    let (n_ref, n_new) = (reference.len(), swept.observations.len());
    assert!(n_ref > 2000, "{n_ref} reference observations");
    assert!(
        n_ref - same <= n_ref / 100 && n_new - same <= n_new / 100,
        "reference {n_ref}, sweep {n_new}, shared {same}"
    );
    // the drop counts add up to the covered pixels
    for c in &swept.images {
        assert_eq!(c.observed + c.dropped.total(), c.covered, "{c:?}");
    }

    // reduced to a budget: within it per image, every image kept, a subset of the full set
    let small = ObserveSettings {
        reduce: Some(Reduction {
            budget: 300,
            ..Default::default()
        }),
        ..Default::default()
    };
    let reduced = observe_scene(&scene, &small);
    for (c, f) in reduced.images.iter().zip(&swept.images) {
        assert!(
            c.observed <= 300 && c.observed >= f.observed.min(250),
            "{c:?}"
        );
        assert_eq!(c.covered, f.covered);
        assert_eq!(c.observed + c.dropped.total(), c.covered, "{c:?}");
    }
    let full_px: HashMap<_, _> = swept
        .observations
        .iter()
        .map(|o| ((o.image, o.x, o.y), o))
        .collect();
    for o in &reduced.observations {
        assert_eq!(full_px[&(o.image, o.x, o.y)], o);
    }
    // the default reduction leaves a small job as it is
    let default = observe_scene(&scene, &ObserveSettings::default());
    assert_eq!(default.observations, swept.observations);

    // streamed (images read one at a time, as `prepare` does) = held
    let prepared = prepare(&job, &Settings::default(), &mut |_| {}).unwrap();
    assert!(prepared.scene.views.iter().all(|v| v.image.is_none()));
    assert_eq!(prepared.observed.observations, default.observations);
}
