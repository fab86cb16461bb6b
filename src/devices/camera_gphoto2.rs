//! A DSLR (or any camera libgphoto2 drives) through the `gphoto2` command line: set shutter speed
//! and ISO, capture, download the RAW file, decode it to linear RGB (`imageio::raw`).
//!
//! Why the command line and not libgphoto2: no C bindings to build, and `gphoto2` is what
//! operators already use to check their camera. Each shot is one process:
//! `gphoto2 [--port P] --set-config shutterspeed=1/60 --set-config iso=100
//!  --capture-image-and-download --force-overwrite --filename DIR/brdf-rig-shot.%C`.
//! Exposure and ISO snap to the camera's usual third-stop values; the metadata reports the
//! values actually set, so radiance scaling uses them.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::{Camera, DeviceError, ShotMetadata, ShotSettings};
use crate::imageio::raw::decode_raw_file;
use crate::render::image::LinearImage;

/// Settings of the gphoto2 backend.
#[derive(Clone, Debug, PartialEq)]
pub struct Gphoto2Config {
    /// The `gphoto2` program (a path, or a name looked up in PATH).
    pub program: PathBuf,
    /// `--port`, e.g. `usb:001,004`; none = the first camera found.
    pub port: Option<String>,
    /// Config keys for shutter speed and ISO (Canon and Nikon bodies use these names).
    pub shutter_key: String,
    pub iso_key: String,
    /// Further `--set-config key=value` pairs, e.g. `imageformat=RAW`.
    pub extra_config: Vec<(String, String)>,
    /// Where downloads land before decoding (a private temporary folder by default).
    pub download_dir: PathBuf,
    /// Longest a shot may take beyond its exposure.
    pub timeout: Duration,
}

impl Gphoto2Config {
    pub fn new(download_dir: PathBuf) -> Self {
        Self {
            program: PathBuf::from("gphoto2"),
            port: None,
            shutter_key: "shutterspeed".into(),
            iso_key: "iso".into(),
            extra_config: Vec::new(),
            download_dir,
            timeout: Duration::from_secs(30),
        }
    }
}

/// Shutter speeds in third stops from 30 s to 1/8000 s, as cameras name them.
const SHUTTER_SPEEDS: &[(&str, f64)] = &[
    ("30", 30.0),
    ("25", 25.0),
    ("20", 20.0),
    ("15", 15.0),
    ("13", 13.0),
    ("10", 10.0),
    ("8", 8.0),
    ("6", 6.0),
    ("5", 5.0),
    ("4", 4.0),
    ("3.2", 3.2),
    ("2.5", 2.5),
    ("2", 2.0),
    ("1.6", 1.6),
    ("1.3", 1.3),
    ("1", 1.0),
    ("0.8", 0.8),
    ("0.6", 0.6),
    ("0.5", 0.5),
    ("0.4", 0.4),
    ("0.3", 0.3),
    ("1/4", 0.25),
    ("1/5", 0.2),
    ("1/6", 1.0 / 6.0),
    ("1/8", 0.125),
    ("1/10", 0.1),
    ("1/13", 1.0 / 13.0),
    ("1/15", 1.0 / 15.0),
    ("1/20", 0.05),
    ("1/25", 0.04),
    ("1/30", 1.0 / 30.0),
    ("1/40", 0.025),
    ("1/50", 0.02),
    ("1/60", 1.0 / 60.0),
    ("1/80", 0.0125),
    ("1/100", 0.01),
    ("1/125", 0.008),
    ("1/160", 1.0 / 160.0),
    ("1/200", 0.005),
    ("1/250", 0.004),
    ("1/320", 1.0 / 320.0),
    ("1/400", 0.0025),
    ("1/500", 0.002),
    ("1/640", 1.0 / 640.0),
    ("1/800", 0.00125),
    ("1/1000", 0.001),
    ("1/1250", 0.0008),
    ("1/1600", 0.000625),
    ("1/2000", 0.0005),
    ("1/2500", 0.0004),
    ("1/3200", 0.0003125),
    ("1/4000", 0.00025),
    ("1/5000", 0.0002),
    ("1/6400", 0.000156_25),
    ("1/8000", 0.000125),
];

const ISOS: &[u32] = &[
    100, 125, 160, 200, 250, 320, 400, 500, 640, 800, 1000, 1250, 1600, 2000, 2500, 3200, 6400,
];

/// The camera's shutter-speed value nearest (in stops) to `secs`, and its duration.
pub fn shutter_speed(secs: f64) -> (&'static str, f64) {
    let mut best = SHUTTER_SPEEDS[0];
    for &s in SHUTTER_SPEEDS {
        if (s.1.ln() - secs.ln()).abs() < (best.1.ln() - secs.ln()).abs() {
            best = s;
        }
    }
    best
}

/// The ISO nearest (in stops) to `gain` x 100.
pub fn iso_for_gain(gain: f64) -> u32 {
    let want = (gain.max(1e-3) * 100.0).ln();
    let mut best = ISOS[0];
    for &i in ISOS {
        if (f64::from(i).ln() - want).abs() < (f64::from(best).ln() - want).abs() {
            best = i;
        }
    }
    best
}

/// A DSLR driven by `gphoto2`.
pub struct Gphoto2Camera {
    config: Gphoto2Config,
}

/// The file name pattern passed to `--filename` (gphoto2 replaces `%C` by the suffix).
pub const DOWNLOAD_STEM: &str = "brdf-rig-shot";

impl Gphoto2Camera {
    pub fn new(config: Gphoto2Config) -> Self {
        Self { config }
    }

    /// The argument list of one capture (without the program name). Pure, for tests.
    pub fn capture_args(&self, settings: ShotSettings) -> Vec<String> {
        let c = &self.config;
        let mut args = Vec::new();
        if let Some(port) = &c.port {
            args.push("--port".to_string());
            args.push(port.clone());
        }
        let (speed, _) = shutter_speed(settings.exposure_secs);
        for (k, v) in c
            .extra_config
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .chain([
                (c.shutter_key.clone(), speed.to_string()),
                (c.iso_key.clone(), iso_for_gain(settings.gain).to_string()),
            ])
        {
            args.push("--set-config".to_string());
            args.push(format!("{k}={v}"));
        }
        args.push("--capture-image-and-download".to_string());
        args.push("--force-overwrite".to_string());
        args.push("--filename".to_string());
        args.push(
            c.download_dir
                .join(format!("{DOWNLOAD_STEM}.%C"))
                .display()
                .to_string(),
        );
        args
    }

    fn device_name(&self) -> String {
        format!(
            "gphoto2 camera{}",
            self.config
                .port
                .as_ref()
                .map(|p| format!(" on {p}"))
                .unwrap_or_default()
        )
    }

    fn fail(&self, reason: String) -> DeviceError {
        DeviceError::Other {
            device: self.device_name(),
            reason,
        }
    }

    /// The downloaded RAW file (not a JPEG a RAW+JPEG body also sends).
    fn find_download(&self) -> Option<PathBuf> {
        let entries = std::fs::read_dir(&self.config.download_dir).ok()?;
        let mut found: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                p.file_stem().and_then(|s| s.to_str()) == Some(DOWNLOAD_STEM)
                    && !matches!(
                        p.extension()
                            .and_then(|e| e.to_str())
                            .map(str::to_ascii_lowercase)
                            .as_deref(),
                        Some("jpg" | "jpeg")
                    )
            })
            .collect();
        found.sort();
        found.pop()
    }

    fn clear_downloads(&self) {
        if let Ok(entries) = std::fs::read_dir(&self.config.download_dir) {
            for e in entries.flatten() {
                if e.path().file_stem().and_then(|s| s.to_str()) == Some(DOWNLOAD_STEM) {
                    let _ = std::fs::remove_file(e.path());
                }
            }
        }
    }
}

/// Runs a command with a deadline; returns its stdout and stderr.
fn run_with_timeout(
    cmd: &mut Command,
    timeout: Duration,
) -> std::io::Result<(bool, String, String)> {
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()?;
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait()? {
            let out = child.wait_with_output()?;
            return Ok((
                status.success(),
                String::from_utf8_lossy(&out.stdout).into_owned(),
                String::from_utf8_lossy(&out.stderr).into_owned(),
            ));
        }
        if start.elapsed() > timeout {
            let _ = child.kill();
            let _ = child.wait();
            return Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!("no answer after {:.0} s", timeout.as_secs_f64()),
            ));
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

impl Camera for Gphoto2Camera {
    fn capture(
        &mut self,
        settings: ShotSettings,
    ) -> Result<(LinearImage, ShotMetadata), DeviceError> {
        std::fs::create_dir_all(&self.config.download_dir).map_err(|e| {
            self.fail(format!(
                "creating the download folder {}: {e}",
                self.config.download_dir.display()
            ))
        })?;
        self.clear_downloads();
        let args = self.capture_args(settings);
        let (_, exposure) = shutter_speed(settings.exposure_secs);
        let iso = iso_for_gain(settings.gain);
        let timeout = self.config.timeout + Duration::from_secs_f64(exposure);
        let mut cmd = Command::new(&self.config.program);
        cmd.args(&args);
        let (ok, stdout, stderr) = run_with_timeout(&mut cmd, timeout).map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                DeviceError::Disconnected {
                    device: self.device_name(),
                    reason: format!(
                        "`{}` is not installed (Debian: apt-get install gphoto2)",
                        self.config.program.display()
                    ),
                }
            } else if e.kind() == std::io::ErrorKind::TimedOut {
                DeviceError::Timeout {
                    device: self.device_name(),
                    attempts: 1,
                    what: format!("capture: {e}"),
                }
            } else {
                self.fail(format!("running {}: {e}", self.config.program.display()))
            }
        })?;
        if !ok {
            let msg = stderr
                .lines()
                .chain(stdout.lines())
                .filter(|l| !l.trim().is_empty())
                .collect::<Vec<_>>()
                .join(" | ");
            return Err(
                if msg.contains("No camera found") || msg.contains("Could not detect") {
                    DeviceError::Disconnected {
                        device: self.device_name(),
                        reason: msg,
                    }
                } else {
                    self.fail(format!("gphoto2 failed: {msg}"))
                },
            );
        }
        let file = self.find_download().ok_or_else(|| {
            self.fail(format!(
                "gphoto2 reported success but no {DOWNLOAD_STEM}.* file is in {}",
                self.config.download_dir.display()
            ))
        })?;
        let lin = decode_raw_file(&file).map_err(|e| self.fail(e.to_string()))?;
        self.clear_downloads();
        Ok((
            lin.image,
            ShotMetadata {
                exposure_secs: exposure,
                gain: f64::from(iso) / 100.0,
                saturation: lin.saturation,
                device: format!("gphoto2 {} {}", lin.make, lin.model),
            },
        ))
    }
}

/// Cameras `gphoto2 --auto-detect` lists, as `(model, port)`.
pub fn parse_auto_detect(output: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut past_rule = false;
    for line in output.lines() {
        if line.trim_start().starts_with("---") {
            past_rule = true;
            continue;
        }
        if !past_rule || line.trim().is_empty() {
            continue;
        }
        // "Canon EOS 5D Mark III          usb:001,004": the port is the last field.
        let trimmed = line.trim_end();
        if let Some(split) = trimmed.rfind(char::is_whitespace) {
            let (model, port) = trimmed.split_at(split);
            out.push((model.trim().to_string(), port.trim().to_string()));
        }
    }
    out
}

/// Why the attached cameras could not be listed.
#[derive(Debug, thiserror::Error)]
pub enum ListError {
    #[error("gphoto2 --auto-detect failed: {stderr}")]
    Failed { stderr: String },
    #[error("`{}` is not installed (Debian: apt-get install gphoto2)", program.display())]
    NotInstalled { program: std::path::PathBuf },
    #[error("running {}: {source}", program.display())]
    Run {
        program: std::path::PathBuf,
        source: std::io::Error,
    },
}

/// Lists attached cameras; an error says why listing was impossible (e.g. gphoto2 missing).
pub fn list(program: &Path) -> Result<Vec<(String, String)>, ListError> {
    let mut cmd = Command::new(program);
    cmd.arg("--auto-detect");
    match run_with_timeout(&mut cmd, Duration::from_secs(10)) {
        Ok((true, stdout, _)) => Ok(parse_auto_detect(&stdout)),
        Ok((false, _, stderr)) => Err(ListError::Failed {
            stderr: stderr.trim().to_string(),
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(ListError::NotInstalled {
            program: program.to_path_buf(),
        }),
        Err(source) => Err(ListError::Run {
            program: program.to_path_buf(),
            source,
        }),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    #[test]
    fn listing_without_gphoto2_names_the_program_and_the_package() {
        let e = list(Path::new("/nonexistent/gphoto2")).unwrap_err();
        assert!(matches!(e, ListError::NotInstalled { .. }), "{e:?}");
        assert_eq!(
            e.to_string(),
            "`/nonexistent/gphoto2` is not installed (Debian: apt-get install gphoto2)"
        );
    }

    use super::*;
    use crate::imageio::dng::write_minimal_dng;

    #[test]
    fn command_line_sets_exposure_and_iso_and_downloads_to_the_folder() {
        let mut cfg = Gphoto2Config::new(PathBuf::from("/tmp/dl"));
        cfg.port = Some("usb:001,004".into());
        cfg.extra_config = vec![("imageformat".into(), "RAW".into())];
        let cam = Gphoto2Camera::new(cfg);
        let args = cam.capture_args(ShotSettings {
            exposure_secs: 0.016,
            gain: 2.0,
        });
        assert_eq!(
            args,
            [
                "--port",
                "usb:001,004",
                "--set-config",
                "imageformat=RAW",
                "--set-config",
                "shutterspeed=1/60",
                "--set-config",
                "iso=200",
                "--capture-image-and-download",
                "--force-overwrite",
                "--filename",
                "/tmp/dl/brdf-rig-shot.%C",
            ]
        );
    }

    #[test]
    fn exposures_snap_to_third_stops() {
        assert_eq!(shutter_speed(1.0 / 60.0).0, "1/60");
        assert_eq!(shutter_speed(0.0041).0, "1/250");
        assert_eq!(shutter_speed(100.0).0, "30");
        assert_eq!(shutter_speed(1e-6).0, "1/8000");
        assert_eq!(iso_for_gain(1.0), 100);
        assert_eq!(iso_for_gain(16.0), 1600);
        assert_eq!(iso_for_gain(0.01), 100);
    }

    #[test]
    fn auto_detect_output_is_parsed() {
        let out = "Model                          Port\n----------------------------------------------------------\nCanon EOS 5D Mark III          usb:001,004\nNikon DSC D850                 usb:002,003\n";
        assert_eq!(
            parse_auto_detect(out),
            vec![
                (
                    "Canon EOS 5D Mark III".to_string(),
                    "usb:001,004".to_string()
                ),
                ("Nikon DSC D850".to_string(), "usb:002,003".to_string())
            ]
        );
        assert!(parse_auto_detect("Model Port\n------\n").is_empty());
    }

    /// Up to the device boundary: a stand-in `gphoto2` script that checks its arguments and
    /// "downloads" a DNG; the backend must decode it.
    #[cfg(unix)]
    #[test]
    fn capture_runs_the_program_and_decodes_the_download() {
        use std::os::unix::fs::PermissionsExt;
        let tmp = tempfile::tempdir().unwrap();
        let dng = tmp.path().join("fixture.dng");
        std::fs::write(
            &dng,
            write_minimal_dng(8, 6, &[3000; 48], 1000, 5000, [1.0, 1.0, 1.0]),
        )
        .unwrap();
        let script = tmp.path().join("gphoto2");
        std::fs::write(
            &script,
            format!(
                "#!/bin/sh\nout=\"\"\nseen=0\nwhile [ $# -gt 0 ]; do\n  case \"$1\" in\n    --filename) out=\"$2\"; shift;;\n    shutterspeed=1/250) seen=1;;\n  esac\n  shift\ndone\n[ $seen = 1 ] || {{ echo 'wrong shutter' >&2; exit 3; }}\ncp {} \"$(echo \"$out\" | sed 's/%C/dng/')\"\n",
                dng.display()
            ),
        )
        .unwrap();
        std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
        let mut cfg = Gphoto2Config::new(tmp.path().join("dl"));
        cfg.program = script;
        let mut cam = Gphoto2Camera::new(cfg);
        let (img, meta) = cam
            .capture(ShotSettings {
                exposure_secs: 0.004,
                gain: 1.0,
            })
            .unwrap();
        assert_eq!((img.width(), img.height()), (8, 6));
        assert!(img.data().iter().all(|&v| (v - 0.5).abs() < 1e-6));
        assert_eq!(meta.exposure_secs, 0.004);
        assert!(meta.device.contains("test sensor"));
        // a wrong exposure makes the stand-in fail: the error carries its message
        let err = cam
            .capture(ShotSettings {
                exposure_secs: 1.0,
                gain: 1.0,
            })
            .unwrap_err()
            .to_string();
        assert!(err.contains("wrong shutter"), "{err}");
        // a missing program is a clear "not installed"
        let mut cfg = Gphoto2Config::new(tmp.path().join("dl"));
        cfg.program = tmp.path().join("no-such-gphoto2");
        let err = Gphoto2Camera::new(cfg)
            .capture(ShotSettings {
                exposure_secs: 0.01,
                gain: 1.0,
            })
            .unwrap_err()
            .to_string();
        assert!(err.contains("not installed"), "{err}");
    }
}
