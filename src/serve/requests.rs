//! The bodies of the page's acting requests and their checks: as strict as the command line's
//! (the same ranges, `crate::ranges`; the same plan and profile checks, done where the CLI does
//! them), plus what a remote page must not do: name a file or folder on the server. A session is
//! a plain folder name under the server's sessions folder; a plan is one of the plans the
//! server lists. Unknown fields are refused, so a misspelt field is an error, not a default.
//!
//! Pure: no I/O.

use serde::Deserialize;
use serde::de::DeserializeOwned;

use super::hub::{Command, StartSpec};
use crate::ranges::{Closed, Open, RangeError, check_int, check_real};

/// Why a request is refused; the page shows the message as it is.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum RequestError {
    /// The body is not the request's JSON (serde_json's reason, which names the field).
    #[error("invalid request: {0}")]
    Json(String),
    #[error(
        "session name {0:?}: use 1 to 64 letters, digits, '.', '_' or '-', not starting with '.'"
    )]
    SessionName(String),
    #[error(transparent)]
    Range(#[from] RangeError),
    /// A field missing, or given where it has no use.
    #[error("{0}")]
    Field(String),
}

impl From<RequestError> for String {
    fn from(e: RequestError) -> String {
        e.to_string()
    }
}

/// A request body as JSON of type `T`, or the reason it is not one.
pub fn parse<T: DeserializeOwned>(body: &[u8]) -> Result<T, RequestError> {
    serde_json::from_slice(body).map_err(|e| RequestError::Json(e.to_string()))
}

/// A session folder name: 1 to 64 of `A-Z a-z 0-9 . _ -`, not starting with a dot (no path,
/// no hidden folder, nothing a shell or a URL must quote).
pub fn session_name(name: &str) -> Result<String, RequestError> {
    let ok = !name.is_empty()
        && name.len() <= 64
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-'));
    if ok {
        Ok(name.to_string())
    } else {
        Err(RequestError::SessionName(name.to_string()))
    }
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// The page shows each instruction and waits for Continue.
    Guided,
    /// Nobody acts: the room light and targets are handled (the simulated rig's virtual
    /// operator, or a rig already set).
    Unattended,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClaimRequest {
    /// Shown to the other pages.
    #[serde(default)]
    pub name: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartRequest {
    /// A plan id from the state's `plans`.
    pub plan: String,
    pub session: String,
    pub mode: Mode,
    /// As `capture --snapshot-every`.
    #[serde(default = "default_snapshot_every")]
    pub snapshot_every: usize,
}

fn default_snapshot_every() -> usize {
    16
}

impl StartRequest {
    pub fn check(&self) -> Result<StartSpec, RequestError> {
        Ok(StartSpec {
            plan_id: self.plan.clone(),
            session: session_name(&self.session)?,
            guided: self.mode == Mode::Guided,
            snapshot_every: check_int("snapshot_every", self.snapshot_every, 1, 100_000)?,
        })
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResumeRequest {
    pub session: String,
    pub mode: Mode,
}

impl ResumeRequest {
    pub fn check(&self) -> Result<Command, RequestError> {
        Ok(Command::Resume {
            session: session_name(&self.session)?,
            guided: self.mode == Mode::Guided,
        })
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContinueRequest {
    /// The instruction this answers (`capture.instruction.seq`).
    pub seq: u64,
}

/// What the rig allows: from the profile.
#[derive(Clone, Debug, PartialEq)]
pub struct RigLimits {
    /// Highest level of each channel.
    pub max_levels: Vec<f64>,
    pub min_angle_deg: f64,
    pub max_angle_deg: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightRequest {
    pub on: bool,
    /// Needed to switch on; switching off always switches every channel off.
    #[serde(default)]
    pub channel: Option<usize>,
    #[serde(default = "full")]
    pub level: f64,
}

fn full() -> f64 {
    1.0
}

impl LightRequest {
    pub fn check(&self, limits: &RigLimits) -> Result<Command, RequestError> {
        if !self.on {
            return Ok(Command::LightOff);
        }
        let n = limits.max_levels.len();
        let Some(channel) = self.channel else {
            return Err(RequestError::Field(
                "channel: needed to switch a light on".into(),
            ));
        };
        if n == 0 {
            return Err(RequestError::Field("the rig has no light channel".into()));
        }
        let channel = check_int("channel", channel, 0, n - 1)?;
        let max = limits.max_levels[channel];
        let level = check_real("level", self.level, Open(0.0), Closed(max))?;
        Ok(Command::LightOn { channel, level })
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TurntableRequest {
    /// `home` or `move`.
    pub action: String,
    #[serde(default)]
    pub angle_deg: Option<f64>,
}

impl TurntableRequest {
    pub fn check(&self, limits: &RigLimits) -> Result<Command, RequestError> {
        match (self.action.as_str(), self.angle_deg) {
            ("home", None) => Ok(Command::Home),
            ("move", Some(a)) => Ok(Command::MoveTo {
                angle_deg: check_real(
                    "angle_deg",
                    a,
                    Closed(limits.min_angle_deg),
                    Closed(limits.max_angle_deg),
                )?,
            }),
            ("move", None) => Err(RequestError::Field("angle_deg: needed to move".into())),
            ("home", Some(_)) => Err(RequestError::Field("angle_deg: not used to home".into())),
            (other, _) => Err(RequestError::Field(format!(
                "action {other:?}: must be home or move"
            ))),
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PreviewRequest {
    pub exposure_secs: f64,
    #[serde(default = "full")]
    pub gain: f64,
}

impl PreviewRequest {
    /// The ranges a plan's exposures and gain may take.
    pub fn check(&self) -> Result<(f64, f64), RequestError> {
        Ok((
            check_real("exposure_secs", self.exposure_secs, Open(0.0), Closed(60.0))?,
            check_real("gain", self.gain, Open(0.0), Closed(1000.0))?,
        ))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    fn limits() -> RigLimits {
        RigLimits {
            max_levels: vec![1.0, 0.5],
            min_angle_deg: -360.0,
            max_angle_deg: 360.0,
        }
    }

    #[test]
    fn session_names_are_plain_folder_names() {
        for ok in ["s1", "lab-2026.03.01_bunny", "a"] {
            assert_eq!(session_name(ok).unwrap(), ok);
        }
        for bad in [
            "",
            ".",
            "..",
            ".hidden",
            "a/b",
            "../etc",
            "a b",
            "x\0",
            "é",
            &"x".repeat(65),
        ] {
            assert!(session_name(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn rig_requests_are_checked_against_the_profile() {
        let l = limits();
        let on = |body: &str| parse::<LightRequest>(body.as_bytes()).and_then(|r| r.check(&l));
        assert_eq!(
            on(r#"{"on": true, "channel": 1, "level": 0.5}"#),
            Ok(Command::LightOn {
                channel: 1,
                level: 0.5
            })
        );
        assert_eq!(on(r#"{"on": false}"#), Ok(Command::LightOff));
        let e = on(r#"{"on": true, "channel": 1, "level": 0.8}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("level = 0.8") && e.contains("(0, 0.5]"), "{e}");
        assert!(
            on(r#"{"on": true, "channel": 2}"#)
                .unwrap_err()
                .to_string()
                .contains("[0, 1]")
        );
        assert!(
            on(r#"{"on": true}"#)
                .unwrap_err()
                .to_string()
                .contains("channel")
        );
        assert!(
            on(r#"{"on": true, "channel": -1}"#)
                .unwrap_err()
                .to_string()
                .contains("invalid")
        );
        assert!(
            on(r#"{"on": true, "channel": 0, "lvl": 1}"#)
                .unwrap_err()
                .to_string()
                .contains("unknown field")
        );
        let tt = |body: &str| parse::<TurntableRequest>(body.as_bytes()).and_then(|r| r.check(&l));
        assert_eq!(tt(r#"{"action": "home"}"#), Ok(Command::Home));
        assert_eq!(
            tt(r#"{"action": "move", "angle_deg": -45}"#),
            Ok(Command::MoveTo { angle_deg: -45.0 })
        );
        assert!(
            tt(r#"{"action": "move", "angle_deg": 361}"#)
                .unwrap_err()
                .to_string()
                .contains("[-360, 360]")
        );
        assert!(tt(r#"{"action": "spin"}"#).is_err());
        assert!(tt(r#"{"action": "move"}"#).is_err());
    }

    #[test]
    fn start_and_preview_requests_use_the_command_lines_ranges() {
        let start = |body: &str| parse::<StartRequest>(body.as_bytes()).and_then(|r| r.check());
        let s = start(r#"{"plan": "quick.toml", "session": "s1", "mode": "guided"}"#).unwrap();
        assert!(s.guided);
        assert_eq!(s.snapshot_every, 16);
        assert!(start(r#"{"plan": "q", "session": "../x", "mode": "guided"}"#).is_err());
        assert!(start(r#"{"plan": "q", "session": "s", "mode": "sometimes"}"#).is_err());
        let e =
            start(r#"{"plan": "q", "session": "s", "mode": "unattended", "snapshot_every": 0}"#)
                .unwrap_err()
                .to_string();
        assert!(e.contains("[1, 100000]"), "{e}");
        let p = |body: &str| parse::<PreviewRequest>(body.as_bytes()).and_then(|r| r.check());
        assert_eq!(p(r#"{"exposure_secs": 0.01}"#), Ok((0.01, 1.0)));
        assert!(
            p(r#"{"exposure_secs": 0}"#)
                .unwrap_err()
                .to_string()
                .contains("(0, 60]")
        );
        assert!(p(r#"{"exposure_secs": 1e400}"#).is_err());
    }
}
