//! Pinhole camera intrinsics and poses.
//!
//! Conventions (COLMAP's): camera axes x right, y down, z forward; a world point `p_world` maps to
//! `p_cam = R * p_world + t` (`camera_from_world`), then to pixel `(fx * x/z + cx, fy * y/z + cy)`
//! where pixel centres sit at half-integers (pixel (0,0) centre is (0.5, 0.5)), as COLMAP.
//! Pure: no I/O.

use nalgebra::{Matrix3, Point3, UnitQuaternion, Vector3};

/// Pinhole intrinsics in pixels, with optional radial distortion (k1, k2) and tangential (p1, p2),
/// following COLMAP's OPENCV model; zero distortion is the PINHOLE model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    pub width: usize,
    pub height: usize,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
}

impl Intrinsics {
    /// An undistorted pinhole camera.
    pub fn pinhole(width: usize, height: usize, fx: f64, fy: f64, cx: f64, cy: f64) -> Self {
        Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            k1: 0.0,
            k2: 0.0,
            p1: 0.0,
            p2: 0.0,
        }
    }

    pub fn has_distortion(&self) -> bool {
        self.k1 != 0.0 || self.k2 != 0.0 || self.p1 != 0.0 || self.p2 != 0.0
    }

    /// Applies the OPENCV distortion to normalised coordinates `(x/z, y/z)`.
    pub fn distort(&self, u: f64, v: f64) -> (f64, f64) {
        let r2 = u * u + v * v;
        let radial = 1.0 + self.k1 * r2 + self.k2 * r2 * r2;
        let du = 2.0 * self.p1 * u * v + self.p2 * (r2 + 2.0 * u * u);
        let dv = self.p1 * (r2 + 2.0 * v * v) + 2.0 * self.p2 * u * v;
        (u * radial + du, v * radial + dv)
    }

    /// Inverts [`Self::distort`] by fixed-point iteration (converges for the mild distortion of
    /// real lenses; exact when there is none).
    pub fn undistort(&self, ud: f64, vd: f64) -> (f64, f64) {
        if !self.has_distortion() {
            return (ud, vd);
        }
        let (mut u, mut v) = (ud, vd);
        for _ in 0..20 {
            let (du, dv) = self.distort(u, v);
            u += ud - du;
            v += vd - dv;
        }
        (u, v)
    }

    /// Projects a point in camera coordinates to a pixel; `None` behind the camera.
    pub fn project(&self, p_cam: &Vector3<f64>) -> Option<(f64, f64)> {
        if p_cam.z <= 1e-12 {
            return None;
        }
        let (u, v) = self.distort(p_cam.x / p_cam.z, p_cam.y / p_cam.z);
        Some((self.fx * u + self.cx, self.fy * v + self.cy))
    }

    /// The unit ray direction (camera coordinates) through pixel position `(px, py)`.
    pub fn ray(&self, px: f64, py: f64) -> Vector3<f64> {
        let (u, v) = self.undistort((px - self.cx) / self.fx, (py - self.cy) / self.fy);
        Vector3::new(u, v, 1.0).normalize()
    }
}

/// A camera pose: `camera_from_world` rotation and translation (COLMAP's `R, t`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    pub rotation: UnitQuaternion<f64>,
    pub translation: Vector3<f64>,
}

impl Pose {
    pub fn identity() -> Self {
        Self {
            rotation: UnitQuaternion::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// A camera at `eye` looking at `target`, with image-up close to `up` (world axes).
    pub fn look_at(eye: Point3<f64>, target: Point3<f64>, up: Vector3<f64>) -> Self {
        let z = (target - eye).normalize();
        let x = z.cross(&up).normalize(); // right-handed, with y pointing down in the image
        let y = z.cross(&x);
        let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
        let rotation =
            UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(r));
        let translation = -(rotation * eye.coords);
        Self {
            rotation,
            translation,
        }
    }

    pub fn camera_from_world(&self, p_world: &Point3<f64>) -> Vector3<f64> {
        self.rotation * p_world.coords + self.translation
    }

    /// Rotates a direction from world to camera axes.
    pub fn dir_to_camera(&self, d_world: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * d_world
    }

    /// Rotates a direction from camera to world axes.
    pub fn dir_to_world(&self, d_cam: &Vector3<f64>) -> Vector3<f64> {
        self.rotation.inverse() * d_cam
    }

    /// The camera centre in world coordinates.
    pub fn centre(&self) -> Point3<f64> {
        Point3::from(-(self.rotation.inverse() * self.translation))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn look_at_puts_target_on_the_optical_axis() {
        let eye = Point3::new(1.0, 2.0, 3.0);
        let pose = Pose::look_at(eye, Point3::origin(), Vector3::z());
        let p = pose.camera_from_world(&Point3::origin());
        assert!(p.x.abs() < 1e-12 && p.y.abs() < 1e-12);
        assert!((p.z - eye.coords.norm()).abs() < 1e-12);
        assert!((pose.centre() - eye).norm() < 1e-12);
        // world up appears as image up (negative y)
        let up = pose.dir_to_camera(&Vector3::z());
        assert!(up.y < 0.0);
    }

    #[test]
    fn distortion_round_trip_and_ray_projection() {
        let mut k = Intrinsics::pinhole(640, 480, 500.0, 510.0, 320.0, 240.0);
        k.k1 = -0.1;
        k.k2 = 0.02;
        k.p1 = 0.001;
        let (u, v) = k.undistort(0.3, -0.2);
        let (ud, vd) = k.distort(u, v);
        assert!((ud - 0.3).abs() < 1e-10 && (vd + 0.2).abs() < 1e-10);
        let ray = k.ray(100.0, 50.0);
        let (px, py) = k.project(&(ray * 7.0)).unwrap();
        assert!((px - 100.0).abs() < 1e-8 && (py - 50.0).abs() < 1e-8);
    }
}
