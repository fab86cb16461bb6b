//! Pinhole camera intrinsics and poses.
//!
//! Conventions (COLMAP's): camera axes x right, y down, z forward; a world point `p_world` maps to
//! `p_cam = R * p_world + t` (`camera_from_world`), then to pixel `(fx * x/z + cx, fy * y/z + cy)`
//! where pixel centres sit at half-integers (pixel (0,0) centre is (0.5, 0.5)), as COLMAP.
//! Pure: no I/O.

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};

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

    /// The same camera for an image resampled by `scale` (0.5: half width and height). With
    /// pixel centres at half-integers and the origin at the image corner, image coordinates
    /// scale exactly: focal lengths and principal point multiply by `scale`; distortion, which
    /// acts on normalised coordinates, is unchanged. The size is rounded to whole pixels.
    pub fn scaled(&self, scale: f64) -> Self {
        Self {
            width: (self.width as f64 * scale).round() as usize,
            height: (self.height as f64 * scale).round() as usize,
            fx: self.fx * scale,
            fy: self.fy * scale,
            cx: self.cx * scale,
            cy: self.cy * scale,
            ..*self
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

    /// The pose as an isometry `camera_from_world`, to compose with other transforms: for an
    /// object turned by a turntable, `camera_from_object = camera_from_world * world_from_object`.
    pub fn to_isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::from(self.translation), self.rotation)
    }

    /// The pose of an isometry read as `camera_from_world`.
    pub fn from_isometry(camera_from_world: &Isometry3<f64>) -> Self {
        Self {
            rotation: camera_from_world.rotation,
            translation: camera_from_world.translation.vector,
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
    fn isometry_composition_moves_the_object_not_the_camera() {
        let pose = Pose::look_at(Point3::new(0.0, -3.0, 1.0), Point3::origin(), Vector3::z());
        assert_eq!(Pose::from_isometry(&pose.to_isometry()), pose);
        // turn the object 90 degrees about z: its point (1, 0, 0) now sits at world (0, 1, 0)
        let world_from_object = Isometry3::rotation(Vector3::z() * std::f64::consts::FRAC_PI_2);
        let cam_from_obj = Pose::from_isometry(&(pose.to_isometry() * world_from_object));
        let a = cam_from_obj.camera_from_world(&Point3::new(1.0, 0.0, 0.0));
        let b = pose.camera_from_world(&Point3::new(0.0, 1.0, 0.0));
        assert!((a - b).norm() < 1e-12);
    }

    #[test]
    fn scaled_camera_projects_to_scaled_image_coordinates() {
        let mut k = Intrinsics::pinhole(640, 480, 500.0, 510.0, 321.0, 239.0);
        k.k1 = -0.05;
        let h = k.scaled(0.25);
        assert_eq!((h.width, h.height), (160, 120));
        let p = Vector3::new(0.3, -0.2, 2.0);
        let (a, b) = (k.project(&p).unwrap(), h.project(&p).unwrap());
        assert!((b.0 - a.0 * 0.25).abs() < 1e-12 && (b.1 - a.1 * 0.25).abs() < 1e-12);
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
