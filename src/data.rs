//! Where the data shipped with brdf-rig lives (meshes, neural MERL fits, their test vectors), so
//! the binary works from the repository, or installed elsewhere with its data copied beside it.
//!
//! `$BRDF_RIG_DATA`, when set, is used as it is (a wrong path then shows in the errors, rather
//! than being skipped silently). Otherwise, first existing folder wins:
//! 1. `<folder of the executable>/../share/brdf-rig/data` (an installed layout);
//! 2. `<folder of the executable>/data` (a copied binary with its data beside it);
//! 3. the repository's `data/` (`CARGO_MANIFEST_DIR` at build time).
//!
//! When none exists the repository path is returned, so errors name a real place to put it.
//! Touches only the environment and the file system's metadata; reads no file.

use std::path::{Path, PathBuf};

/// The data folder (see the module header for the search order).
pub fn data_dir() -> PathBuf {
    let exe_dir = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf));
    let env = std::env::var_os("BRDF_RIG_DATA").map(PathBuf::from);
    choose(
        env,
        exe_dir.as_deref(),
        Path::new(env!("CARGO_MANIFEST_DIR")),
    )
}

/// `env` if set; else the first candidate that is a folder, else the repository's.
fn choose(env: Option<PathBuf>, exe_dir: Option<&Path>, manifest: &Path) -> PathBuf {
    if let Some(e) = env {
        return e;
    }
    let repo = manifest.join("data");
    let mut candidates: Vec<PathBuf> = Vec::new();
    if let Some(d) = exe_dir {
        candidates.push(d.join("../share/brdf-rig/data"));
        candidates.push(d.join("data"));
    }
    candidates.into_iter().find(|p| p.is_dir()).unwrap_or(repo)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn the_first_existing_candidate_wins_and_the_repository_is_the_fallback() {
        let root = tempfile::tempdir().unwrap();
        let bin = root.path().join("bin");
        let share = root.path().join("share/brdf-rig/data");
        std::fs::create_dir_all(&bin).unwrap();
        let repo = root.path().join("repo");
        // nothing exists: the repository's path, so errors name it
        assert_eq!(choose(None, Some(&bin), &repo), repo.join("data"));
        // an installed layout
        std::fs::create_dir_all(&share).unwrap();
        assert_eq!(
            choose(None, Some(&bin), &repo),
            bin.join("../share/brdf-rig/data")
        );
        // a copied binary with its data beside it loses to the installed layout (found first)
        std::fs::create_dir_all(bin.join("data")).unwrap();
        assert_eq!(
            choose(None, Some(&bin), &repo),
            bin.join("../share/brdf-rig/data")
        );
        std::fs::remove_dir_all(root.path().join("share")).unwrap();
        assert_eq!(choose(None, Some(&bin), &repo), bin.join("data"));
        // the environment always wins, even naming nothing (its errors then name it)
        let env = root.path().join("mine");
        assert_eq!(choose(Some(env.clone()), Some(&bin), &repo), env);
    }
}
