//! The camera preview of the lab page: a linear camera image turned into what a person judges
//! exposure by. Clipped pixels (any channel at or above the camera's saturation value) are
//! painted with magenta and black stripes, a histogram of the linear values (64 bins per channel
//! over `[0, saturation]`) and the clipped fraction go with each frame, and the picture is
//! shrunk by whole factors to fit the preview size and encoded as JPEG.
//!
//! Display: sRGB of `value / saturation` (so mid-grey on the page is the same linear level
//! whatever the camera's units), with no auto-exposure: a dark preview means a dark image.
//!
//! [`frame`] is pure (image in, bytes and numbers out). The [`Worker`] runs it on its own thread,
//! so neither the rig's thread nor the async server ever waits for an encoder.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;

use serde::Serialize;

use crate::render::image::LinearImage;

/// Histogram bins per channel.
pub const BINS: usize = 64;

/// Where a frame came from.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Source {
    /// A live frame taken for the preview (idle, or while the operator acts).
    Live,
    /// The image of a shot the capture just journaled.
    Shot { id: String },
}

/// What goes to the page with the JPEG bytes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameInfo {
    pub seq: u64,
    /// Size of the JPEG picture.
    pub width: usize,
    pub height: usize,
    /// Size of the camera image it shows.
    pub source_width: usize,
    pub source_height: usize,
    pub source: Source,
    pub exposure_secs: f64,
    pub gain: f64,
    /// Fraction of the camera's pixels with a clipped channel.
    pub clipped_fraction: f64,
    /// Pixel counts of R, G and B over `[0, saturation]` in [`BINS`] bins (clipped values in
    /// the last).
    pub histogram: [Vec<u32>; 3],
    /// Time taken to make this frame from the linear image (shrink, mark, histogram, JPEG).
    pub encode_millis: f64,
}

/// A frame ready to send.
#[derive(Clone, Debug)]
pub struct Frame {
    pub info: FrameInfo,
    pub jpeg: Vec<u8>,
}

/// One image to turn into a frame.
pub struct Job {
    pub image: LinearImage,
    pub saturation: f32,
    pub source: Source,
    pub exposure_secs: f64,
    pub gain: f64,
}

/// The 8-bit picture of a frame before encoding.
#[derive(Clone, Debug, PartialEq)]
pub struct Picture {
    pub width: usize,
    pub height: usize,
    /// RGB interleaved.
    pub rgb: Vec<u8>,
    pub histogram: [Vec<u32>; 3],
    pub clipped_fraction: f64,
}

/// The whole factor by which an image of `w x h` is shrunk to fit `max_w x max_h` (at least 1).
pub fn shrink_factor(w: usize, h: usize, max_w: usize, max_h: usize) -> usize {
    let fx = w.div_ceil(max_w.max(1));
    let fy = h.div_ceil(max_h.max(1));
    fx.max(fy).max(1)
}

/// sRGB code of `v` in [0, 1] by table (4096 steps: below the 8-bit resolution everywhere).
struct SrgbTable(Vec<u8>);

impl SrgbTable {
    fn new() -> Self {
        Self(
            (0..4096)
                .map(|i| (crate::imageio::srgb_encode(i as f32 / 4095.0) * 255.0).round() as u8)
                .collect(),
        )
    }

    fn code(&self, v: f32) -> u8 {
        let i = (v.clamp(0.0, 1.0) * 4095.0).round() as usize;
        self.0.get(i).copied().unwrap_or(255)
    }
}

/// The clipped-pixel mark: magenta and black diagonal stripes, 4 pixels wide, so a clipped area
/// reads as such on any picture.
fn mark(x: usize, y: usize) -> [u8; 3] {
    if ((x + y) / 4).is_multiple_of(2) {
        [255, 0, 255]
    } else {
        [0, 0, 0]
    }
}

/// Shrinks `image` by a whole factor to fit `max_w x max_h` (box average), marks clipped pixels
/// (a shrunk pixel is marked when any pixel it covers is clipped) and counts the histogram over
/// every camera pixel. `saturation` is the camera's clipping value (positive; 1 when unknown).
pub fn picture(image: &LinearImage, saturation: f32, max_w: usize, max_h: usize) -> Picture {
    let sat = if saturation.is_finite() && saturation > 0.0 {
        saturation
    } else {
        1.0
    };
    let (w, h) = (image.width(), image.height());
    let f = shrink_factor(w, h, max_w, max_h);
    let (ow, oh) = ((w / f).max(1), (h / f).max(1));
    let data = image.data();
    let mut histogram = [vec![0u32; BINS], vec![0u32; BINS], vec![0u32; BINS]];
    let mut clipped_px = 0usize;
    let mut clipped = vec![false; w * h];
    for (i, px) in data.chunks_exact(3).enumerate() {
        let mut any = false;
        for (c, &v) in px.iter().enumerate() {
            let t = if v.is_nan() { 0.0 } else { v / sat };
            any |= t >= 1.0;
            let bin = ((t.clamp(0.0, 1.0) * BINS as f32) as usize).min(BINS - 1);
            histogram[c][bin] += 1;
        }
        if any {
            clipped[i] = true;
            clipped_px += 1;
        }
    }
    let table = SrgbTable::new();
    let mut rgb = vec![0u8; ow * oh * 3];
    let n = (f * f) as f32;
    for oy in 0..oh {
        for ox in 0..ow {
            let mut sum = [0.0f32; 3];
            let mut any = false;
            for y in oy * f..(oy * f + f).min(h) {
                for x in ox * f..(ox * f + f).min(w) {
                    let i = y * w + x;
                    any |= clipped[i];
                    for (c, s) in sum.iter_mut().enumerate() {
                        let v = data[3 * i + c];
                        *s += if v.is_nan() { 0.0 } else { v };
                    }
                }
            }
            let out = &mut rgb[3 * (oy * ow + ox)..3 * (oy * ow + ox) + 3];
            if any {
                out.copy_from_slice(&mark(ox, oy));
            } else {
                for c in 0..3 {
                    out[c] = table.code(sum[c] / n / sat);
                }
            }
        }
    }
    Picture {
        width: ow,
        height: oh,
        rgb,
        histogram,
        clipped_fraction: clipped_px as f64 / (w * h).max(1) as f64,
    }
}

/// Why a preview frame could not be made (the page's log shows it as a warning).
#[derive(Debug, thiserror::Error)]
pub enum PreviewError {
    #[error("encoding the preview as JPEG: {0}")]
    Jpeg(#[source] image::ImageError),
}

/// JPEG bytes of an 8-bit RGB picture (quality 1..=100).
pub fn jpeg(p: &Picture, quality: u8) -> Result<Vec<u8>, PreviewError> {
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality.clamp(1, 100))
        .encode(
            &p.rgb,
            p.width as u32,
            p.height as u32,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(PreviewError::Jpeg)?;
    Ok(out)
}

/// A frame from a job: the picture, its JPEG, the numbers.
pub fn frame(job: &Job, seq: u64, max_w: usize, max_h: usize) -> Result<Frame, PreviewError> {
    let t = std::time::Instant::now();
    let p = picture(&job.image, job.saturation, max_w, max_h);
    let jpeg = jpeg(&p, 80)?;
    Ok(Frame {
        info: FrameInfo {
            seq,
            width: p.width,
            height: p.height,
            source_width: job.image.width(),
            source_height: job.image.height(),
            source: job.source.clone(),
            exposure_secs: job.exposure_secs,
            gain: job.gain,
            clipped_fraction: p.clipped_fraction,
            histogram: p.histogram,
            encode_millis: 1000.0 * t.elapsed().as_secs_f64(),
        },
        jpeg,
    })
}

/// Turns images into frames on its own thread, one at a time. [`Worker::offer`] never waits:
/// while a frame is being made, a new image is dropped (the preview shows the latest it can).
pub struct Worker {
    jobs: mpsc::SyncSender<Job>,
    busy: Arc<AtomicBool>,
}

impl Worker {
    /// Starts the thread; each frame goes to `publish`. Frames fit `max_w x max_h`.
    pub fn spawn(
        max_w: usize,
        max_h: usize,
        publish: impl Fn(Result<Frame, PreviewError>) + Send + 'static,
    ) -> std::io::Result<Worker> {
        let (jobs, rx) = mpsc::sync_channel::<Job>(1);
        let busy = Arc::new(AtomicBool::new(false));
        let flag = busy.clone();
        std::thread::Builder::new()
            .name("brdf-rig-preview".into())
            .spawn(move || {
                let mut seq = 0u64;
                while let Ok(job) = rx.recv() {
                    seq += 1;
                    publish(frame(&job, seq, max_w, max_h));
                    flag.store(false, Ordering::SeqCst);
                }
            })?;
        Ok(Worker { jobs, busy })
    }

    /// True while a frame is being made: taking a live picture now would be wasted.
    pub fn is_busy(&self) -> bool {
        self.busy.load(Ordering::SeqCst)
    }

    /// Hands an image over unless a frame is being made; true when it was taken.
    pub fn offer(&self, job: Job) -> bool {
        if self
            .busy
            .compare_exchange(false, true, Ordering::SeqCst, Ordering::SeqCst)
            .is_err()
        {
            return false;
        }
        if self.jobs.try_send(job).is_err() {
            self.busy.store(false, Ordering::SeqCst);
            return false;
        }
        true
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn clipped_pixels_are_marked_and_counted_and_the_histogram_sums_to_the_pixels() {
        let (w, h) = (40, 30);
        let mut img = LinearImage::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let v = x as f32 / (w - 1) as f32 * 0.5; // 0 .. 0.5 of saturation 2
                img.set(x, y, [v, v, v]);
            }
        }
        // a clipped 4x4 block in one channel only
        for y in 10..14 {
            for x in 20..24 {
                img.set(x, y, [0.1, 2.5, 0.1]);
            }
        }
        let p = picture(&img, 2.0, 640, 480);
        assert_eq!((p.width, p.height), (40, 30));
        assert!((p.clipped_fraction - 16.0 / 1200.0).abs() < 1e-12);
        for c in 0..3 {
            assert_eq!(p.histogram[c].iter().sum::<u32>(), 1200);
        }
        assert_eq!(
            p.histogram[1][BINS - 1],
            16,
            "clipped values in the last bin"
        );
        // nothing reaches the top quarter but the clipped block
        assert!(p.histogram[0][BINS * 3 / 4..].iter().all(|&n| n == 0));
        let at = |x: usize, y: usize| &p.rgb[3 * (y * p.width + x)..3 * (y * p.width + x) + 3];
        for y in 10..14 {
            for x in 20..24 {
                assert_eq!(at(x, y), mark(x, y));
            }
        }
        // unclipped: the sRGB code of value / saturation
        let v = 39.0 / 39.0 * 0.5 / 2.0;
        let want = (crate::imageio::srgb_encode(v) * 255.0).round() as u8;
        assert!((i32::from(at(39, 0)[0]) - i32::from(want)).abs() <= 1);
        assert_eq!(at(0, 0), [0, 0, 0]);
    }

    #[test]
    fn big_images_shrink_by_whole_factors_and_keep_their_clipping_marks() {
        assert_eq!(shrink_factor(640, 480, 640, 480), 1);
        assert_eq!(shrink_factor(641, 480, 640, 480), 2);
        assert_eq!(shrink_factor(6000, 4000, 640, 480), 10);
        let mut img = LinearImage::new(1280, 960);
        img.set(5, 5, [1.0, 0.0, 0.0]); // one clipped pixel
        let p = picture(&img, 1.0, 640, 480);
        assert_eq!((p.width, p.height), (640, 480));
        assert_eq!(&p.rgb[3 * (2 * 640 + 2)..3 * (2 * 640 + 2) + 3], mark(2, 2));
        assert!((p.clipped_fraction - 1.0 / (1280.0 * 960.0)).abs() < 1e-15);
        let f = frame(
            &Job {
                image: img,
                saturation: 1.0,
                source: Source::Live,
                exposure_secs: 0.01,
                gain: 1.0,
            },
            7,
            640,
            480,
        )
        .unwrap();
        assert_eq!(&f.jpeg[..2], &[0xff, 0xd8], "a JPEG");
        let back = image::load_from_memory(&f.jpeg).unwrap();
        assert_eq!((back.width(), back.height()), (640, 480));
        assert_eq!(f.info.seq, 7);
    }

    #[test]
    fn nan_and_odd_saturation_do_not_panic() {
        let img = LinearImage::from_rgb(2, 1, vec![f32::NAN, 0.5, 2.0, 0.0, 0.0, 0.0]).unwrap();
        let p = picture(&img, f32::NAN, 640, 480);
        assert_eq!(p.clipped_fraction, 0.5);
    }
}
