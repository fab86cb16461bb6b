//! Rig profiles: the TOML file that says how to reach the rig and what it may do (serial port,
//! turntable limits, light channels with their directions). `rig-profiles/simulated.toml` is
//! built into the binary as the default.
//!
//! Sections owned here (`[serial]`, `[turntable]`, `[light]`, `[sim]`) reject unknown keys, so a
//! typo is an error, not a silently ignored setting. Other top-level sections (capture's
//! `[camera]`, calibration's `[calibration]`) are ignored here; their owners parse them from
//! [`Profile::source`] with their own types. Errors name the file, the line and the key.
//!
//! Units: degrees and seconds-based rates as an operator writes them (`*_deg`, `*_deg_s`,
//! `*_deg_s2`), durations in milliseconds (`*_ms`), light levels in [0, 1].
//! Must not open ports or spawn anything (that is `devices::rig`).

use std::path::{Path, PathBuf};

use serde::Deserialize;
use thiserror::Error;

/// The built-in simulated profile (`rig-profiles/simulated.toml`).
pub const SIMULATED: &str = include_str!("../rig-profiles/simulated.toml");
/// Name under which the built-in profile appears in messages.
pub const SIMULATED_NAME: &str = "<built-in rig-profiles/simulated.toml>";
/// Name of [`Profile::real_board_defaults`] in messages.
pub const REAL_BOARD_NAME: &str =
    "<built-in defaults for a real board: simulated.toml's rig with example-real.toml's [serial]>";

#[derive(Debug, Error)]
pub enum ProfileError {
    #[error("cannot read rig profile {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{file}:{line}: {key}: {message}")]
    Parse {
        file: String,
        line: usize,
        key: String,
        message: String,
    },
    #[error("{file}:{line}: {key}: {reason}")]
    Invalid {
        file: String,
        line: usize,
        key: String,
        reason: String,
    },
    /// Another module's section was asked for and the file is not TOML.
    #[error("{origin}: {source}")]
    Toml {
        origin: String,
        #[source]
        source: Box<toml::de::Error>,
    },
    /// Another module's section (`[camera]`, `[scene]`) does not fit that module's type.
    #[error("{origin}: [{section}]: {source}")]
    Section {
        origin: String,
        section: String,
        #[source]
        source: Box<toml::de::Error>,
    },
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SerialSection {
    /// A device path, or `"sim"` for the in-process simulated firmware.
    pub port: String,
    #[serde(default = "default_baud")]
    pub baud: u32,
    pub timeout_ms: u64,
    pub retries: u32,
    #[serde(default = "default_reconnect")]
    pub reconnect_ms: u64,
    #[serde(default = "default_watchdog")]
    pub watchdog_ms: u16,
    /// How long after opening the port the board may stay silent while it boots (an Arduino
    /// resets when its port opens and its bootloader holds the UART for 1-2 s): requests are
    /// re-sent every `timeout_ms` for this long before `retries` start counting. Default
    /// [`DEFAULT_BOOT_WINDOW_MS`] for a real board's profile, 0 for `port = "sim"`.
    #[serde(default)]
    pub boot_window_ms: Option<u64>,
}

/// The boot window of a real board when the profile does not give one: an Arduino Mega's
/// bootloader holds the UART for about 1-2 s after the reset that opening the port causes.
pub const DEFAULT_BOOT_WINDOW_MS: u64 = 2500;

fn default_baud() -> u32 {
    115_200
}
fn default_reconnect() -> u64 {
    3000
}
fn default_watchdog() -> u16 {
    2000
}
fn default_poll() -> u64 {
    2
}
fn default_warmup_timeout() -> u64 {
    3000
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TurntableSection {
    pub max_speed_deg_s: f64,
    pub max_accel_deg_s2: f64,
    pub min_angle_deg: f64,
    pub max_angle_deg: f64,
    pub steps_per_rev: u32,
    #[serde(default = "default_poll")]
    pub poll_ms: u64,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ChannelSection {
    pub name: String,
    /// Highest level the driver will send, in (0, 1].
    pub max_level: f64,
    /// Around the turntable axis from the camera's direction, counter-clockwise seen from above.
    pub azimuth_deg: f64,
    /// Above the horizontal plane through the object's centre.
    pub elevation_deg: f64,
}

impl ChannelSection {
    /// Unit vector towards the light in the lab frame: +z up (the turntable axis), +x towards
    /// the camera (horizontally), +y = z cross x.
    pub fn direction_lab(&self) -> [f64; 3] {
        let (az, el) = (
            self.azimuth_deg.to_radians(),
            self.elevation_deg.to_radians(),
        );
        [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()]
    }
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LightSection {
    #[serde(default = "default_warmup_timeout")]
    pub warmup_timeout_ms: u64,
    pub channels: Vec<ChannelSection>,
}

/// Settings of the simulated firmware (used only with `port = "sim"`).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct SimSection {
    pub warmup_ms: u32,
    pub drop_rate: f64,
    pub corrupt_rate: f64,
    pub seed: u64,
    /// The simulated board ignores what it receives for this long after it starts (or comes
    /// back after an unplug), as a bootloader would.
    pub boot_delay_ms: u32,
}

impl Default for SimSection {
    fn default() -> SimSection {
        SimSection {
            warmup_ms: 50,
            drop_rate: 0.0,
            corrupt_rate: 0.0,
            seed: 1,
            boot_delay_ms: 0,
        }
    }
}

/// The version of the profile format this tool reads; a profile without `format_version` is
/// version 1.
pub const PROFILE_FORMAT_VERSION: u32 = 1;

/// The sections of the file this module owns; unknown top-level sections are ignored.
#[derive(Clone, Debug, Deserialize, PartialEq)]
struct Sections {
    #[serde(default = "crate::format::version_1")]
    format_version: u32,
    serial: SerialSection,
    turntable: TurntableSection,
    light: LightSection,
    #[serde(default)]
    sim: SimSection,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    /// Where it came from (a path, or [`SIMULATED_NAME`]), for messages.
    pub origin: String,
    /// The whole file, for the sections other modules own.
    pub source: String,
    pub serial: SerialSection,
    pub turntable: TurntableSection,
    pub light: LightSection,
    pub sim: SimSection,
}

impl Profile {
    /// The built-in simulated rig.
    pub fn simulated() -> Result<Profile, ProfileError> {
        Profile::parse(SIMULATED, SIMULATED_NAME)
    }

    /// A board on a port given without a profile: the built-in rig description (turntable and
    /// light channels of `simulated.toml`) with the serial timing of a real board (the
    /// `[serial]` section of `rig-profiles/example-real.toml`: 200 ms per reply, 5 re-sends, 10 s
    /// to re-open a vanished port, and the default boot window), not the simulator's.
    pub fn real_board_defaults(port: &Path) -> Result<Profile, ProfileError> {
        let quoted = toml::Value::String(port.display().to_string()).to_string();
        let serial = format!(
            "[serial]\n\
             # --port without --profile: a real board's timing (rig-profiles/example-real.toml)\n\
             port = {quoted}\n\
             baud = {}\n\
             timeout_ms = 200\n\
             retries = 5\n\
             reconnect_ms = 10000\n\
             watchdog_ms = {}\n\
             boot_window_ms = {DEFAULT_BOOT_WINDOW_MS}\n\n",
            default_baud(),
            default_watchdog()
        );
        // The built-in profile's [serial] section is the first table, [turntable] the second.
        let rest = SIMULATED
            .find("[turntable]")
            .map(|i| &SIMULATED[i..])
            .unwrap_or(SIMULATED);
        Profile::parse(&format!("{serial}{rest}"), REAL_BOARD_NAME)
    }

    /// The boot window (see [`SerialSection::boot_window_ms`]): the profile's, else 0 for the
    /// simulated rig's profile (its firmware runs before its port exists) and
    /// [`DEFAULT_BOOT_WINDOW_MS`] for a profile of a real board.
    pub fn boot_window_ms(&self) -> u64 {
        self.serial
            .boot_window_ms
            .unwrap_or(if self.is_simulated() {
                0
            } else {
                DEFAULT_BOOT_WINDOW_MS
            })
    }

    /// The top-level section `key` of the profile, parsed by the module that owns it (the rig
    /// driver ignores it); `T::default()` when the profile has none. Other sections' keys do not
    /// matter.
    pub fn section<T: serde::de::DeserializeOwned + Default>(
        &self,
        key: &str,
    ) -> Result<T, ProfileError> {
        parse_section(&self.source, &self.origin, key)
    }

    /// The profile a rig command uses: the file given, else the built-in rig with a real board's
    /// timing when only a port is given ([`Profile::real_board_defaults`]), else the built-in
    /// simulated rig.
    pub fn chosen(file: Option<&Path>, port: Option<&Path>) -> Result<Profile, ProfileError> {
        match (file, port) {
            (Some(p), _) => Profile::load(p),
            (None, Some(port)) => Profile::real_board_defaults(port),
            (None, None) => Profile::simulated(),
        }
    }

    pub fn load(path: &Path) -> Result<Profile, ProfileError> {
        let text = std::fs::read_to_string(path).map_err(|source| ProfileError::Read {
            path: path.to_owned(),
            source,
        })?;
        // Absolute, as the session header records it: a path relative to the caller's folder
        // means nothing to a reader elsewhere.
        let origin = std::path::absolute(path).unwrap_or_else(|_| path.to_owned());
        Profile::parse(&text, &origin.display().to_string())
    }

    /// Parses and validates profile text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Profile, ProfileError> {
        let s: Sections = toml::from_str(text).map_err(|e| {
            let (line, key) = match e.span() {
                Some(span) => locate(text, span.start),
                None => (0, String::from("(file)")),
            };
            ProfileError::Parse {
                file: origin.to_owned(),
                line,
                key,
                message: e.message().trim().to_owned(),
            }
        })?;
        if s.format_version != PROFILE_FORMAT_VERSION {
            return Err(ProfileError::Invalid {
                file: origin.to_owned(),
                line: text
                    .lines()
                    .position(|l| l.trim_start().starts_with("format_version"))
                    .map_or(0, |i| i + 1),
                key: "format_version".into(),
                reason: format!(
                    "version {}, but this brdf-rig reads profile version {PROFILE_FORMAT_VERSION}",
                    s.format_version
                ),
            });
        }
        let p = Profile {
            origin: origin.to_owned(),
            source: text.to_owned(),
            serial: s.serial,
            turntable: s.turntable,
            light: s.light,
            sim: s.sim,
        };
        p.validate()?;
        Ok(p)
    }

    /// True when the port is the in-process simulated firmware.
    pub fn is_simulated(&self) -> bool {
        self.serial.port == "sim"
    }

    fn invalid(&self, section: &str, key: &str, reason: String) -> ProfileError {
        ProfileError::Invalid {
            file: self.origin.clone(),
            line: line_of_key(&self.source, section, key),
            key: format!("{section}.{key}"),
            reason,
        }
    }

    fn validate(&self) -> Result<(), ProfileError> {
        let s = &self.serial;
        if s.port.trim().is_empty() {
            return Err(self.invalid("serial", "port", "empty port path".into()));
        }
        let int = |section: &str, key: &str, v: u64, lo: u64, hi: u64, why: &str| {
            if (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(self.invalid(section, key, format!("{v}: must be in [{lo}, {hi}]{why}")))
            }
        };
        int("serial", "baud", s.baud.into(), 300, 4_000_000, "")?;
        int("serial", "timeout_ms", s.timeout_ms, 1, 60_000, "")?;
        int("serial", "retries", s.retries.into(), 0, 100, "")?;
        int("serial", "reconnect_ms", s.reconnect_ms, 0, 600_000, "")?;
        int(
            "serial",
            "watchdog_ms",
            s.watchdog_ms.into(),
            100,
            60_000,
            " (PROTOCOL.md SET_WATCHDOG)",
        )?;
        if let Some(b) = s.boot_window_ms {
            int("serial", "boot_window_ms", b, 0, 60_000, "")?;
        }
        let t = &self.turntable;
        // The wire carries rates in millidegrees per second (squared) in 32 bits, angles in
        // signed 32-bit millidegrees.
        let rate_max = f64::from(u32::MAX) / 1000.0;
        let angle_max = f64::from(i32::MAX) / 1000.0;
        let (rate, angle) = ((0.0, true, rate_max), (-angle_max, false, angle_max));
        for (key, v, (lo, open_lo, hi)) in [
            ("max_speed_deg_s", t.max_speed_deg_s, rate),
            ("max_accel_deg_s2", t.max_accel_deg_s2, rate),
            ("min_angle_deg", t.min_angle_deg, angle),
            ("max_angle_deg", t.max_angle_deg, angle),
        ] {
            let above = if open_lo { v > lo } else { v >= lo };
            if !(v.is_finite() && above && v <= hi) {
                let l = if open_lo { "(" } else { "[" };
                return Err(self.invalid(
                    "turntable",
                    key,
                    format!(
                        "{}: must be in {l}{lo}, {hi}] (the wire carries millidegrees in 32 bits)",
                        number(v)
                    ),
                ));
            }
        }
        if t.max_angle_deg <= t.min_angle_deg {
            return Err(self.invalid(
                "turntable",
                "max_angle_deg",
                format!("must be above min_angle_deg ({})", t.min_angle_deg),
            ));
        }
        int(
            "turntable",
            "steps_per_rev",
            t.steps_per_rev.into(),
            1,
            10_000_000,
            "",
        )?;
        int("turntable", "poll_ms", t.poll_ms, 0, 1000, "")?;
        int(
            "light",
            "warmup_timeout_ms",
            self.light.warmup_timeout_ms,
            0,
            600_000,
            "",
        )?;
        let n = self.light.channels.len();
        if n == 0 || n > crate::protocol::messages::MAX_CHANNELS {
            return Err(self.invalid(
                "light",
                "channels",
                format!(
                    "{n} channels; the protocol carries 1 to {}",
                    crate::protocol::messages::MAX_CHANNELS
                ),
            ));
        }
        for (i, c) in self.light.channels.iter().enumerate() {
            let at = |key: &str, reason: String| ProfileError::Invalid {
                file: self.origin.clone(),
                line: line_of_nth(&self.source, "[[light.channels]]", i, key),
                key: format!("light.channels[{i}].{key}"),
                reason,
            };
            if !(c.max_level > 0.0 && c.max_level <= 1.0) {
                return Err(at("max_level", "must be in (0, 1]".into()));
            }
            if !(-360.0..=360.0).contains(&c.azimuth_deg) {
                return Err(at(
                    "azimuth_deg",
                    format!("{}: must be in [-360, 360]", number(c.azimuth_deg)),
                ));
            }
            if !(-90.0..=90.0).contains(&c.elevation_deg) {
                return Err(at("elevation_deg", "must be in [-90, 90]".into()));
            }
        }
        let rate = |key: &str, r: f64| {
            if (0.0..1.0).contains(&r) {
                Ok(())
            } else {
                Err(self.invalid("sim", key, format!("{r}: must be in [0, 1)")))
            }
        };
        rate("drop_rate", self.sim.drop_rate)?;
        rate("corrupt_rate", self.sim.corrupt_rate)?;
        int("sim", "warmup_ms", self.sim.warmup_ms.into(), 0, 60_000, "")?;
        int(
            "sim",
            "boot_delay_ms",
            self.sim.boot_delay_ms.into(),
            0,
            60_000,
            "",
        )?;
        Ok(())
    }
}

/// A number as an operator wrote it: `1e9`, not a thousand digits.
fn number(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e7).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// The top-level section `key` of profile text (see [`Profile::section`]); `origin` names it in
/// errors.
pub fn parse_section<T: serde::de::DeserializeOwned + Default>(
    text: &str,
    origin: &str,
    key: &str,
) -> Result<T, ProfileError> {
    let table: toml::Table = toml::from_str(text).map_err(|e| ProfileError::Toml {
        origin: origin.to_owned(),
        source: Box::new(e),
    })?;
    match table.get(key) {
        None => Ok(T::default()),
        Some(v) => v.clone().try_into().map_err(|e| ProfileError::Section {
            origin: origin.to_owned(),
            section: key.to_owned(),
            source: Box::new(e),
        }),
    }
}

/// 1-based line of byte `offset`, and the key written on that line (`section.key`).
fn locate(text: &str, offset: usize) -> (usize, String) {
    let offset = offset.min(text.len());
    let line = text[..offset].matches('\n').count() + 1;
    let mut section = String::new();
    let mut key = String::new();
    for (i, l) in text.lines().enumerate() {
        if i + 1 > line {
            break;
        }
        let t = l.trim();
        if t.starts_with('[') {
            section = t.trim_matches(|c| c == '[' || c == ']').trim().to_owned();
            key.clear();
        }
        if i + 1 == line
            && let Some((k, _)) = t.split_once('=')
        {
            key = k.trim().to_owned();
        }
    }
    let full = match (section.is_empty(), key.is_empty()) {
        (true, true) => "(top level)".to_owned(),
        (false, true) => format!("[{section}]"),
        (true, false) => key,
        (false, false) => format!("{section}.{key}"),
    };
    (line, full)
}

/// 1-based line of `key = ...` inside `[section]`, or of the section header, or 0.
fn line_of_key(text: &str, section: &str, key: &str) -> usize {
    let header = format!("[{section}]");
    let mut inside = false;
    let mut header_line = 0;
    for (i, l) in text.lines().enumerate() {
        let t = l.trim();
        if t.starts_with('[') {
            inside = t == header;
            if inside {
                header_line = i + 1;
            }
            continue;
        }
        if inside && t.split_once('=').map(|(k, _)| k.trim()) == Some(key) {
            return i + 1;
        }
    }
    header_line
}

/// Like [`line_of_key`] for the `n`-th occurrence of an array-of-tables header.
fn line_of_nth(text: &str, header: &str, n: usize, key: &str) -> usize {
    let mut count = 0;
    let mut inside = false;
    let mut header_line = 0;
    for (i, l) in text.lines().enumerate() {
        let t = l.trim();
        if t.starts_with('[') {
            inside = false;
            if t == header {
                if count == n {
                    inside = true;
                    header_line = i + 1;
                }
                count += 1;
            }
            continue;
        }
        if inside && t.split_once('=').map(|(k, _)| k.trim()) == Some(key) {
            return i + 1;
        }
    }
    header_line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_profile_of_another_version_is_refused_naming_file_and_line() {
        let v2 = format!("# a comment\nformat_version = 2\n{SIMULATED}");
        let e = Profile::parse(&v2, "rig.toml").unwrap_err().to_string();
        assert!(e.contains("rig.toml:2") && e.contains("version 2"), "{e}");
        let v1 = format!("format_version = 1\n{SIMULATED}");
        assert!(Profile::parse(&v1, "rig.toml").is_ok());
    }

    #[test]
    fn built_in_and_example_profiles_parse() {
        let p = Profile::simulated().unwrap();
        assert!(p.is_simulated());
        assert_eq!(p.light.channels.len(), 3);
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("rig-profiles");
        let real = Profile::load(&dir.join("example-real.toml")).unwrap();
        assert!(!real.is_simulated());
        assert_eq!(real.light.channels[0].max_level, 0.8);
    }

    #[test]
    fn unknown_key_names_file_line_and_key() {
        let text = SIMULATED.replace("max_accel_deg_s2", "max_acel_deg_s2");
        let want_line = SIMULATED
            .lines()
            .position(|l| l.starts_with("max_accel_deg_s2"))
            .unwrap()
            + 1;
        let e = Profile::parse(&text, "my-rig.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(&format!("my-rig.toml:{want_line}: ")), "{e}");
        assert!(e.contains("turntable.max_acel_deg_s2"), "{e}");
        assert!(e.contains("unknown field"), "{e}");
    }

    #[test]
    fn wrong_type_names_the_key() {
        let text = SIMULATED.replace("retries = 5", "retries = \"five\"");
        let want_line = text.lines().position(|l| l.contains("\"five\"")).unwrap() + 1;
        let e = Profile::parse(&text, "x.toml").unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("x.toml:{want_line}: serial.retries:")),
            "{e}"
        );
    }

    #[test]
    fn out_of_range_value_names_the_key_and_line() {
        let text = SIMULATED.replacen(
            "name = \"mid\"\nmax_level = 1.0",
            "name = \"mid\"\nmax_level = 1.5",
            1,
        );
        let want_line = text.lines().position(|l| l == "max_level = 1.5").unwrap() + 1;
        let e = Profile::parse(&text, "x.toml").unwrap_err().to_string();
        assert_eq!(
            e,
            format!("x.toml:{want_line}: light.channels[1].max_level: must be in (0, 1]")
        );
        let text = SIMULATED.replace("min_angle_deg = -360.0", "min_angle_deg = 400.0");
        let e = Profile::parse(&text, "x.toml").unwrap_err().to_string();
        assert!(e.contains("turntable.max_angle_deg: must be above"), "{e}");
    }

    #[test]
    fn every_out_of_range_value_gives_the_allowed_range() {
        for (from, to, want) in [
            (
                "max_speed_deg_s = 90.0",
                "max_speed_deg_s = 1e9",
                "turntable.max_speed_deg_s: 1e9: must be in (0, 4294967.295]",
            ),
            (
                "timeout_ms = 100",
                "timeout_ms = 0",
                "must be in [1, 60000]",
            ),
            ("retries = 5", "retries = 101", "must be in [0, 100]"),
            (
                "reconnect_ms = 3000",
                "reconnect_ms = 9000000",
                "serial.reconnect_ms: 9000000: must be in [0, 600000]",
            ),
            ("poll_ms = 1", "poll_ms = 5000", "must be in [0, 1000]"),
            (
                "warmup_timeout_ms = 3000",
                "warmup_timeout_ms = 7200000",
                "light.warmup_timeout_ms: 7200000: must be in [0, 600000]",
            ),
            (
                "drop_rate = 0.0",
                "drop_rate = 1.0",
                "sim.drop_rate: 1: must be in [0, 1)",
            ),
            (
                "azimuth_deg = 20.0",
                "azimuth_deg = 1e300",
                "light.channels[0].azimuth_deg: 1e300: must be in [-360, 360]",
            ),
            (
                "watchdog_ms = 2000",
                "watchdog_ms = 2000\nboot_window_ms = 100000",
                "serial.boot_window_ms: 100000: must be in [0, 60000]",
            ),
        ] {
            assert!(SIMULATED.contains(from), "{from}");
            let e = Profile::parse(&SIMULATED.replacen(from, to, 1), "x.toml")
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{to}: {e}");
        }
    }

    #[test]
    fn a_port_without_a_profile_gets_a_real_boards_timing() {
        let sim = Profile::simulated().unwrap();
        assert_eq!(sim.boot_window_ms(), 0);
        let p = Profile::real_board_defaults(Path::new("/dev/tty ACM'0")).unwrap();
        assert_eq!(p.serial.port, "/dev/tty ACM'0");
        assert_eq!((p.serial.timeout_ms, p.serial.retries), (200, 5));
        assert_eq!(p.boot_window_ms(), DEFAULT_BOOT_WINDOW_MS);
        assert_eq!(p.turntable, sim.turntable);
        assert_eq!(p.light, sim.light);
        assert_eq!(p.origin, REAL_BOARD_NAME);
        // its source is what it says (a session keeps a copy; a resume reads it back)
        assert_eq!(Profile::parse(&p.source, "copy").unwrap().serial, p.serial);
        // a real board's own profile has the window without saying so
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("rig-profiles");
        let real = Profile::load(&dir.join("example-real.toml")).unwrap();
        assert_eq!(real.boot_window_ms(), DEFAULT_BOOT_WINDOW_MS);
    }

    #[test]
    fn sections_of_other_modules_are_tolerated() {
        let text = format!("{SIMULATED}\n[camera]\nbackend = \"sim\"\n\n[calibration]\nx = 1\n");
        let p = Profile::parse(&text, "x.toml").unwrap();
        assert!(p.source.contains("[camera]"));
    }

    #[test]
    fn a_bad_section_of_another_module_names_the_file_and_section() {
        #[derive(Debug, Default, Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Other {
            #[allow(dead_code)] // only its absence from the TOML matters
            size: f64,
        }
        let e = parse_section::<Other>("[other]\nsise = 1.0\n", "x.toml", "other").unwrap_err();
        assert!(matches!(&e, ProfileError::Section { section, .. } if section == "other"));
        let m = e.to_string();
        assert!(
            m.starts_with("x.toml: [other]: ") && m.contains("sise"),
            "{m}"
        );
        let e = parse_section::<Other>("[other\n", "x.toml", "other").unwrap_err();
        assert!(matches!(e, ProfileError::Toml { .. }), "{e}");
        assert!(e.to_string().starts_with("x.toml: "), "{e}");
    }

    #[test]
    fn light_directions_are_unit_vectors_in_the_lab_frame() {
        let p = Profile::simulated().unwrap();
        let d = p.light.channels[0].direction_lab();
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        assert!((n - 1.0).abs() < 1e-12);
        // Azimuth 20 degrees in the horizontal plane: 20 degrees from the camera direction +x.
        assert!((d[1].atan2(d[0]).to_degrees() - 20.0).abs() < 1e-9);
        assert_eq!(d[2], 0.0);
    }
}
