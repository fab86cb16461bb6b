//! Pixel regions for calibration targets: luminance planes, Otsu thresholds, 8-connected
//! components, hole filling, region growing and bilinear sampling.
//!
//! Conventions: a plane is row-major `width * height` `f32`, like [`LinearImage`]; continuous
//! pixel coordinates put the centre of pixel `(x, y)` at `(x + 0.5, y + 0.5)` (COLMAP), which is
//! what [`bilinear`] expects. Pure: no I/O.

use crate::render::image::LinearImage;

/// A single-channel image plane.
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
}

impl Plane {
    /// Mean of the three channels.
    pub fn luminance(img: &LinearImage) -> Self {
        let data = img
            .data()
            .chunks_exact(3)
            .map(|c| (c[0] + c[1] + c[2]) / 3.0)
            .collect();
        Self {
            width: img.width(),
            height: img.height(),
            data,
        }
    }

    /// Largest channel per pixel: a pixel is saturated when any channel is.
    pub fn max_channel(img: &LinearImage) -> Self {
        let data = img
            .data()
            .chunks_exact(3)
            .map(|c| c[0].max(c[1]).max(c[2]))
            .collect();
        Self {
            width: img.width(),
            height: img.height(),
            data,
        }
    }

    /// The mean luminance of each `f`x`f` block of `img` (a partial block at the right or
    /// bottom is dropped), without a full-resolution plane in between; `f = 1` is
    /// [`Plane::luminance`].
    pub fn luminance_box_down(img: &LinearImage, f: usize) -> Self {
        let f = f.max(1);
        let (w, h) = (img.width() / f, img.height() / f);
        let mut data = vec![0f32; w * h];
        let norm = 1.0 / (3 * f * f) as f32;
        let full = img.width();
        for (j, row) in data.chunks_mut(w.max(1)).enumerate().take(h) {
            for y in j * f..(j + 1) * f {
                let src = &img.data()[3 * y * full..3 * (y * full + w * f)];
                for (i, v) in row.iter_mut().enumerate() {
                    *v += src[3 * i * f..3 * (i + 1) * f].iter().sum::<f32>();
                }
            }
            row.iter_mut().for_each(|v| *v *= norm);
        }
        Self {
            width: w,
            height: h,
            data,
        }
    }

    /// The mean of each `f`x`f` block (a partial block at the right or bottom is dropped): a
    /// coarse pixel `(i, j)` averages `[f i, f i + f) x [f j, f j + f)`, so full-resolution
    /// coordinates are `f` times coarse ones (pixel centres at half-integers in both).
    pub fn box_down(&self, f: usize) -> Self {
        let f = f.max(1);
        let (w, h) = (self.width / f, self.height / f);
        let mut data = vec![0f32; w * h];
        let norm = 1.0 / (f * f) as f32;
        for (j, row) in data.chunks_mut(w.max(1)).enumerate().take(h) {
            for y in j * f..(j + 1) * f {
                let src = &self.data[y * self.width..y * self.width + w * f];
                for (i, v) in row.iter_mut().enumerate() {
                    *v += src[i * f..(i + 1) * f].iter().sum::<f32>();
                }
            }
            row.iter_mut().for_each(|v| *v *= norm);
        }
        Self {
            width: w,
            height: h,
            data,
        }
    }

    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// 3x3 box filter (edges replicate), to steady a threshold against pixel noise.
    pub fn box3(&self) -> Self {
        let (w, h) = (self.width, self.height);
        let mut out = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut s = 0.0;
                for dy in [-1i64, 0, 1] {
                    for dx in [-1i64, 0, 1] {
                        let xx = (x as i64 + dx).clamp(0, w as i64 - 1) as usize;
                        let yy = (y as i64 + dy).clamp(0, h as i64 - 1) as usize;
                        s += self.data[yy * w + xx];
                    }
                }
                out[y * w + x] = s / 9.0;
            }
        }
        Self {
            width: w,
            height: h,
            data: out,
        }
    }
}

/// The integer downsampling factor that brings a `w`x`h` image's larger side to about
/// `target_px`: 1 up to `target_px` (the image is used whole), else at least 2.
pub fn downsample_factor(w: usize, h: usize, target_px: usize) -> usize {
    let side = w.max(h);
    if side <= target_px {
        1
    } else {
        (side as f64 / target_px.max(1) as f64).round().max(2.0) as usize
    }
}

/// Bilinear sample at continuous pixel coordinates (pixel centres at half-integers); `None`
/// outside the span of pixel centres.
pub fn bilinear(p: &Plane, x: f64, y: f64) -> Option<f64> {
    let (u, v) = (x - 0.5, y - 0.5);
    if !(u >= 0.0 && v >= 0.0) {
        return None;
    }
    let (x0, y0) = (u.floor() as usize, v.floor() as usize);
    if x0 + 1 >= p.width || y0 + 1 >= p.height {
        return None;
    }
    let (fx, fy) = (u - x0 as f64, v - y0 as f64);
    let a = p.at(x0, y0) as f64;
    let b = p.at(x0 + 1, y0) as f64;
    let c = p.at(x0, y0 + 1) as f64;
    let d = p.at(x0 + 1, y0 + 1) as f64;
    Some((a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy)
}

/// Otsu's threshold over values clipped to `[lo, hi]` (256 bins). `None` when the range is empty.
pub fn otsu_threshold(values: &[f32], lo: f32, hi: f32) -> Option<f32> {
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    const BINS: usize = 256;
    let mut hist = [0f64; BINS];
    let scale = (BINS - 1) as f32 / (hi - lo);
    for &v in values {
        if v.is_finite() {
            let b = ((v.clamp(lo, hi) - lo) * scale).round() as usize;
            hist[b.min(BINS - 1)] += 1.0;
        }
    }
    let total: f64 = hist.iter().sum();
    let sum_all: f64 = hist.iter().enumerate().map(|(i, h)| i as f64 * h).sum();
    let (mut w0, mut sum0) = (0.0, 0.0);
    let (mut best, mut best_t) = (-1.0, None);
    for (t, &h) in hist.iter().enumerate().take(BINS - 1) {
        w0 += h;
        sum0 += t as f64 * h;
        let w1 = total - w0;
        if w0 == 0.0 || w1 == 0.0 {
            continue;
        }
        let m0 = sum0 / w0;
        let m1 = (sum_all - sum0) / w1;
        let between = w0 * w1 * (m0 - m1) * (m0 - m1);
        if between > best {
            best = between;
            best_t = Some(t);
        }
    }
    best_t.map(|t| lo + (t as f32 + 0.5) / scale)
}

/// The `q` quantile (0..=1) of finite values; `None` when there are none.
pub fn quantile(values: &[f32], q: f64) -> Option<f32> {
    let mut v: Vec<f32> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    // a selection, not a sort: linear in the pixel count
    let i = ((v.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    Some(*v.select_nth_unstable_by(i, f32::total_cmp).1)
}

/// One 8-connected component of a mask: pixel indices (`y * width + x`).
#[derive(Clone, Debug, PartialEq)]
pub struct Component {
    pub pixels: Vec<usize>,
    /// Some pixel lies on the first or last row or column.
    pub touches_border: bool,
}

/// 8-connected components of `mask` (`width * height`).
pub fn components(mask: &[bool], width: usize, height: usize) -> Vec<Component> {
    let mut label = vec![false; mask.len()];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for start in 0..mask.len() {
        if !mask[start] || label[start] {
            continue;
        }
        label[start] = true;
        stack.push(start);
        let mut pixels = Vec::new();
        let mut touches_border = false;
        while let Some(i) = stack.pop() {
            pixels.push(i);
            let (x, y) = (i % width, i / width);
            if x == 0 || y == 0 || x + 1 == width || y + 1 == height {
                touches_border = true;
            }
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                    if xx < 0 || yy < 0 || xx >= width as i64 || yy >= height as i64 {
                        continue;
                    }
                    let j = yy as usize * width + xx as usize;
                    if mask[j] && !label[j] {
                        label[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        out.push(Component {
            pixels,
            touches_border,
        });
    }
    out
}

/// The component with its holes filled: every pixel that the outside of the component cannot
/// reach (4-connected, through non-members, from the image border) becomes a member. Returns a
/// full-size mask.
pub fn filled_mask(c: &Component, width: usize, height: usize) -> Vec<bool> {
    let mut member = vec![false; width * height];
    for &i in &c.pixels {
        member[i] = true;
    }
    let border: Vec<usize> = (0..width * height)
        .filter(|&i| {
            let (x, y) = (i % width, i / width);
            !member[i] && (x == 0 || y == 0 || x + 1 == width || y + 1 == height)
        })
        .collect();
    let mut filled = vec![true; width * height];
    for i in grow_region(&border, width, height, |j| !member[j]) {
        filled[i] = false;
    }
    filled
}

/// Pixels 4-connected to `seeds` through pixels where `keep` holds (the seeds always count).
pub fn grow_region(
    seeds: &[usize],
    w: usize,
    h: usize,
    keep: impl Fn(usize) -> bool,
) -> Vec<usize> {
    let mut seen = vec![false; w * h];
    let mut stack: Vec<usize> = Vec::new();
    for &i in seeds {
        if !seen[i] {
            seen[i] = true;
            stack.push(i);
        }
    }
    let mut out = Vec::new();
    while let Some(i) = stack.pop() {
        out.push(i);
        let (x, y) = (i % w, i / w);
        let mut visit = |j: usize| {
            if !seen[j] && keep(j) {
                seen[j] = true;
                stack.push(j);
            }
        };
        if x > 0 {
            visit(i - 1);
        }
        if x + 1 < w {
            visit(i + 1);
        }
        if y > 0 {
            visit(i - w);
        }
        if y + 1 < h {
            visit(i + w);
        }
    }
    out
}

/// Morphological opening with a `(2k+1)` square: removes parts narrower than `2k+1` pixels (a
/// stand or post holding a sphere) and keeps the rest as it was. Outside the image counts as
/// empty for the erosion, so a region cut by the frame still reaches the frame afterwards.
pub fn open_mask(mask: &[bool], w: usize, h: usize, k: usize) -> Vec<bool> {
    if k == 0 {
        return mask.to_vec();
    }
    let eroded = morph(mask, w, h, k, Morph::Erode { outside_set: false });
    morph(&eroded, w, h, k, Morph::Dilate)
}

/// Morphological closing with a `(2k+1)` square: fills notches and gaps narrower than `2k+1`
/// pixels (a bright highlight that reaches a dark sphere's rim bites such a notch into it).
/// Outside the image counts as set for the erosion, so a region near the frame does not grow
/// towards it.
pub fn close_mask(mask: &[bool], w: usize, h: usize, k: usize) -> Vec<bool> {
    if k == 0 {
        return mask.to_vec();
    }
    let dilated = morph(mask, w, h, k, Morph::Dilate);
    morph(&dilated, w, h, k, Morph::Erode { outside_set: true })
}

#[derive(Clone, Copy)]
enum Morph {
    Dilate,
    Erode { outside_set: bool },
}

/// One separable pass with a `(2k+1)` square, with prefix counts: erosion keeps a pixel when the
/// whole window is set, dilation when any of it is.
fn morph(m: &[bool], w: usize, h: usize, k: usize, op: Morph) -> Vec<bool> {
    let keep = |n: usize, in_image: usize| match op {
        Morph::Dilate => n > 0,
        Morph::Erode { outside_set: false } => n == 2 * k + 1,
        Morph::Erode { outside_set: true } => n == in_image,
    };
    let mut rows = vec![false; w * h];
    for y in 0..h {
        let mut pre = vec![0usize; w + 1];
        for x in 0..w {
            pre[x + 1] = pre[x] + m[y * w + x] as usize;
        }
        for x in 0..w {
            let (a, b) = (x.saturating_sub(k), (x + k + 1).min(w));
            rows[y * w + x] = keep(pre[b] - pre[a], b - a);
        }
    }
    let mut out = vec![false; w * h];
    for x in 0..w {
        let mut pre = vec![0usize; h + 1];
        for y in 0..h {
            pre[y + 1] = pre[y] + rows[y * w + x] as usize;
        }
        for y in 0..h {
            let (a, b) = (y.saturating_sub(k), (y + k + 1).min(h));
            out[y * w + x] = keep(pre[b] - pre[a], b - a);
        }
    }
    out
}

/// Algebraic (Kasa) circle fit to points: `(cx, cy, r)`; `None` when degenerate.
pub fn fit_circle(points: &[(f64, f64)]) -> Option<(f64, f64, f64)> {
    if points.len() < 3 {
        return None;
    }
    // centre the data for conditioning
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    // minimise sum (x^2 + y^2 + D x + E y + F)^2
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atb = nalgebra::Vector3::<f64>::zeros();
    for &(x, y) in points {
        let (u, v) = (x - mx, y - my);
        let row = nalgebra::Vector3::new(u, v, 1.0);
        ata += row * row.transpose();
        atb += row * (-(u * u + v * v));
    }
    let sol = ata.cholesky()?.solve(&atb);
    let (cx, cy) = (-sol[0] / 2.0, -sol[1] / 2.0);
    let r2 = cx * cx + cy * cy - sol[2];
    (r2 > 0.0).then(|| (cx + mx, cy + my, r2.sqrt()))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn box_down_averages_blocks_and_luminance_comes_down_the_same_way() {
        let (w, h) = (7, 5);
        let p = Plane {
            width: w,
            height: h,
            data: (0..w * h)
                .map(|i| ((i % w) + 10 * (i / w)) as f32)
                .collect(),
        };
        let d = p.box_down(2);
        assert_eq!((d.width, d.height), (3, 2));
        // block (1, 1): x 2..4, y 2..4 -> mean x 2.5, mean y 2.5
        assert!((d.at(1, 1) - (2.5 + 25.0)).abs() < 1e-5);
        assert_eq!(p.box_down(1), p);
        // an image whose channels are v, 2v, 3v: its luminance is 2v
        let rgb: Vec<f32> = p.data.iter().flat_map(|&v| [v, 2.0 * v, 3.0 * v]).collect();
        let img = LinearImage::from_rgb(w, h, rgb).unwrap();
        let l = Plane::luminance_box_down(&img, 2);
        assert_eq!((l.width, l.height), (3, 2));
        for (a, b) in l.data.iter().zip(&d.data) {
            assert!((a - 2.0 * b).abs() < 1e-4, "{a} {b}");
        }
        assert_eq!(Plane::luminance_box_down(&img, 1), Plane::luminance(&img));
    }

    #[test]
    fn small_images_are_used_whole_and_large_ones_come_down_to_about_the_target() {
        assert_eq!(downsample_factor(320, 240, 750), 1);
        assert_eq!(downsample_factor(750, 500, 750), 1);
        assert_eq!(downsample_factor(6000, 4000, 750), 8);
        assert_eq!(downsample_factor(4000, 6000, 750), 8);
        assert_eq!(downsample_factor(800, 600, 750), 2);
    }

    #[test]
    fn circle_fit_recovers_exact_circle() {
        let pts: Vec<(f64, f64)> = (0..40)
            .map(|i| {
                let a = i as f64 * 0.3;
                (12.5 + 7.0 * a.cos(), -3.0 + 7.0 * a.sin())
            })
            .collect();
        let (cx, cy, r) = fit_circle(&pts).unwrap();
        assert!((cx - 12.5).abs() < 1e-9 && (cy + 3.0).abs() < 1e-9 && (r - 7.0).abs() < 1e-9);
    }

    #[test]
    fn opening_removes_a_thin_post_and_keeps_a_disc() {
        let (w, h) = (40, 40);
        let mut mask = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let disc = (x as f64 - 20.0).hypot(y as f64 - 15.0) < 10.0;
                let post = (19..=21).contains(&x) && y >= 15;
                mask[y * w + x] = disc || post;
            }
        }
        let opened = open_mask(&mask, w, h, 2);
        assert!(
            !opened[39 * w + 20],
            "the post reaches the bottom edge no more"
        );
        assert!(opened[15 * w + 20] && opened[15 * w + 11] && opened[15 * w + 29]);
        let c = components(&opened, w, h);
        assert_eq!(c.len(), 1);
        assert!(!c[0].touches_border);
    }

    #[test]
    fn components_and_hole_filling() {
        // a 7x7 ring with a hole in the middle, and a separate pixel in the corner
        let (w, h) = (9, 9);
        let mut mask = vec![false; w * h];
        for y in 1..8 {
            for x in 1..8 {
                if !(3..=5).contains(&x) || !(3..=5).contains(&y) {
                    mask[y * w + x] = true;
                }
            }
        }
        mask[0] = true; // touches the corner, but 8-connected to (1,1)
        let comps = components(&mask, w, h);
        assert_eq!(comps.len(), 1);
        assert!(comps[0].touches_border);
        let filled = filled_mask(&comps[0], w, h);
        assert_eq!(filled.iter().filter(|&&m| m).count(), 49 + 1);
    }

    #[test]
    fn bilinear_uses_pixel_centres_and_otsu_splits_two_levels() {
        let p = Plane {
            width: 2,
            height: 2,
            data: vec![0.0, 1.0, 2.0, 3.0],
        };
        assert_eq!(bilinear(&p, 0.5, 0.5), Some(0.0));
        assert_eq!(bilinear(&p, 1.0, 1.0), Some(1.5));
        assert_eq!(bilinear(&p, 0.4, 0.5), None);
        let mut v = vec![0.1f32; 100];
        v.extend(vec![0.9f32; 50]);
        let t = otsu_threshold(&v, 0.0, 1.0).unwrap();
        assert!(t > 0.1 && t < 0.9, "{t}");
    }
}
