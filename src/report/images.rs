//! Images in a report: PNG previews of linear images (8-bit sRGB, for humans, not data), sphere
//! renders of a BRDF, and the PNG renders a reconstruction wrote. Pure except [`png_files`].

use super::avail::Avail;
use crate::brdf::Brdf;
use crate::geometry::camera::{Intrinsics, Pose};
use crate::render::image::LinearImage;
use crate::render::light::DirectionalLight;
use crate::render::sphere::{Sphere, render_sphere};
use nalgebra::{Point3, Vector3};
use std::path::{Path, PathBuf};

/// An image embedded in the page.
#[derive(Clone, Debug, PartialEq)]
pub struct EmbeddedImage {
    pub caption: String,
    /// PNG bytes.
    pub png: Vec<u8>,
    pub width: u32,
    pub height: u32,
}

/// Box-filter downscale so the width is at most `max_width` (integer factor).
pub(super) fn downscale(img: &LinearImage, max_width: usize) -> LinearImage {
    let f = img.width().div_ceil(max_width.max(1)).max(1);
    if f == 1 {
        return img.clone();
    }
    let (w, h) = (img.width() / f, img.height() / f);
    let mut out = LinearImage::new(w.max(1), h.max(1));
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0.0f32; 3];
            for dy in 0..f {
                for dx in 0..f {
                    let p = img.get(x * f + dx, y * f + dy);
                    for c in 0..3 {
                        acc[c] += p[c];
                    }
                }
            }
            let n = (f * f) as f32;
            out.set(x, y, acc.map(|a| a / n));
        }
    }
    out
}

/// Exposure (stops) mapping the 99th percentile of the largest channel over the non-black
/// pixels of all images to 0.9; 0 when every pixel is black.
pub(super) fn auto_exposure(imgs: &[&LinearImage]) -> f32 {
    let mut v: Vec<f32> = imgs
        .iter()
        .flat_map(|i| i.data().chunks_exact(3).map(|p| p[0].max(p[1]).max(p[2])))
        .filter(|x| x.is_finite() && *x > 0.0)
        .collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f32::total_cmp);
    let p = v[((v.len() - 1) as f64 * 0.99) as usize];
    (0.9 / p).log2()
}

/// An 8-bit sRGB PNG of `img * 2^stops`.
pub(super) fn encode_png(img: &LinearImage, stops: f32) -> Option<EmbeddedImage> {
    let bytes = crate::imageio::preview_srgb8(img, stops);
    let (w, h) = (
        u32::try_from(img.width()).ok()?,
        u32::try_from(img.height()).ok()?,
    );
    let mut png = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut png),
        &bytes,
        w,
        h,
        image::ExtendedColorType::Rgb8,
    )
    .ok()?;
    Some(EmbeddedImage {
        caption: String::new(),
        png,
        width: w,
        height: h,
    })
}

/// The lights of the sphere previews: angle between light and view (degrees), light towards
/// the upper left of the image. With one light fixed relative to the camera this angle is
/// 2 theta_d for every pixel, as on the rig.
pub const SPHERE_LIGHT_ANGLES_DEG: [f64; 3] = [0.0, 45.0, 90.0];

/// The result on a sphere under the lights of [`SPHERE_LIGHT_ANGLES_DEG`], one exposure for
/// all (so their brightness compares).
pub fn sphere_renders(brdf: &dyn Brdf, pixels: usize) -> Avail<Vec<EmbeddedImage>> {
    let n = pixels.clamp(16, 1024);
    let sphere = Sphere {
        centre: Point3::origin(),
        radius: 1.0,
    };
    let eye = Point3::new(0.0, 0.0, 4.0);
    let pose = Pose::look_at(eye, sphere.centre, Vector3::y());
    // The sphere's outline (half angle asin(1/4)) fills 80 % of the frame.
    let half = (0.25f64).asin().tan();
    let f = 0.4 * n as f64 / half;
    let k = Intrinsics::pinhole(n, n, f, f, n as f64 / 2.0, n as f64 / 2.0);
    let irradiance = [std::f64::consts::PI; 3];
    let mut imgs = Vec::new();
    for a in SPHERE_LIGHT_ANGLES_DEG {
        let r = a.to_radians();
        // Rotate the view direction (+z towards the camera) towards the upper left (-x, +y).
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let to_light = Vector3::new(-s * r.sin(), s * r.sin(), r.cos());
        let Some(light) = DirectionalLight::new(to_light, irradiance) else {
            return Avail::No("internal: a sphere light direction is degenerate".into());
        };
        imgs.push((a, render_sphere(&sphere, brdf, &light, &k, &pose, [0.0; 3])));
    }
    let refs: Vec<&LinearImage> = imgs.iter().map(|(_, i)| i).collect();
    let stops = auto_exposure(&refs);
    let mut out = Vec::new();
    for (a, img) in &imgs {
        match encode_png(img, stops) {
            Some(e) => out.push(EmbeddedImage {
                caption: format!(
                    "light {a:.0} deg from the view (theta_d = {:.1} deg), irradiance pi; \
                     exposure {stops:+.1} stops",
                    a / 2.0
                ),
                ..e
            }),
            None => return Avail::No("a sphere render could not be encoded as PNG".into()),
        }
    }
    Avail::Yes(out)
}

/// Why a PNG file cannot be embedded. The report names the file beside the message.
#[derive(Debug, thiserror::Error)]
pub(super) enum EmbedError {
    #[error(transparent)]
    Read(#[from] std::io::Error),
    #[error(transparent)]
    Decode(#[from] image::ImageError),
}

/// A PNG file embedded as it is (its size read from the file).
pub(super) fn embed_png(path: &Path, caption: String) -> Result<EmbeddedImage, EmbedError> {
    let bytes = std::fs::read(path)?;
    let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)?;
    Ok(EmbeddedImage {
        caption,
        width: img.width(),
        height: img.height(),
        png: bytes,
    })
}

/// The `*.png` files of the reconstruction output (its own renders), embedded as they are.
pub(super) fn png_files(dir: &Path) -> Avail<Vec<EmbeddedImage>> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Avail::No(format!("{}: cannot list the folder", dir.display()));
    };
    let mut files: Vec<PathBuf> = rd
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")))
        .collect();
    files.sort();
    if files.is_empty() {
        return Avail::No("the reconstruction output has no PNG renders".into());
    }
    let mut out = Vec::new();
    let mut bad = Vec::new();
    for p in files {
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        match embed_png(&p, name) {
            Ok(img) => out.push(img),
            Err(e) => bad.push(format!("{}: {e}", p.display())),
        }
    }
    if out.is_empty() {
        Avail::No(format!("no PNG could be decoded: {}", bad.join("; ")))
    } else {
        Avail::Yes(out)
    }
}
