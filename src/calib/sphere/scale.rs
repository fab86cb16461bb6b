//! Working on a large image at the scale the sphere needs: the outline is found on a
//! box-downsampled luminance and refined at full resolution along profiles across it (`edges`),
//! the highlight is looked for in a window around the sphere (`highlight`), so that the time no
//! longer grows with the sensor's pixel count. Images up to `WHOLE_WIDTH_PX` wide (every test
//! image) are used whole.
//!
//! Conventions: as `calib::sphere`; a coarse pixel `(i, j)` averages the full pixels
//! `[f i, f i + f) x [f j, f j + f)`, so full-resolution coordinates are `f` times coarse ones
//! (pixel centres at half-integers in both). Pure: no I/O.

use super::SphereOutline;
use crate::calib::regions;
use crate::geometry::camera::Intrinsics;
use crate::render::image::LinearImage;

/// Width (pixels) up to which an image is used whole (every test image is), and about the width
/// a larger one is downsampled to for the outline's search. The search over candidates (a rim
/// fit on every profile of each, and the probes outside the best) costs as the sphere's
/// circumference times its rim band, about the square of the width: on the 24 MP fixture it
/// took 12 s at 1500 px, 1.3 s at 750 px and 0.7 s at 500 px, with the same light direction,
/// since the full-resolution profiles measure the outline again (docs/calibration.md).
const WHOLE_WIDTH_PX: usize = 1000;
const COARSE_WIDTH_PX: usize = 500;
/// A sphere must span a few coarse pixels to be found (`min_radius_px`, at least 3): one too
/// small for the coarse image (under 36 px of radius at 24 MP) is looked for again at about
/// this width before the search gives up.
const RETRY_WIDTH_PX: usize = 1500;

/// The integer downsampling factor for a `w`x`h` image: 1 up to `WHOLE_WIDTH_PX` (the image is
/// used whole), else the factor that brings the larger side to about `COARSE_WIDTH_PX`.
pub(super) fn factor(w: usize, h: usize) -> usize {
    if w.max(h) <= WHOLE_WIDTH_PX {
        1
    } else {
        regions::downsample_factor(w, h, COARSE_WIDTH_PX)
    }
}

/// The factor of the second search, for a sphere too small for the first (`factor`); `None`
/// when it would not be finer.
pub(super) fn retry_factor(w: usize, h: usize) -> Option<usize> {
    let f = regions::downsample_factor(w, h, RETRY_WIDTH_PX);
    (f < factor(w, h)).then_some(f)
}

/// The camera of the image downsampled by `f` (as [`regions::Plane::box_down`]).
pub(super) fn coarse_intrinsics(intr: &Intrinsics, f: usize) -> Intrinsics {
    Intrinsics {
        width: intr.width / f,
        height: intr.height / f,
        ..intr.scaled(1.0 / f as f64)
    }
}

/// A window of a large light image around the sphere (its outline widened by half its radius
/// and a margin), with the camera and the outline moved into it; `None` when the image is small
/// enough to be used whole or the window would be the whole frame.
pub(super) fn sphere_window(
    img: &LinearImage,
    outline: &SphereOutline,
    intr: &Intrinsics,
) -> Option<(LinearImage, Intrinsics, SphereOutline, [usize; 2])> {
    let (w, h) = (img.width(), img.height());
    if factor(w, h) == 1 {
        return None;
    }
    let reach = 1.5 * outline.radius_px + 16.0;
    let [cx, cy] = outline.centre_px;
    let clamp = |v: f64, n: usize| v.clamp(0.0, n as f64) as usize;
    let (x0, x1) = (
        clamp((cx - reach).floor(), w),
        clamp((cx + reach).ceil(), w),
    );
    let (y0, y1) = (
        clamp((cy - reach).floor(), h),
        clamp((cy + reach).ceil(), h),
    );
    if x1 <= x0 || y1 <= y0 || (x1 - x0) * (y1 - y0) >= w * h {
        return None;
    }
    let (cw, ch) = (x1 - x0, y1 - y0);
    let mut data = Vec::with_capacity(3 * cw * ch);
    for y in y0..y1 {
        data.extend_from_slice(&img.data()[3 * (y * w + x0)..3 * (y * w + x1)]);
    }
    let crop = LinearImage::from_rgb(cw, ch, data)?;
    let k = Intrinsics {
        width: cw,
        height: ch,
        cx: intr.cx - x0 as f64,
        cy: intr.cy - y0 as f64,
        ..*intr
    };
    let mut o = outline.clone();
    o.centre_px = [cx - x0 as f64, cy - y0 as f64];
    Some((crop, k, o, [x0, y0]))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn a_coarse_camera_keeps_coordinates_proportional() {
        assert_eq!(factor(640, 480), 1);
        assert_eq!(factor(1000, 750), 1);
        assert_eq!(factor(1600, 1200), 3);
        assert_eq!(factor(6000, 4000), 12);
        assert_eq!(retry_factor(6000, 4000), Some(4));
        assert_eq!(retry_factor(1600, 1200), Some(2));
        // an image used whole has no finer search to retry with
        assert_eq!(retry_factor(1000, 750), None);
        // a coarse pixel centre maps to the full-resolution centre of its block
        let k = Intrinsics::pinhole(7, 5, 10.0, 10.0, 3.5, 2.5);
        let c = coarse_intrinsics(&k, 2);
        assert_eq!((c.width, c.height), (3, 2));
        assert!((c.cx * 2.0 - k.cx).abs() < 1e-12 && (c.fx * 2.0 - k.fx).abs() < 1e-12);
    }
}
