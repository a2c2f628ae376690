//! The shared corpus and scratch directories.

use std::path::{Path, PathBuf};

/// The workspace root (the directory of the facade's `Cargo.toml`).
pub fn workspace_root() -> &'static Path {
    // This crate lives in `crates/testkit` of the workspace.
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// The shared corpus, `../shared/data` relative to the workspace root, or
/// `None` with a printed note when it is absent (as in a user's clone): a test
/// that needs it returns early.
pub fn shared_data() -> Option<PathBuf> {
    let dir = workspace_root().join("../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else {
        println!(
            "note: {} is absent; skipping what needs the shared data",
            dir.display()
        );
        None
    }
}

/// A file of the shared corpus by its path inside `../shared/data` (e.g.
/// `bench/city_4096.txt`), or `None` with a printed note when it is absent.
pub fn shared_file(relative: &str) -> Option<PathBuf> {
    let file = shared_data()?.join(relative);
    if file.is_file() {
        Some(file)
    } else {
        println!("note: {} is absent; skipping what needs it", file.display());
        None
    }
}

/// The workspace's shared-scene jobs (`data/jobs/shared_*.ron`) whose file
/// name contains `pick`, sorted; empty (with a printed note) when the shared
/// corpus they load is absent.
pub fn shared_jobs(pick: &str) -> Vec<PathBuf> {
    if shared_data().is_none() {
        return Vec::new();
    }
    let dir = workspace_root().join("data/jobs");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("a directory entry").path())
        .filter(|p| {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            name.starts_with("shared_") && name.ends_with(".ron") && name.contains(pick)
        })
        .collect();
    files.sort();
    files
}

/// A fresh, empty directory `shadowcull-<pid>-<name>` under the system's
/// temporary directory (emptied first when a previous run left it behind),
/// removed with everything in it when the value is dropped: a test leaves
/// nothing behind, pass or fail (a failing test's panic unwinds through the
/// drop).
pub fn scratch_dir(name: &str) -> ScratchDir {
    let dir = std::env::temp_dir().join(format!("shadowcull-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    ScratchDir(dir)
}

/// A test's temporary directory ([`scratch_dir`]): a path that removes its
/// directory when dropped. Derefs to [`Path`].
#[derive(Debug)]
pub struct ScratchDir(PathBuf);

impl std::ops::Deref for ScratchDir {
    type Target = Path;

    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for ScratchDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for ScratchDir {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
