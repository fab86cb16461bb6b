//! Atomic file writes: bytes go to a temporary file beside the target (`.NAME.tmp-XXXXXX`),
//! which is fsynced and renamed over it, so a crash leaves the old file or the new one, never
//! half of one; the same without the fsyncs for large results a run can make again (MERL
//! tables), and a link (or copy) made the same way; and the removal of the temporaries a
//! killed write left. Every file this tool writes goes through here. Depends on nothing in the
//! crate.

use std::io::Write;
use std::path::{Path, PathBuf};

/// Writes `bytes` to `path` atomically (temp file in the same directory, fsync, rename). The
/// temporary file is named `.NAME.tmp-XXXXXX` beside `path`, so a write killed half way leaves a
/// file that is recognisably stray (`capture::session` removes them on resume).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_atomic_with(path, |f| f.write_all(bytes))
}

/// Removes the temporary files a killed [`write_atomic`] left in `dir` (`.NAME.tmp-XXXXXX`),
/// for every NAME or only for the `names` given; returns how many. A folder that does not exist
/// has none. Only for files no other process is writing (their owner holds a lock).
pub fn remove_stray_temporaries(dir: &Path, names: Option<&[&str]>) -> std::io::Result<usize> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(e),
    };
    let mut removed = 0;
    for entry in entries {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some((stem, _)) = name.strip_prefix('.').and_then(|n| n.rsplit_once(".tmp-")) else {
            continue;
        };
        if names.is_none_or(|ns| ns.contains(&stem)) && entry.file_type()?.is_file() {
            std::fs::remove_file(entry.path())?;
            removed += 1;
        }
    }
    Ok(removed)
}

/// [`write_atomic`] without the fsyncs, for large results a run can make again (a MERL table
/// is 35 MB, and an object of three materials writes three): a killed or crashed process
/// leaves the old file or the new one, never half of one; after a power loss the file system's
/// ordering decides (ext4 flushes a file renamed over another by default), which is why the
/// captures, the job and the reports, which cannot be made again or are small, use
/// [`write_atomic`].
pub fn write_atomic_unsynced(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    replace_with(path, false, |f| f.write_all(bytes))
}

/// Atomic write where `fill` streams into the (seekable) temp file.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>,
) -> std::io::Result<()> {
    replace_with(path, true, fill)
}

/// The temporary file beside `path`, filled, fsynced when `sync`, renamed over `path`.
fn replace_with(
    path: &Path,
    sync: bool,
    fill: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let (dir, mut tmp) = temporary_beside(path)?;
    fill(tmp.as_file_mut())?;
    tmp.as_file_mut().flush()?;
    if sync {
        tmp.as_file().sync_all()?;
    }
    tmp.persist(path).map_err(|e| e.error)?;
    // make the rename itself durable; not every platform can open a directory, so best effort
    if sync && let Ok(d) = std::fs::File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// A new temporary file `.NAME.tmp-XXXXXX` in `path`'s folder (removed on drop unless
/// persisted), and that folder. Created with the permissions any new file gets (0666 less the
/// umask on unix), not the temporary file's private 0600: it becomes the user's result, which
/// the lab's group reads as it reads every other file.
fn temporary_beside(path: &Path) -> std::io::Result<(PathBuf, tempfile::NamedTempFile)> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let prefix = format!(".{name}.tmp-");
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let tmp = builder.tempfile_in(&dir)?;
    Ok((dir, tmp))
}

/// Gives `dst` the contents of the file `src` atomically: a hard link where the file system
/// allows one (nothing written twice), a copy otherwise; made beside `dst` under a temporary
/// name (`.NAME.tmp-XXXXXX`) and renamed over it, so a crash leaves the old `dst` or the new
/// one. Not fsynced, like [`write_atomic_unsynced`], whose large results it serves. A later
/// [`write_atomic`] of either name renames a new file over that name and leaves the other as
/// it was.
pub fn link_or_copy_atomic(src: &Path, dst: &Path) -> std::io::Result<()> {
    // a unique name, then free for the link (which must not find a file there)
    let tmp = temporary_beside(dst)?.1.into_temp_path();
    std::fs::remove_file(&tmp)?;
    if std::fs::hard_link(src, &tmp).is_err() {
        std::fs::copy(src, &tmp)?;
    }
    tmp.persist(dst).map_err(|e| e.error)?;
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn a_linked_file_has_the_contents_and_a_later_write_of_one_name_leaves_the_other() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        let (src, dst) = (d.join("material-1.binary"), d.join("brdf.binary"));
        write_atomic_unsynced(&src, b"first").unwrap();
        write_atomic_unsynced(&dst, b"old").unwrap();
        assert_eq!(std::fs::read(&dst).unwrap(), b"old");
        link_or_copy_atomic(&src, &dst).unwrap();
        assert_eq!(std::fs::read(&dst).unwrap(), b"first");
        // no temporary left beside them
        let mut names: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, ["brdf.binary", "material-1.binary"]);
        // rewriting one name does not change the other (a new file is renamed over it)
        write_atomic(&dst, b"second").unwrap();
        assert_eq!(std::fs::read(&src).unwrap(), b"first");
        write_atomic(&src, b"third").unwrap();
        assert_eq!(std::fs::read(&dst).unwrap(), b"second");
        // a source that does not exist is an error, and the target stays as it was
        assert!(link_or_copy_atomic(&d.join("missing.binary"), &dst).is_err());
        assert_eq!(std::fs::read(&dst).unwrap(), b"second");
    }

    #[cfg(unix)]
    #[test]
    fn a_written_file_has_the_permissions_of_any_new_file() {
        use std::os::unix::fs::PermissionsExt;
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        std::fs::write(d.join("plain"), b"x").unwrap();
        write_atomic(&d.join("synced"), b"x").unwrap();
        write_atomic_unsynced(&d.join("unsynced"), b"x").unwrap();
        link_or_copy_atomic(&d.join("unsynced"), &d.join("linked")).unwrap();
        for name in ["synced", "unsynced", "linked"] {
            assert_eq!(mode(&d.join(name)), mode(&d.join("plain")), "{name}");
        }
    }

    #[test]
    fn stray_temporaries_are_removed_and_nothing_else() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        for name in [
            ".a.exr.tmp-X1",
            ".job.toml.tmp-Y2",
            "a.exr",
            ".lock",
            "b.tmp-3",
            ".calibration.json.tmp-Z3",
        ] {
            std::fs::write(d.join(name), b"x").unwrap();
        }
        std::fs::create_dir(d.join(".dir.tmp-4")).unwrap();
        let names = ["job.toml", "calibration.json"];
        assert_eq!(remove_stray_temporaries(d, Some(&names)).unwrap(), 2);
        assert!(d.join(".a.exr.tmp-X1").exists());
        assert_eq!(remove_stray_temporaries(d, None).unwrap(), 1);
        let mut left: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, [".dir.tmp-4", ".lock", "a.exr", "b.tmp-3"]);
        assert_eq!(remove_stray_temporaries(&d.join("none"), None).unwrap(), 0);
        // a real write leaves nothing behind
        write_atomic(&d.join("c.bin"), b"abc").unwrap();
        assert_eq!(remove_stray_temporaries(d, None).unwrap(), 0);
    }
}
