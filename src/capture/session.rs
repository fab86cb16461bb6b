//! The session folder: the boundary between capture and the calibrate/reconstruct steps.
//!
//! Its layout, file names, version and records are `capture::session_format`'s (re-exported
//! here); this file writes a session and resumes one.
//! Images are linear RGB OpenEXR (32-bit float), in the camera's units times nothing: the
//! exposure and gain are in the record, so radiance = value / (exposure_secs * gain).
//!
//! Crash safety: an image is written to a temporary file, fsynced and renamed into place (then
//! the directory is fsynced); only then is its record appended to the journal and fsynced. So
//! every journaled record names a complete image with its checksum, and a kill at any point
//! loses at most the shot in flight, which a resume takes again (overwriting a stray image).
//! A torn last journal line (the kill hit the append) is dropped on resume.
//!
//! Repair: a resume re-checks every journaled image against its size and SHA-256 (the same
//! check as `session verify`, [`super::verify::check_record`]). A missing or damaged image is
//! taken again: its damaged file is first moved to `DIR/set-aside/` (never overwritten), and
//! the new record carries `retake` (why, and where the old file went). A later record with
//! `retake` supersedes the earlier record of its shot ([`current_records`]).

use std::collections::HashMap;
use std::fs::{self, File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use super::error::CaptureError;
use super::plan::{CapturePlan, PlannedShot, parse_plan};
pub use super::session_format::{
    FORMAT_VERSION, JOURNAL_FILE, LOCK_FILE, MANIFEST_FILE, Manifest, PLAN_FILE, Retake,
    SESSION_FILE, SET_ASIDE_DIR, SessionHeader, ShotRecord, current_records, read_header,
    read_journal, read_manifest, sha256_hex,
};

/// A journaled shot a resume found missing or damaged, to be taken again.
#[derive(Clone, Debug, PartialEq)]
pub struct Repair {
    pub id: String,
    pub file: String,
    pub problem: super::verify::Problem,
}

/// Seconds since the Unix epoch and the same instant as `YYYY-MM-DDTHH:MM:SS.mmmZ`.
pub fn now_utc() -> (f64, String) {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0);
    (t, format_utc(t))
}

/// Formats Unix seconds as an RFC 3339 UTC timestamp with milliseconds.
pub fn format_utc(unix_secs: f64) -> String {
    let millis_total = (unix_secs * 1000.0).round() as i64;
    let secs = millis_total.div_euclid(1000);
    let millis = millis_total.rem_euclid(1000);
    let days = secs.div_euclid(86_400);
    let sod = secs.rem_euclid(86_400);
    // Howard Hinnant's civil_from_days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{millis:03}Z",
        sod / 3600,
        (sod / 60) % 60,
        sod % 60
    )
}

fn sync_dir(dir: &Path) -> Result<(), CaptureError> {
    // Persists a rename; opening a directory read-only and fsyncing it is the POSIX way.
    let d = File::open(dir).map_err(|e| CaptureError::io("opening the folder to sync", dir, e))?;
    d.sync_all()
        .map_err(|e| CaptureError::io("syncing the folder", dir, e))
}

/// Writes `bytes` to `path` atomically: temporary file beside it (`.NAME.tmp-XXXXXX`, which
/// [`remove_stray_temporaries`] recognises), fsync, rename (`atomic::write_atomic`), then an fsync
/// of the folder that, unlike there, must succeed: a session never reports a shot it could lose.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CaptureError> {
    crate::atomic::write_atomic(path, bytes)
        .map_err(|e| CaptureError::io("writing atomically", path, e))?;
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => sync_dir(d),
        _ => sync_dir(Path::new(".")),
    }
}

/// An open session folder, locked for writing.
pub struct Session {
    dir: PathBuf,
    header: SessionHeader,
    plan: CapturePlan,
    shots: Vec<PlannedShot>,
    records: Vec<ShotRecord>,
    done: HashMap<String, usize>,
    /// Journaled shots found missing or damaged at resume, in plan order.
    repairs: Vec<Repair>,
    /// Shot id -> why it is re-taken and where its old file went, until the re-take is journaled.
    pending: HashMap<String, Retake>,
    journal: File,
    // Held for the lifetime of the session; the kernel releases it if the process dies.
    _lock: File,
}

fn lock_folder(dir: &Path) -> Result<File, CaptureError> {
    let path = dir.join(LOCK_FILE);
    let f = OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(|e| CaptureError::io("opening the lock file", &path, e))?;
    // A lock can be held for a moment after its owner let it go: a process that another
    // thread is starting shares the lock's open file until it execs (the file is close-on-exec,
    // but the fork copies it first). So a held lock is tried again for up to half a second
    // before the folder counts as in use; a capture that is really writing holds it far longer.
    for attempt in 0..=LOCK_RETRIES {
        if fs4::FileExt::try_lock(&f).is_ok() {
            return Ok(f);
        }
        if attempt < LOCK_RETRIES {
            std::thread::sleep(LOCK_RETRY_PAUSE);
        }
    }
    Err(CaptureError::Session {
        path: dir.to_path_buf(),
        reason: "another capture is writing to this folder (its lock is held)".into(),
    })
}

/// Tries of a held lock after the first, and the pause between them (see [`lock_folder`]).
const LOCK_RETRIES: u32 = 20;
const LOCK_RETRY_PAUSE: std::time::Duration = std::time::Duration::from_millis(25);

/// Removes folders a killed `create` of `name` left in `parent` (their process is gone).
fn remove_stale_staging(parent: &Path, name: &str) {
    let prefix = format!(".{name}.creating-");
    let Ok(entries) = fs::read_dir(parent) else {
        return;
    };
    for entry in entries.flatten() {
        let file_name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = file_name.strip_prefix(&prefix) else {
            continue;
        };
        let alive = Path::new("/proc").join(pid).exists() && pid != std::process::id().to_string();
        if !alive {
            let _ = fs::remove_dir_all(entry.path());
        }
    }
}

/// Removes temporary files left by a killed atomic write.
fn remove_stray_temporaries(dir: &Path) -> Result<(), CaptureError> {
    for sub in ["", "ambient", "light", "calib", "sim"] {
        let d = dir.join(sub);
        crate::atomic::remove_stray_temporaries(&d, None)
            .map_err(|e| CaptureError::io("removing stray temporaries", &d, e))?;
    }
    Ok(())
}

/// Writes the files of a new session into `staging` (see [`Session::create`]).
fn build_staging(
    staging: &Path,
    plan_text: &str,
    header: &SessionHeader,
    extra: &[(&str, &[u8])],
) -> Result<(), CaptureError> {
    for sub in ["ambient", "light", "calib"] {
        let d = staging.join(sub);
        fs::create_dir_all(&d).map_err(|e| CaptureError::io("creating", &d, e))?;
    }
    write_atomic(&staging.join(PLAN_FILE), plan_text.as_bytes())?;
    for (file, bytes) in extra {
        write_atomic(&staging.join(file), bytes)?;
    }
    let header_json = serde_json::to_vec_pretty(header).map_err(|e| CaptureError::Session {
        path: staging.to_path_buf(),
        reason: e.to_string(),
    })?;
    write_atomic(&staging.join(SESSION_FILE), &header_json)?;
    write_atomic(&staging.join(JOURNAL_FILE), b"")
}

/// Moves `dir/file` to `dir/set-aside/file` (or `.1`, `.2`, ... beside it when that is taken);
/// returns the new path relative to `dir`.
fn set_aside(dir: &Path, file: &str) -> Result<String, CaptureError> {
    let from = dir.join(file);
    let base = format!("{SET_ASIDE_DIR}/{file}");
    let mut rel = base.clone();
    let mut n = 0;
    while dir.join(&rel).exists() {
        n += 1;
        rel = format!("{base}.{n}");
    }
    let to = dir.join(&rel);
    if let Some(parent) = to.parent() {
        fs::create_dir_all(parent).map_err(|e| CaptureError::io("creating", parent, e))?;
    }
    fs::rename(&from, &to).map_err(|e| {
        CaptureError::io(
            format!("setting the damaged image aside to {}", to.display()),
            &from,
            e,
        )
    })?;
    if let Some(parent) = to.parent() {
        sync_dir(parent)?;
    }
    if let Some(parent) = from.parent() {
        sync_dir(parent)?;
    }
    Ok(rel)
}

impl Session {
    /// Creates a new session in `dir` (which must not exist or be empty), with `extra` files
    /// (name, bytes) beside the plan. The folder is built under a temporary name and renamed
    /// into place, so a kill during creation leaves either no session or a whole one.
    pub fn create(
        dir: &Path,
        plan: &CapturePlan,
        plan_text: &str,
        mut header: SessionHeader,
        extra: &[(&str, &[u8])],
    ) -> Result<Self, CaptureError> {
        if dir.exists() {
            let non_empty = fs::read_dir(dir)
                .map_err(|e| CaptureError::io("listing", dir, e))?
                .next()
                .is_some();
            if non_empty {
                return Err(CaptureError::Session {
                    path: dir.to_path_buf(),
                    reason: "the folder exists and is not empty; choose a new --out, or continue it with --resume".into(),
                });
            }
        }
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .ok_or_else(|| CaptureError::Session {
                path: dir.to_path_buf(),
                reason: "not a folder name".into(),
            })?;
        let parent = match dir.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        fs::create_dir_all(&parent)
            .map_err(|e| CaptureError::io("creating the parent folder", &parent, e))?;
        remove_stale_staging(&parent, &name);
        let staging = parent.join(format!(".{name}.creating-{}", std::process::id()));
        let _ = fs::remove_dir_all(&staging);
        let shots = plan.shots();
        header.format_version = FORMAT_VERSION;
        header.plan_name = plan.name.clone();
        header.planned_shots = shots.len();
        let built = build_staging(&staging, plan_text, &header, extra).and_then(|()| {
            // rename(2) replaces an empty directory, so an empty --out folder is fine too.
            fs::rename(&staging, dir)
                .map_err(|e| CaptureError::io("moving the new session into place", dir, e))
        });
        if let Err(e) = built {
            let _ = fs::remove_dir_all(&staging);
            // The user named `dir`, not the staging folder beside it.
            return Err(match e {
                CaptureError::Io { what, source, .. } => CaptureError::Io {
                    what: format!("creating the session folder ({what})"),
                    path: dir.to_path_buf(),
                    source,
                },
                other => other,
            });
        }
        sync_dir(&parent)?;
        let lock = lock_folder(dir)?;
        let journal_path = dir.join(JOURNAL_FILE);
        let journal = OpenOptions::new()
            .append(true)
            .open(&journal_path)
            .map_err(|e| CaptureError::io("opening the journal", &journal_path, e))?;
        let s = Self {
            dir: dir.to_path_buf(),
            header,
            plan: plan.clone(),
            shots,
            records: Vec::new(),
            done: HashMap::new(),
            repairs: Vec::new(),
            pending: HashMap::new(),
            journal,
            _lock: lock,
        };
        s.write_snapshot(false)?;
        Ok(s)
    }

    /// Opens an existing session to continue it: re-reads its plan and journal, drops a torn
    /// last journal line and stray temporaries, and re-checks every journaled image: a missing
    /// or damaged one is not done any more ([`Session::repairs`]), so the run takes it again.
    pub fn resume(dir: &Path) -> Result<Self, CaptureError> {
        let header_path = dir.join(SESSION_FILE);
        if !header_path.exists() {
            return Err(CaptureError::Session {
                path: dir.to_path_buf(),
                reason: format!("no {SESSION_FILE}: not a brdf-rig session folder"),
            });
        }
        let lock = lock_folder(dir)?;
        let header = read_header(dir)?;
        let plan_path = dir.join(PLAN_FILE);
        let plan_text = fs::read_to_string(&plan_path)
            .map_err(|e| CaptureError::io("reading", &plan_path, e))?;
        let plan = parse_plan(&plan_text, &plan_path.display().to_string())?;
        let shots = plan.shots();
        let journal_path = dir.join(JOURNAL_FILE);
        let (records, good_len) = read_journal(&journal_path)?;
        let journal = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&journal_path)
            .map_err(|e| CaptureError::io("opening the journal", &journal_path, e))?;
        journal
            .set_len(good_len)
            .map_err(|e| CaptureError::io("dropping a torn journal line", &journal_path, e))?;
        journal
            .sync_all()
            .map_err(|e| CaptureError::io("syncing the journal", &journal_path, e))?;
        remove_stray_temporaries(dir)?;
        // A plain duplicate (never written by this tool) is ignored, as `session verify` says.
        let (current, _duplicates) = current_records(records);
        let mut s = Self {
            dir: dir.to_path_buf(),
            header,
            plan,
            shots,
            records: Vec::new(),
            done: HashMap::new(),
            repairs: Vec::new(),
            pending: HashMap::new(),
            journal,
            _lock: lock,
        };
        for r in current {
            if !s.shots.iter().any(|p| p.id == r.id) {
                return Err(CaptureError::Session {
                    path: dir.to_path_buf(),
                    reason: format!("journal record `{}` is not a shot of the plan", r.id),
                });
            }
            match super::verify::check_record(dir, &r).1 {
                Some(problem) => {
                    s.pending.insert(
                        r.id.clone(),
                        Retake {
                            reason: problem.what().to_string(),
                            set_aside: None,
                        },
                    );
                    s.repairs.push(Repair {
                        id: r.id,
                        file: r.file,
                        problem,
                    });
                }
                None => {
                    s.done.insert(r.id.clone(), s.records.len());
                    s.records.push(r);
                }
            }
        }
        Ok(s)
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    pub fn header(&self) -> &SessionHeader {
        &self.header
    }

    pub fn plan(&self) -> &CapturePlan {
        &self.plan
    }

    pub fn planned(&self) -> &[PlannedShot] {
        &self.shots
    }

    pub fn records(&self) -> &[ShotRecord] {
        &self.records
    }

    pub fn is_done(&self, id: &str) -> bool {
        self.done.contains_key(id)
    }

    /// Journaled shots a resume found missing or damaged; the run takes them again.
    pub fn repairs(&self) -> &[Repair] {
        &self.repairs
    }

    /// Shots of the plan not yet in the journal, in plan order.
    pub fn remaining(&self) -> Vec<PlannedShot> {
        self.shots
            .iter()
            .filter(|s| !self.done.contains_key(&s.id))
            .cloned()
            .collect()
    }

    /// Writes the image of shot `id` (atomically) and returns its size and checksum. Does not
    /// journal it. A damaged image of a shot being re-taken is moved to `set-aside/` first.
    pub fn write_image(
        &mut self,
        id: &str,
        file: &str,
        bytes: &[u8],
    ) -> Result<(u64, String), CaptureError> {
        let path = self.dir.join(file);
        if let Some(parent) = path.parent() {
            fs::create_dir_all(parent).map_err(|e| CaptureError::io("creating", parent, e))?;
        }
        if let Some(retake) = self.pending.get_mut(id)
            && retake.set_aside.is_none()
            && path.exists()
        {
            retake.set_aside = Some(set_aside(&self.dir, file)?);
        }
        write_atomic(&path, bytes)?;
        Ok((bytes.len() as u64, sha256_hex(bytes)))
    }

    /// Appends a record to the journal and fsyncs it: from here on the shot is taken. A shot
    /// being re-taken gets its `retake` note here.
    pub fn append(&mut self, mut record: ShotRecord) -> Result<(), CaptureError> {
        let path = self.dir.join(JOURNAL_FILE);
        if record.retake.is_none() {
            record.retake = self.pending.get(&record.id).cloned();
        }
        let mut line = serde_json::to_vec(&record).map_err(|e| CaptureError::Session {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        line.push(b'\n');
        // One write call: a kill can tear it only at the end, which the reader drops.
        self.journal
            .write_all(&line)
            .map_err(|e| CaptureError::io("appending to the journal", &path, e))?;
        self.journal
            .sync_data()
            .map_err(|e| CaptureError::io("syncing the journal", &path, e))?;
        self.pending.remove(&record.id);
        self.done.insert(record.id.clone(), self.records.len());
        self.records.push(record);
        Ok(())
    }

    pub fn is_complete(&self) -> bool {
        self.shots.iter().all(|s| self.done.contains_key(&s.id))
    }

    /// Replaces `manifest.json` atomically with the current state.
    pub fn write_snapshot(&self, complete: bool) -> Result<(), CaptureError> {
        let mut shots = self.records.clone();
        shots.sort_by_key(|r| r.index);
        let m = Manifest {
            header: self.header.clone(),
            status: if complete { "complete" } else { "in_progress" }.into(),
            shots,
        };
        let path = self.dir.join(MANIFEST_FILE);
        let bytes = serde_json::to_vec_pretty(&m).map_err(|e| CaptureError::Session {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        write_atomic(&path, &bytes)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use crate::capture::plan::default_plan;

    fn header() -> SessionHeader {
        SessionHeader {
            format_version: 0,
            tool: "test".into(),
            plan_name: String::new(),
            planned_shots: 0,
            profile: "none".into(),
            camera_backend: "none".into(),
            created_utc: format_utc(0.0),
            simulated: false,
        }
    }

    fn record(shot: &PlannedShot, sha: &str) -> ShotRecord {
        ShotRecord {
            id: shot.id.clone(),
            index: shot.index,
            kind: shot.kind,
            view: shot.view,
            angle_deg: shot.angle_deg,
            measured_angle_deg: shot.angle_deg,
            channel: shot.channel,
            level: shot.level,
            light_dir_lab: None,
            exposure_secs: shot.exposure_secs,
            gain: 1.0,
            saturation: 1.0,
            device: "test".into(),
            file: shot.file.clone(),
            width: 1,
            height: 1,
            bytes: 3,
            sha256: sha.into(),
            time_unix: 0.0,
            time_utc: format_utc(0.0),
            retake: None,
        }
    }

    #[test]
    fn utc_formatting_matches_known_instants() {
        assert_eq!(format_utc(0.0), "1970-01-01T00:00:00.000Z");
        assert_eq!(format_utc(951_782_400.5), "2000-02-29T00:00:00.500Z");
        assert_eq!(format_utc(1_798_761_599.0), "2026-12-31T23:59:59.000Z");
    }

    #[test]
    fn journal_survives_a_torn_append_and_resume_drops_it() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("s");
        let plan = default_plan();
        let mut s = Session::create(&dir, &plan, DEFAULT_TEXT, header(), &[]).unwrap();
        let shots = s.planned().to_vec();
        let (_, sha) = s.write_image(&shots[0].id, &shots[0].file, b"abc").unwrap();
        s.append(record(&shots[0], &sha)).unwrap();
        // the folder is locked while open
        assert!(Session::resume(&dir).is_err());
        drop(s);
        // a torn append: half a line, no newline
        let jp = dir.join(JOURNAL_FILE);
        let mut f = OpenOptions::new().append(true).open(&jp).unwrap();
        f.write_all(b"{\"id\":\"ambient/v001").unwrap();
        drop(f);
        fs::write(dir.join("ambient/.v001_e0.exr.tmp-1"), b"junk").unwrap();
        let mut s = Session::resume(&dir).unwrap();
        assert_eq!(s.records().len(), 1);
        assert!(s.is_done(&shots[0].id));
        assert_eq!(s.remaining().len(), shots.len() - 1);
        assert!(!dir.join("ambient/.v001_e0.exr.tmp-1").exists());
        s.append(record(&shots[1], &sha)).unwrap();
        drop(s);
        let (recs, _) = read_journal(&jp).unwrap();
        assert_eq!(recs.len(), 2);
        assert_eq!(recs[1].id, shots[1].id);
    }

    #[test]
    fn resume_sets_damaged_images_aside_and_journals_the_retakes() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("s");
        let mut s = Session::create(&dir, &default_plan(), DEFAULT_TEXT, header(), &[]).unwrap();
        let shots = s.planned().to_vec();
        for shot in &shots[..3] {
            let (_, sha) = s.write_image(&shot.id, &shot.file, b"abc").unwrap();
            s.append(record(shot, &sha)).unwrap();
        }
        drop(s);
        fs::write(dir.join(&shots[1].file), b"abd").unwrap(); // same size, other bytes
        fs::remove_file(dir.join(&shots[2].file)).unwrap();
        let mut s = Session::resume(&dir).unwrap();
        let repaired: Vec<&str> = s.repairs().iter().map(|r| r.id.as_str()).collect();
        assert_eq!(repaired, [shots[1].id.as_str(), shots[2].id.as_str()]);
        assert!(s.is_done(&shots[0].id) && !s.is_done(&shots[1].id));
        // the damaged shots come first among the remaining ones, in plan order
        let remaining = s.remaining();
        assert_eq!(remaining[0].id, shots[1].id);
        assert_eq!(remaining[1].id, shots[2].id);
        for shot in &shots[1..3] {
            let (_, sha) = s.write_image(&shot.id, &shot.file, b"abc").unwrap();
            s.append(record(shot, &sha)).unwrap();
        }
        drop(s);
        assert_eq!(
            fs::read(dir.join(SET_ASIDE_DIR).join(&shots[1].file)).unwrap(),
            b"abd"
        );
        let (records, _) = read_journal(&dir.join(JOURNAL_FILE)).unwrap();
        assert_eq!(records.len(), 5);
        let r1 = records[3].retake.as_ref().unwrap();
        assert!(r1.reason.starts_with("checksum mismatch"), "{r1:?}");
        assert_eq!(
            r1.set_aside.as_deref(),
            Some(format!("{SET_ASIDE_DIR}/{}", shots[1].file).as_str())
        );
        let r2 = records[4].retake.as_ref().unwrap();
        assert_eq!(
            (r2.reason.as_str(), r2.set_aside.as_deref()),
            ("missing", None)
        );
        // the re-takes supersede the first records
        let (current, duplicates) = current_records(records);
        assert!(duplicates.is_empty());
        assert_eq!(current.len(), 3);
        assert!(current[1].retake.is_some() && current[2].retake.is_some());
        let s = Session::resume(&dir).unwrap();
        assert!(s.repairs().is_empty());
        assert_eq!(s.records().len(), 3);
    }

    #[test]
    fn a_plain_duplicate_record_does_not_replace_the_first() {
        let shot = &default_plan().shots()[0];
        let first = record(shot, "aa");
        let second = record(shot, "bb");
        let (current, duplicates) = current_records(vec![first.clone(), second]);
        assert_eq!(current, vec![first]);
        assert_eq!(duplicates, vec![shot.id.clone()]);
    }

    #[test]
    fn a_new_session_that_cannot_be_built_is_named_as_given() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("s");
        // A file where the staging folder goes: building it fails half way.
        let staging = tmp
            .path()
            .join(format!(".s.creating-{}", std::process::id()));
        fs::write(&staging, b"").unwrap();
        let err = Session::create(&dir, &default_plan(), DEFAULT_TEXT, header(), &[])
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("creating the session folder"), "{err}");
        assert!(err.contains(&dir.display().to_string()), "{err}");
        assert!(!err.contains(".creating-"), "{err}");
        assert!(!dir.exists());
    }

    #[test]
    fn a_bad_line_in_the_middle_is_an_error_naming_the_line() {
        let tmp = tempfile::tempdir().unwrap();
        let p = tmp.path().join("j.jsonl");
        fs::write(&p, b"not json\n{}\n").unwrap();
        let err = read_journal(&p).unwrap_err().to_string();
        assert!(err.contains("line 1"), "{err}");
    }

    #[test]
    fn create_refuses_a_non_empty_folder() {
        let tmp = tempfile::tempdir().unwrap();
        fs::write(tmp.path().join("x"), b"").unwrap();
        let err = Session::create(tmp.path(), &default_plan(), DEFAULT_TEXT, header(), &[])
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("--resume"), "{err}");
    }

    const DEFAULT_TEXT: &str = crate::capture::plan::DEFAULT_PLAN_TOML;
}
