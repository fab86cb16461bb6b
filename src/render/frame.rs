//! The local shading frame of the `Brdf` trait at a surface point: normal = +z, an arbitrary
//! tangent (the BRDFs here are isotropic, so its choice does not change the value).
//!
//! The tangent comes from Duff et al., "Building an Orthonormal Basis, Revisited" (JCGT 2017):
//! continuous except across n.z = 0's sign flip, no branches on a threshold. Pure.

use nalgebra::Vector3;

/// An orthonormal frame `(t, b, n)` with `t x b = n`.
#[derive(Clone, Copy, Debug)]
pub struct ShadingFrame {
    pub t: Vector3<f64>,
    pub b: Vector3<f64>,
    pub n: Vector3<f64>,
}

impl ShadingFrame {
    /// The frame around unit normal `n`.
    pub fn new(n: Vector3<f64>) -> Self {
        let sign = 1.0f64.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let t = Vector3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let bb = Vector3::new(b, sign + n.y * n.y * a, -n.y);
        Self { t, b: bb, n }
    }

    /// A world direction in local coordinates (normal = +z).
    pub fn to_local(&self, d: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(self.t.dot(d), self.b.dot(d), self.n.dot(d))
    }

    /// A local direction in world coordinates.
    pub fn to_world(&self, d: &Vector3<f64>) -> Vector3<f64> {
        self.t * d.x + self.b * d.y + self.n * d.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal_and_right_handed() {
        for n in [
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(0.0, 0.0, -1.0),
            Vector3::new(0.3, -0.5, 0.2),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(-0.1, 0.9, -0.6),
        ] {
            let n = n.normalize();
            let f = ShadingFrame::new(n);
            assert!((f.t.norm() - 1.0).abs() < 1e-12 && (f.b.norm() - 1.0).abs() < 1e-12);
            assert!(f.t.dot(&f.b).abs() < 1e-12 && f.t.dot(&n).abs() < 1e-12);
            assert!((f.t.cross(&f.b) - n).norm() < 1e-12);
            let d = Vector3::new(0.2, 0.7, -0.4);
            assert!((f.to_world(&f.to_local(&d)) - d).norm() < 1e-12);
            assert!((f.to_local(&n) - Vector3::z()).norm() < 1e-12);
        }
    }
}
