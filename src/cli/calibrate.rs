//! `brdf-rig calibrate`: light direction from sphere images, irradiance from a white board.
//! Thin: validates the arguments into a configuration, reads the images, calls `calib`, prints.
//! `brdf-rig calibrate SESSION` (a capture session folder) is in `calibrate_session.rs`.

use anyhow::{Context, Result, bail};
use brdf_rig::calib::clip::ClipLevel;
use brdf_rig::calib::light::{LightError, OutlineInput, SphereShot, calibrate_light};
use brdf_rig::calib::sphere::{SphereError, SphereOptions};
use brdf_rig::calib::white::{BoardRegion, WhiteOptions, calibrate_irradiance};
use brdf_rig::geometry::camera::Intrinsics;
use brdf_rig::imageio::{DecodedImage, Samples, Transfer};
use clap::{Args, Subcommand, ValueEnum};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

use super::ranges::{Open, Unbounded, real32_in};

/// `brdf-rig calibrate SESSION` calibrates a capture session folder; the subcommands measure
/// images from elsewhere.
#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct CalibrateArgs {
    #[command(subcommand)]
    pub what: Option<CalibrateCommand>,
    #[command(flatten)]
    pub session: super::calibrate_session::SessionArgs,
}

#[derive(Subcommand, Debug)]
pub enum CalibrateCommand {
    /// Light direction from single-light images of a glossy black sphere.
    Sphere(SphereArgs),
    /// Irradiance per colour channel from an image of a white reference board.
    White(WhiteArgs),
}

/// How the stored values of PNG/TIFF files map to radiance.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub enum TransferArg {
    /// Linear codes (RAW-derived 16-bit files); 8-bit files are refused.
    #[default]
    Linear,
    /// The sRGB curve (8-bit camera output, or 16-bit sRGB files).
    Srgb,
}

impl From<TransferArg> for Transfer {
    fn from(t: TransferArg) -> Self {
        match t {
            TransferArg::Linear => Transfer::Linear,
            TransferArg::Srgb => Transfer::Srgb,
        }
    }
}

/// Images: EXR (linear, no clip level unless --saturation), 16-bit PNG/TIFF read as
/// `value / 65535 * scale` (clip level: the largest code), 8-bit sRGB with `--transfer srgb`, or
/// camera RAW (DNG, CR2, NEF, ARW, ...: demosaiced, white-balanced as shot, times `scale`; clip
/// level: the white level).
#[derive(Args, Debug)]
pub struct SphereArgs {
    /// Single-light image of the sphere; repeat for several (combined, with their spread).
    #[arg(long = "image", required = true, value_name = "FILE")]
    pub images: Vec<PathBuf>,
    /// Image to find the sphere's outline in (e.g. under ambient light): one for all light
    /// images, or one per --image. Without it the outline is found in the light image.
    #[arg(long = "outline-image", value_name = "FILE")]
    pub outline_images: Vec<PathBuf>,
    /// The outline as a circle in pixels instead of detecting it: cx,cy,radius.
    #[arg(long, value_name = "CX,CY,R", conflicts_with = "outline_images")]
    pub circle: Option<String>,
    /// Pinhole intrinsics in pixels (COLMAP convention, pixel centres at +0.5), optionally
    /// followed by OPENCV distortion k1,k2,p1,p2.
    #[arg(
        long,
        value_name = "FX,FY,CX,CY[,K1,K2,P1,P2]",
        allow_hyphen_values = true
    )]
    pub intrinsics: String,
    /// Clip level of the camera, in image units (after --scale), > 0. Default: the largest code of
    /// an integer (PNG/TIFF) file, the white level of a RAW file; none for EXR or float TIFF,
    /// which hold linear radiance.
    #[arg(long, value_parser = real32_in(Open(0.0), Unbounded))]
    pub saturation: Option<f32>,
    /// How PNG/TIFF values map to radiance: linear, or the sRGB curve (EXR and RAW are linear).
    #[arg(long, value_enum, default_value_t = TransferArg::Linear)]
    pub transfer: TransferArg,
    /// Normal-incidence Fresnel reflectance of the sphere, to correct the outline for its rim
    /// fading into the backdrop; "none" for a chrome sphere or a matte outline image.
    #[arg(long = "rim-f0", default_value = "0.04", value_name = "F0|none")]
    pub rim_f0: String,
    /// Scale of PNG/TIFF and RAW images (the radiance of the largest code, or of the white
    /// level in green), > 0.
    #[arg(long, default_value_t = 1.0, value_parser = real32_in(Open(0.0), Unbounded))]
    pub scale: f32,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct WhiteArgs {
    /// Linear image of the white board under the single light.
    #[arg(long, value_name = "FILE")]
    pub image: PathBuf,
    /// Albedo of the board: one value, or one per channel r,g,b.
    #[arg(long, value_name = "A|R,G,B")]
    pub albedo: String,
    /// Unit vector towards the light, camera axes (x right, y down, z forward).
    #[arg(long = "light-dir", value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub light_dir: String,
    /// Board normal, camera axes; without it the board is assumed to face the light.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub normal: Option<String>,
    /// Region of interest in pixels: x,y,width,height (default: the board is detected).
    #[arg(long, value_name = "X,Y,W,H")]
    pub roi: Option<String>,
    /// Clip level of the camera, in image units (after --scale), > 0. Default: the largest code of
    /// an integer (PNG/TIFF) file, the white level of a RAW file; none for EXR or float TIFF,
    /// which hold linear radiance.
    #[arg(long, value_parser = real32_in(Open(0.0), Unbounded))]
    pub saturation: Option<f32>,
    /// How PNG/TIFF values map to radiance: linear, or the sRGB curve (EXR and RAW are linear).
    #[arg(long, value_enum, default_value_t = TransferArg::Linear)]
    pub transfer: TransferArg,
    /// Scale of PNG/TIFF and RAW images (the radiance of the largest code, or of the white
    /// level in green), > 0.
    #[arg(long, default_value_t = 1.0, value_parser = real32_in(Open(0.0), Unbounded))]
    pub scale: f32,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: CalibrateArgs) -> Result<()> {
    match args.what {
        Some(CalibrateCommand::Sphere(a)) => sphere(a),
        Some(CalibrateCommand::White(a)) => white(a),
        None => super::calibrate_session::run(args.session),
    }
}

/// Parses `n` comma-separated finite numbers of option `field`.
pub fn parse_numbers(field: &str, text: &str, n: usize, names: &str) -> Result<Vec<f64>> {
    let values: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f64>| v.len() == n && v.iter().all(|x| x.is_finite()))
        .with_context(|| {
            format!("{field}: expected {n} comma-separated numbers {names}, got '{text}'")
        })?;
    Ok(values)
}

fn vector(field: &str, text: &str) -> Result<Vector3<f64>> {
    let v = parse_numbers(field, text, 3, "x,y,z")?;
    let v = Vector3::new(v[0], v[1], v[2]);
    if v.norm() < 1e-12 {
        bail!("{field}: the vector '{text}' is zero");
    }
    Ok(v.normalize())
}

/// Reads an image as radiance (EXR; PNG/TIFF codes through `transfer`, times `scale`; RAW times
/// `scale`); the error names the file.
fn read_image(path: &Path, scale: f32, transfer: TransferArg) -> Result<DecodedImage> {
    if !(scale.is_finite() && scale > 0.0) {
        bail!("--scale: must be a positive number, got {scale}");
    }
    Ok(brdf_rig::imageio::read_image(path, scale, transfer.into())?)
}

/// The clip level of the images: given, or what their files say (the largest code of an integer
/// file, the lowest white level of RAW files; none for floats). Never guessed from the pixels
/// (`calib::clip`). Files of different kinds clip at different levels: the user must then say
/// where.
fn clip_level(given: Option<f32>, files: &[(&Path, Samples)], scale: f32) -> Result<ClipLevel> {
    if let Some(s) = given {
        return Ok(ClipLevel::given(s));
    }
    let Some(&(first_path, first)) = files.first() else {
        bail!("no image given");
    };
    // RAW files of one camera are one kind whatever their white balance (and so clip level).
    let kind = |s: &Samples| match s {
        Samples::Raw { .. } => Samples::Raw { clip: 0.0 },
        other => *other,
    };
    if let Some((p, other)) = files.iter().find(|(_, s)| kind(s) != kind(&first)) {
        bail!(
            "{} holds {other:?} samples but {} holds {first:?}: they clip at different levels; \
             give the camera's clip level with --saturation",
            p.display(),
            first_path.display()
        );
    }
    Ok(match first {
        Samples::Float => ClipLevel::float_file(),
        Samples::Integer { bits } => ClipLevel::integer_file(bits, scale),
        Samples::Raw { .. } => {
            let clip = files
                .iter()
                .filter_map(|(_, s)| match s {
                    Samples::Raw { clip } => Some(*clip),
                    _ => None,
                })
                .fold(f32::INFINITY, f32::min);
            ClipLevel::raw_file(clip, scale)
        }
    })
}

struct SphereConfig {
    /// fx, fy, cx, cy, k1, k2, p1, p2
    k: [f64; 8],
    circle: Option<(f64, f64, f64)>,
    opts: SphereOptions,
}

fn sphere_config(a: &SphereArgs) -> Result<SphereConfig> {
    let k = parse_numbers("--intrinsics", &a.intrinsics, 4, "fx,fy,cx,cy")
        .or_else(|_| parse_numbers("--intrinsics", &a.intrinsics, 8, ""))
        .map_err(|_| {
            anyhow::anyhow!(
                "--intrinsics: expected 4 comma-separated numbers fx,fy,cx,cy, or 8 with the \
                 distortion k1,k2,p1,p2 appended, got '{}'",
                a.intrinsics
            )
        })?;
    if k[0] <= 0.0 || k[1] <= 0.0 {
        bail!(
            "--intrinsics: focal lengths must be positive, got fx {} fy {}",
            k[0],
            k[1]
        );
    }
    let circle = match &a.circle {
        Some(c) => {
            let v = parse_numbers("--circle", c, 3, "cx,cy,radius")?;
            Some((v[0], v[1], v[2]))
        }
        None => None,
    };
    if a.outline_images.len() > 1 && a.outline_images.len() != a.images.len() {
        bail!(
            "--outline-image: give one for all {} images or one per --image, not {}",
            a.images.len(),
            a.outline_images.len()
        );
    }
    let rim_fresnel_f0 = match a.rim_f0.trim() {
        "none" => None,
        t => match t.parse::<f64>() {
            Ok(f) if (0.0..1.0).contains(&f) => Some(f),
            _ => bail!("--rim-f0: expected a reflectance in [0, 1) or 'none', got '{t}'"),
        },
    };
    let mut all = [0.0; 8];
    all[..k.len()].copy_from_slice(&k);
    Ok(SphereConfig {
        k: all,
        circle,
        opts: SphereOptions {
            saturation: a.saturation,
            rim_fresnel_f0,
            ..SphereOptions::default()
        },
    })
}

fn sphere(a: SphereArgs) -> Result<()> {
    let mut cfg = sphere_config(&a)?;
    let read = |p: &PathBuf| read_image(p, a.scale, a.transfer);
    let started = std::time::Instant::now();
    let lights: Vec<DecodedImage> = a.images.iter().map(read).collect::<Result<_>>()?;
    let outlines: Vec<DecodedImage> = a.outline_images.iter().map(read).collect::<Result<_>>()?;
    let read_secs = started.elapsed().as_secs_f64();
    let files: Vec<(&Path, Samples)> = a
        .images
        .iter()
        .zip(&lights)
        .chain(a.outline_images.iter().zip(&outlines))
        .map(|(p, d)| (p.as_path(), d.samples))
        .collect();
    let clip = clip_level(a.saturation, &files, a.scale)?;
    cfg.opts.saturation = clip.value;
    let lights: Vec<_> = lights.into_iter().map(|d| d.image).collect();
    let outlines: Vec<_> = outlines.into_iter().map(|d| d.image).collect();
    let (w, h) = (lights[0].width(), lights[0].height());
    for (p, img) in a
        .images
        .iter()
        .zip(&lights)
        .chain(a.outline_images.iter().zip(&outlines))
    {
        if (img.width(), img.height()) != (w, h) {
            bail!(
                "{}: the image is {}x{}, but {} is {w}x{h}; all sphere images must come from the same camera",
                p.display(),
                img.width(),
                img.height(),
                a.images[0].display()
            );
        }
    }
    let k = cfg.k;
    let mut intr = Intrinsics::pinhole(w, h, k[0], k[1], k[2], k[3]);
    (intr.k1, intr.k2, intr.p1, intr.p2) = (k[4], k[5], k[6], k[7]);
    let shots: Vec<SphereShot> = lights
        .iter()
        .enumerate()
        .map(|(i, light)| SphereShot {
            light,
            outline: match (cfg.circle, outlines.len()) {
                (Some((cx, cy, radius_px)), _) => OutlineInput::Circle { cx, cy, radius_px },
                (None, 0) => OutlineInput::FromLightImage,
                (None, 1) => OutlineInput::Image(&outlines[0]),
                (None, _) => OutlineInput::Image(&outlines[i]),
            },
        })
        .collect();
    let cal = calibrate_light(&shots, &intr, &cfg.opts).map_err(|e| {
        let LightError::Image { index, source } = e else {
            return anyhow::Error::new(e);
        };
        let light = a.images[index].display();
        match (&source, cfg.circle) {
            // the outline was detected and could not be: name the image it was looked for in
            (SphereError::NoSphere { .. } | SphereError::SphereCut { .. }, None) => {
                let outline = match a.outline_images.len() {
                    0 => a.images[index].display(),
                    1 => a.outline_images[0].display(),
                    _ => a.outline_images[index].display(),
                };
                anyhow::Error::new(source).context(format!(
                    "finding the sphere's outline in {outline} (for the light image {light}); if \
                     the whole sphere is in the frame, give its outline by hand: --circle CX,CY,R \
                     (pixels, drawn on its edge)"
                ))
            }
            _ => anyhow::Error::new(source).context(format!("calibrating the light from {light}")),
        }
    })?;
    let warnings: Vec<String> = a
        .images
        .iter()
        .zip(&cal.per_image)
        .flat_map(|(p, s)| {
            s.warnings
                .iter()
                .map(move |w| format!("{}: {w}", p.display()))
        })
        .collect();
    for w in &warnings {
        errln!("warning: {w}");
    }
    let d = cal.dir_camera;
    let seconds = StageSeconds(vec![
        ("read", read_secs),
        (
            "outline",
            cal.per_image.iter().map(|s| s.outline_secs).sum(),
        ),
        (
            "highlight",
            cal.per_image.iter().map(|s| s.highlight_secs).sum(),
        ),
    ]);
    if a.json {
        let images: Vec<serde_json::Value> = a
            .images
            .iter()
            .zip(&cal.per_image)
            .map(|(p, s)| {
                serde_json::json!({
                    "image": p.display().to_string(),
                    "light_dir_camera": [s.dir_camera.x, s.dir_camera.y, s.dir_camera.z],
                    "uncertainty_deg": s.uncertainty_rad.to_degrees(),
                    "highlight_px": s.highlight.centroid_px,
                    "highlight_pixels": s.highlight.pixels,
                    "highlight_saturated_pixels": s.highlight.saturated_pixels,
                    "highlight_width_px": s.highlight.width_px,
                    "highlight_normal_uncertainty_deg": s.highlight.uncertainty_rad.to_degrees(),
                    "sphere_centre_px": s.outline.centre_px,
                    "sphere_radius_px": s.outline.radius_px,
                    "edge_points": s.outline.edge_points,
                    "outline_rms_px": s.outline.rms_residual_rad * 0.5 * (intr.fx + intr.fy),
                    "warnings": s.warnings,
                })
            })
            .collect();
        let out = serde_json::json!({
            "axes": "camera: x right, y down, z forward; unit vector towards the light",
            "light_dir_camera": [d.x, d.y, d.z],
            "uncertainty_deg": cal.uncertainty_deg,
            "spread_deg": cal.spread_deg,
            "std_error_deg": cal.std_error_deg,
            "fit_uncertainty_deg": cal.fit_uncertainty_deg,
            "clip_level": clip,
            "clip_level_reason": clip.to_string(),
            "warnings": warnings,
            "images": images,
            "seconds": seconds.json(),
        });
        outln!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        outln!(
            "light direction (towards the light; camera axes x right, y down, z forward): \
             {:.6} {:.6} {:.6}",
            d.x,
            d.y,
            d.z
        );
        outln!(
            "uncertainty {:.3} deg (RMS angle to the truth; spread {:.3} deg over {} image(s), fit {:.3} deg)",
            cal.uncertainty_deg,
            cal.spread_deg,
            cal.per_image.len(),
            cal.fit_uncertainty_deg
        );
        outln!("clip level: {clip}");
        for (p, s) in a.images.iter().zip(&cal.per_image) {
            outln!(
                "  {}: highlight at ({:.2}, {:.2}) px ({} px, {} clipped), sphere centre ({:.2}, {:.2}) px, radius {:.2} px, {} edge points",
                p.display(),
                s.highlight.centroid_px[0],
                s.highlight.centroid_px[1],
                s.highlight.pixels,
                s.highlight.saturated_pixels,
                s.outline.centre_px[0],
                s.outline.centre_px[1],
                s.outline.radius_px,
                s.outline.edge_points
            );
        }
        outln!("{seconds}");
    }
    Ok(())
}

/// Wall time of a command's stages, for its report ("time: read 1.20 s, outline 0.80 s").
struct StageSeconds(Vec<(&'static str, f64)>);

impl StageSeconds {
    fn json(&self) -> serde_json::Value {
        serde_json::Value::Object(
            self.0
                .iter()
                .map(|(k, v)| ((*k).to_string(), serde_json::json!(v)))
                .collect(),
        )
    }
}

impl std::fmt::Display for StageSeconds {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let parts: Vec<String> = self
            .0
            .iter()
            .map(|(k, v)| format!("{k} {v:.2} s"))
            .collect();
        write!(f, "time: {}", parts.join(", "))
    }
}

struct WhiteConfig {
    albedo: [f64; 3],
    light_dir: Vector3<f64>,
    normal: Option<Vector3<f64>>,
    region: BoardRegion,
    opts: WhiteOptions,
}

fn white_config(a: &WhiteArgs) -> Result<WhiteConfig> {
    let albedo = match parse_numbers("--albedo", &a.albedo, 1, "a") {
        Ok(v) => [v[0]; 3],
        Err(_) => {
            let v = parse_numbers("--albedo", &a.albedo, 3, "r,g,b (or one value)")?;
            [v[0], v[1], v[2]]
        }
    };
    if albedo.iter().any(|x| !(*x > 0.0 && *x <= 1.5)) {
        bail!(
            "--albedo: each value must be in (0, 1.5], got '{}'",
            a.albedo
        );
    }
    let light_dir = vector("--light-dir", &a.light_dir)?;
    let normal = a
        .normal
        .as_deref()
        .map(|n| vector("--normal", n))
        .transpose()?;
    let region = match &a.roi {
        Some(r) => {
            let v = parse_numbers("--roi", r, 4, "x,y,width,height")?;
            if v.iter().any(|x| *x < 0.0 || x.fract() != 0.0) {
                bail!("--roi: expected non-negative whole pixels, got '{r}'");
            }
            BoardRegion::Roi {
                x: v[0] as usize,
                y: v[1] as usize,
                width: v[2] as usize,
                height: v[3] as usize,
            }
        }
        None => BoardRegion::Detect,
    };
    Ok(WhiteConfig {
        albedo,
        light_dir,
        normal,
        region,
        opts: WhiteOptions {
            saturation: a.saturation,
            ..WhiteOptions::default()
        },
    })
}

fn white(a: WhiteArgs) -> Result<()> {
    let mut cfg = white_config(&a)?;
    let started = std::time::Instant::now();
    let decoded = read_image(&a.image, a.scale, a.transfer)?;
    let read_secs = started.elapsed().as_secs_f64();
    let clip = clip_level(a.saturation, &[(&a.image, decoded.samples)], a.scale)?;
    cfg.opts.saturation = clip.value;
    let r = calibrate_irradiance(
        &decoded.image,
        cfg.albedo,
        &cfg.light_dir,
        cfg.normal.as_ref(),
        &cfg.region,
        &cfg.opts,
    )
    .with_context(|| format!("measuring the irradiance from {}", a.image.display()))?;
    for w in &r.warnings {
        errln!("warning: {w}");
    }
    let seconds = StageSeconds(vec![
        ("read", read_secs),
        ("detect", r.detect_secs),
        ("fit", r.fit_secs),
    ]);
    if a.json {
        let out = serde_json::json!({
            "image": a.image.display().to_string(),
            "irradiance": r.irradiance,
            "irradiance_std_error": r.std_error,
            "radiance": r.radiance,
            "cos_theta": r.cos_theta,
            "normal_assumed": r.normal_assumed,
            "pixels_used": r.pixels_used,
            "pixels_on_board": r.pixels_on_board,
            "sample_stride": r.sample_stride,
            "pixels_saturated": r.pixels_saturated,
            "region": r.region,
            "flat_field_cells": r.flat_field.cells,
            "flat_field_spread": r.flat_field.spread,
            "clip_level": clip,
            "clip_level_reason": clip.to_string(),
            "warnings": r.warnings,
            "seconds": seconds.json(),
        });
        outln!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        let [er, eg, eb] = r.irradiance;
        outln!("irradiance (R G B): {er:.6} {eg:.6} {eb:.6}");
        outln!(
            "  standard error {:.2e} {:.2e} {:.2e}; board radiance {:.6} {:.6} {:.6}",
            r.std_error[0],
            r.std_error[1],
            r.std_error[2],
            r.radiance[0],
            r.radiance[1],
            r.radiance[2]
        );
        let sampled = if r.sample_stride > 1 {
            format!(
                " (read every {} px of {} on the board)",
                r.sample_stride, r.pixels_on_board
            )
        } else {
            String::new()
        };
        outln!(
            "  cos(theta) {:.4}{}; {} pixels used{sampled}, {} clipped; flat-field spread {:.2} %",
            r.cos_theta,
            if r.normal_assumed {
                " (assumed: no --normal)"
            } else {
                ""
            },
            r.pixels_used,
            r.pixels_saturated,
            100.0 * r.flat_field.spread
        );
        outln!("  clip level: {clip}");
        outln!("  {seconds}");
    }
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn numbers_are_validated_with_the_field_name() {
        assert_eq!(
            parse_numbers("--x", "1, 2.5,-3", 3, "a,b,c").ok(),
            Some(vec![1.0, 2.5, -3.0])
        );
        let e = parse_numbers("--intrinsics", "1,2", 4, "fx,fy,cx,cy").unwrap_err();
        assert!(e.to_string().starts_with("--intrinsics: expected 4"));
        assert!(parse_numbers("--x", "1,nan,2", 3, "").is_err());
        assert!(vector("--normal", "0,0,0").is_err());
    }
}
