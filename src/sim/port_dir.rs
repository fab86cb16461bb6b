//! The temporary folder a simulated rig's port symlink lives in (`runner::SimRig` without a
//! `link_path`), and the sweep of the folders killed processes left behind.
//!
//! A rig removes its folder when it is dropped, but a process killed outright (`SIGKILL`: the
//! capture drills do it on purpose, an operator or the out-of-memory killer may) runs no
//! destructor, and each kill left a `brdf-sim-*` folder in the temporary directory: a CI
//! machine had gathered 504 of them. So each folder names its owner (`owner`: the process id),
//! and making a new one first removes those whose owner no longer runs. The sweep is
//! conservative: only folders with an owner file whose process is gone (checked in `/proc`; on
//! a system without it nothing is swept), and only the files a rig puts there (`owner`, the
//! `tty` symlink, its `tty.new`); a folder holding anything else is left whole.
//!
//! Touches only the temporary directory's `brdf-sim-*` folders; no ports, no threads.

use std::io;
use std::path::Path;

/// The prefix of every simulated rig's port folder.
pub const PREFIX: &str = "brdf-sim-";
/// The file naming the process that owns a port folder.
pub const OWNER_FILE: &str = "owner";
/// The files a rig puts in its folder (the port symlink and the one it renames over it).
const RIG_FILES: [&str; 3] = [OWNER_FILE, "tty", "tty.new"];

/// A new port folder in `parent`, owned by this process, after sweeping `parent`'s stale ones.
pub fn create_in(parent: &Path) -> io::Result<tempfile::TempDir> {
    sweep_stale(parent);
    let dir = tempfile::Builder::new().prefix(PREFIX).tempdir_in(parent)?;
    std::fs::write(dir.path().join(OWNER_FILE), std::process::id().to_string())?;
    Ok(dir)
}

/// A new port folder in the system's temporary directory ([`create_in`]).
pub fn create() -> io::Result<tempfile::TempDir> {
    create_in(&std::env::temp_dir())
}

/// Removes the port folders in `parent` whose owner process has ended; returns how many.
/// Errors are ignored: another process may be sweeping the same folder, and a folder that
/// cannot be removed is only left as it was.
pub fn sweep_stale(parent: &Path) -> usize {
    if !Path::new("/proc/self").exists() {
        return 0;
    }
    let Ok(entries) = std::fs::read_dir(parent) else {
        return 0;
    };
    let mut removed = 0;
    for entry in entries.flatten() {
        let dir = entry.path();
        let is_port_dir = entry.file_name().to_string_lossy().starts_with(PREFIX)
            && entry.file_type().is_ok_and(|t| t.is_dir());
        if !is_port_dir || !owner_has_ended(&dir) || !holds_only_rig_files(&dir) {
            continue;
        }
        for name in RIG_FILES {
            let _ = std::fs::remove_file(dir.join(name));
        }
        if std::fs::remove_dir(&dir).is_ok() {
            removed += 1;
        }
    }
    removed
}

/// Whether every entry of the folder is one a rig puts there.
fn holds_only_rig_files(dir: &Path) -> bool {
    std::fs::read_dir(dir).is_ok_and(|entries| {
        entries
            .map(|e| e.map(|e| RIG_FILES.iter().any(|n| e.file_name() == *n)))
            .all(|ok| ok.unwrap_or(false))
    })
}

/// Whether the folder names an owner process and that process no longer runs.
fn owner_has_ended(dir: &Path) -> bool {
    let Ok(text) = std::fs::read_to_string(dir.join(OWNER_FILE)) else {
        return false;
    };
    match text.trim().parse::<u32>() {
        Ok(pid) => !Path::new("/proc").join(pid.to_string()).exists(),
        Err(_) => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The id of a process that has ended (a child run and waited for).
    fn ended_pid() -> u32 {
        let mut child = std::process::Command::new("true")
            .spawn()
            .expect("run true");
        let pid = child.id();
        child.wait().expect("wait");
        pid
    }

    fn port_dir(parent: &Path, name: &str, owner: Option<u32>) -> std::path::PathBuf {
        let dir = parent.join(format!("{PREFIX}{name}"));
        std::fs::create_dir(&dir).unwrap();
        if let Some(pid) = owner {
            std::fs::write(dir.join(OWNER_FILE), pid.to_string()).unwrap();
        }
        std::os::unix::fs::symlink("/dev/pts/does-not-exist", dir.join("tty")).unwrap();
        dir
    }

    #[test]
    fn only_folders_of_ended_owners_holding_only_a_rigs_files_are_swept() {
        let parent = tempfile::tempdir().unwrap();
        let ended = ended_pid();
        let dead = port_dir(parent.path(), "dead", Some(ended));
        let live = port_dir(parent.path(), "live", Some(std::process::id()));
        let unowned = port_dir(parent.path(), "unowned", None);
        let kept = port_dir(parent.path(), "kept", Some(ended));
        std::fs::write(kept.join("notes.txt"), "not a rig's").unwrap();
        let other = parent.path().join("other-dead");
        std::fs::create_dir(&other).unwrap();
        std::fs::write(other.join(OWNER_FILE), ended.to_string()).unwrap();

        assert_eq!(sweep_stale(parent.path()), 1);
        assert!(!dead.exists());
        assert!(live.join("tty").symlink_metadata().is_ok());
        assert!(unowned.join("tty").symlink_metadata().is_ok());
        assert!(kept.join("notes.txt").exists());
        assert!(kept.join(OWNER_FILE).exists() && kept.join("tty").symlink_metadata().is_ok());
        assert!(other.exists());
        // a second sweep finds nothing more
        assert_eq!(sweep_stale(parent.path()), 0);
    }

    #[test]
    fn a_new_folder_names_this_process_and_sweeps_the_stale_ones_first() {
        let parent = tempfile::tempdir().unwrap();
        let dead = port_dir(parent.path(), "dead", Some(ended_pid()));
        let dir = create_in(parent.path()).unwrap();
        assert!(!dead.exists());
        let owner = std::fs::read_to_string(dir.path().join(OWNER_FILE)).unwrap();
        assert_eq!(owner, std::process::id().to_string());
        // its own process runs: a sweep leaves it
        assert_eq!(sweep_stale(parent.path()), 0);
        assert!(dir.path().exists());
    }
}
