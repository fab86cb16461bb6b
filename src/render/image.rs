//! A linear-radiance RGB image in memory: the currency between the simulated camera, real camera
//! backends, calibration, HDR merging and reconstruction.
//!
//! Conventions: row-major, origin at the top-left pixel, `x` to the right and `y` down (as COLMAP
//! and OpenCV); pixel `(x, y)` covers `[x, x+1) x [y, y+1)` so its centre is `(x + 0.5, y + 0.5)`.
//! Values are linear in radiance (no gamma), in whatever unit the producer states (the simulated
//! camera: W sr^-1 m^-2 times exposure gain). Pure: no file I/O here (see `crate::imageio`).

/// Three-channel linear image, `f32` per channel.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearImage {
    width: usize,
    height: usize,
    /// `width * height * 3` values, RGB interleaved.
    data: Vec<f32>,
}

impl LinearImage {
    /// A black image.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            data: vec![0.0; width * height * 3],
        }
    }

    /// Wraps interleaved RGB data; `None` when the length does not match the size.
    pub fn from_rgb(width: usize, height: usize, data: Vec<f32>) -> Option<Self> {
        (data.len() == width * height * 3).then_some(Self {
            width,
            height,
            data,
        })
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// Interleaved RGB values.
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }

    /// The RGB value at `(x, y)`; panics when out of bounds (callers index within `width/height`).
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        let i = (y * self.width + x) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    pub fn set(&mut self, x: usize, y: usize, rgb: [f32; 3]) {
        let i = (y * self.width + x) * 3;
        self.data[i..i + 3].copy_from_slice(&rgb);
    }

    /// Mean of the three channels at `(x, y)`.
    pub fn luminance(&self, x: usize, y: usize) -> f32 {
        let [r, g, b] = self.get(x, y);
        (r + g + b) / 3.0
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn set_get_round_trip_and_size_check() {
        let mut img = LinearImage::new(4, 3);
        img.set(3, 2, [1.0, 2.0, 3.0]);
        assert_eq!(img.get(3, 2), [1.0, 2.0, 3.0]);
        assert_eq!(img.get(0, 0), [0.0; 3]);
        assert!((img.luminance(3, 2) - 2.0).abs() < 1e-6);
        assert!(LinearImage::from_rgb(2, 2, vec![0.0; 11]).is_none());
        assert!(LinearImage::from_rgb(2, 2, vec![0.0; 12]).is_some());
    }
}
