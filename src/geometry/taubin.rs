//! Taubin lambda|mu smoothing of a mesh's positions (Taubin 1995), with the uniform ("umbrella")
//! Laplacian: a low-pass filter that removes vertex-to-vertex noise without the shrinkage of
//! plain Laplacian smoothing. Two users: `sfm_like` rounds a true mesh off as photogrammetry
//! does, and the normal refinement denoises a photogrammetry mesh's normals before it starts
//! (`reconstruct::refine`, the smoothing chosen by held-out images).
//!
//! Pure: positions in, positions out; the topology is not changed.

use super::mesh::Mesh;
use nalgebra::{Point3, Vector3};

/// The usual pass band for photogrammetry noise: lambda 0.5, mu -0.53 (k_PB ~ 0.1).
pub const LAMBDA: f64 = 0.5;
pub const MU: f64 = -0.53;

/// Taubin-smooths the positions in place: `iterations` times a lambda step and a mu step, each
/// moving every vertex by the factor times (mean of its one-ring minus itself). Vertices without
/// neighbours stay.
pub fn taubin_smooth(mesh: &mut Mesh, iterations: usize, lambda: f64, mu: f64) {
    if iterations == 0 {
        return;
    }
    let nb = mesh.vertex_neighbours();
    let mut p: Vec<Point3<f64>> = mesh.positions().to_vec();
    for _ in 0..iterations {
        for factor in [lambda, mu] {
            let next: Vec<Point3<f64>> = p
                .iter()
                .enumerate()
                .map(|(i, pi)| {
                    if nb[i].is_empty() {
                        return *pi;
                    }
                    let mean: Vector3<f64> = nb[i]
                        .iter()
                        .map(|&j| p[j as usize].coords)
                        .sum::<Vector3<f64>>()
                        / nb[i].len() as f64;
                    pi + (mean - pi.coords) * factor
                })
                .collect();
            p = next;
        }
    }
    // finite in, finite out: a convex blend and a bounded extrapolation of finite points
    let _ = mesh.set_positions(p);
}

/// The mesh's vertex normals with the change that `iterations` Taubin steps of its positions
/// make to the normals of those positions (the mesh itself is not changed): where the normals
/// are the positions' own (every loaded mesh), the normals of the smoothed positions, so
/// vertex-to-vertex noise is filtered out; where normals were set otherwise (refined, or turned
/// by a test), that correction is added to them, not a replacement by the positions' normals.
pub fn smoothed_normals(mesh: &Mesh, iterations: usize) -> Vec<Vector3<f64>> {
    smoothed_normals_each(mesh, &[iterations])
        .pop()
        .unwrap_or_else(|| mesh.vertex_normals().to_vec())
}

/// [`smoothed_normals`] for each of `iterations`, in their order, smoothing once up to the
/// largest (the steps are shared).
pub fn smoothed_normals_each(mesh: &Mesh, iterations: &[usize]) -> Vec<Vec<Vector3<f64>>> {
    let own = mesh.vertex_normals();
    let mut m = mesh.clone();
    // the positions' own normals (a mesh's may have been replaced)
    let _ = m.set_positions(mesh.positions().to_vec());
    let raw = m.vertex_normals().to_vec();
    let mut order: Vec<usize> = (0..iterations.len()).collect();
    order.sort_by_key(|&i| iterations[i]);
    let mut out = vec![Vec::new(); iterations.len()];
    let mut done = 0;
    for i in order {
        let k = iterations[i];
        taubin_smooth(&mut m, k - done, LAMBDA, MU);
        done = k;
        out[i] = if k == 0 {
            own.to_vec()
        } else {
            own.iter()
                .zip(&raw)
                .zip(m.vertex_normals())
                .map(|((n, r), s)| {
                    if *n == Vector3::zeros() {
                        return *n;
                    }
                    (n + (s - r)).try_normalize(1e-12).unwrap_or(*n)
                })
                .collect()
        };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::uv_sphere;
    use rand::{Rng, SeedableRng};

    fn median_angle_to_radial(mesh: &Mesh, normals: &[Vector3<f64>]) -> f64 {
        let mut a: Vec<f64> = mesh
            .positions()
            .iter()
            .zip(normals)
            .map(|(p, n)| {
                let r = p.coords.normalize();
                r.cross(n).norm().atan2(r.dot(n)).to_degrees()
            })
            .collect();
        a.sort_by(f64::total_cmp);
        a[a.len() / 2]
    }

    #[test]
    fn smoothing_a_noisy_sphere_brings_its_normals_back_towards_the_radial_ones() {
        let sphere = uv_sphere(1.0, 24, 48).expect("valid sphere");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let noisy: Vec<Point3<f64>> = sphere
            .positions()
            .iter()
            .map(|p| p * (1.0 + 0.01 * (rng.r#gen::<f64>() - 0.5)))
            .collect();
        let mut mesh = sphere.clone();
        assert!(mesh.set_positions(noisy));
        let raw = median_angle_to_radial(&mesh, mesh.vertex_normals());
        let smooth = median_angle_to_radial(&mesh, &smoothed_normals(&mesh, 4));
        assert!(
            smooth < 0.6 * raw,
            "raw {raw:.3} deg, smoothed {smooth:.3} deg"
        );
        // the shared steps give what separate smoothings give
        let each = smoothed_normals_each(&mesh, &[4, 2]);
        assert_eq!(each[0], smoothed_normals(&mesh, 4));
        assert_eq!(each[1], smoothed_normals(&mesh, 2));
        // zero iterations: the mesh's own normals, and the mesh is never changed
        assert_eq!(smoothed_normals(&mesh, 0), mesh.vertex_normals().to_vec());
        let before = mesh.positions().to_vec();
        let _ = smoothed_normals(&mesh, 2);
        assert_eq!(mesh.positions(), &before[..]);
    }

    #[test]
    fn normals_set_apart_from_the_positions_keep_their_own_direction() {
        // exact sphere positions, normals turned by hand: smoothing the positions changes
        // little, so the turned normals stay turned (not replaced by the positions' normals)
        let mut mesh = uv_sphere(1.0, 16, 32).expect("valid sphere");
        let turned: Vec<Vector3<f64>> = mesh
            .vertex_normals()
            .iter()
            .map(|n| (n + Vector3::new(0.1, 0.0, 0.0)).normalize())
            .collect();
        assert!(mesh.set_vertex_normals(turned.clone()));
        let s = smoothed_normals(&mesh, 4);
        let moved = s
            .iter()
            .zip(&turned)
            .map(|(a, b)| a.cross(b).norm().atan2(a.dot(b)).to_degrees())
            .fold(0.0f64, f64::max);
        assert!(
            moved < 1.0,
            "the turned normals moved by up to {moved:.2} deg"
        );
    }

    #[test]
    fn taubin_steps_keep_a_sphere_s_size() {
        // lambda|mu is a low-pass filter without the shrinkage of plain Laplacian smoothing
        let mut mesh = uv_sphere(1.0, 16, 32).expect("valid sphere");
        taubin_smooth(&mut mesh, 10, LAMBDA, MU);
        let mean_r = mesh
            .positions()
            .iter()
            .map(|p| p.coords.norm())
            .sum::<f64>()
            / mesh.positions().len() as f64;
        assert!((mean_r - 1.0).abs() < 0.02, "mean radius {mean_r}");
    }
}
