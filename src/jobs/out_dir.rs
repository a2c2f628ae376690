//! Output directories: a run, a merge or a comparison holds an exclusive
//! lock on its directory while it writes, and a run or merge first removes
//! what an earlier one left there, so two writers never mix their files and
//! a rerun never leaves the previous run's files beside its own.
//!
//! The lock is an advisory file lock (`flock` on Unix) on `.shadowcull.lock`
//! in the directory, released when the holder ends, however it ends (a
//! killed run leaves no stale lock). The lock file itself stays.

use crate::error::io_err;
use crate::{Error, Result};
use std::fs::{File, OpenOptions, TryLockError};
use std::path::{Path, PathBuf};

/// The lock file's name in an output directory.
pub const LOCK_FILE: &str = ".shadowcull.lock";

/// What `run` and `merge` own in their output directory (with the
/// temporary names of their atomic writes): removed before they write, and
/// nothing else is touched.
pub(crate) const RUN_OUTPUTS: &[&str] = &[
    "stats.csv",
    "summary.json",
    "summary.json.tmp",
    "shard.json",
    "shard.json.tmp",
    "stats.csv.tmp",
    "frames",
];

/// An exclusive lock on an output directory, held until dropped.
#[derive(Debug)]
pub(crate) struct OutputLock {
    _file: File,
}

impl OutputLock {
    /// Creates `dir` if missing and locks it.
    ///
    /// # Errors
    /// [`Error::OutputBusy`] when another process holds the lock; I/O errors.
    pub(crate) fn acquire(dir: &Path) -> Result<OutputLock> {
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
        let path = dir.join(LOCK_FILE);
        let file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(io_err(&path))?;
        match file.try_lock() {
            Ok(()) => Ok(OutputLock { _file: file }),
            Err(TryLockError::WouldBlock) => Err(Error::OutputBusy {
                dir: dir.to_path_buf(),
                lock: path,
            }),
            Err(TryLockError::Error(e)) => Err(io_err(&path)(e)),
        }
    }
}

/// Locks `dir` and removes what a run owns there ([`RUN_OUTPUTS`]).
///
/// # Errors
/// As [`OutputLock::acquire`]; a failed removal names the file.
pub(crate) fn claim_for_run(dir: &Path) -> Result<OutputLock> {
    let lock = OutputLock::acquire(dir)?;
    for name in RUN_OUTPUTS {
        let path: PathBuf = dir.join(name);
        let removed = match std::fs::symlink_metadata(&path) {
            Ok(m) if m.is_dir() => std::fs::remove_dir_all(&path),
            Ok(_) => std::fs::remove_file(&path),
            Err(_) => Ok(()),
        };
        removed.map_err(io_err(&path))?;
    }
    Ok(lock)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_is_refused_until_the_first_is_dropped() {
        let dir = testkit::scratch_dir("lock");
        let first = OutputLock::acquire(&dir).unwrap();
        let e = OutputLock::acquire(&dir).unwrap_err();
        assert!(matches!(e, Error::OutputBusy { .. }), "{e}");
        assert!(e.to_string().contains("another shadowcull"), "{e}");
        drop(first);
        let again = OutputLock::acquire(&dir).unwrap();
        drop(again);
    }

    #[test]
    fn a_claim_removes_what_a_run_owns_and_nothing_else() {
        let dir = testkit::scratch_dir("claim");
        std::fs::create_dir_all(dir.join("frames")).unwrap();
        std::fs::create_dir_all(dir.join("mine")).unwrap();
        for f in [
            "stats.csv",
            "summary.json",
            "shard.json",
            "frames/9_0_mask.png",
        ] {
            std::fs::write(dir.join(f), "old").unwrap();
        }
        std::fs::write(dir.join("notes.txt"), "keep").unwrap();
        std::fs::write(dir.join("mine/summary.json"), "keep").unwrap();
        let lock = claim_for_run(&dir).unwrap();
        for f in ["stats.csv", "summary.json", "shard.json", "frames"] {
            assert!(!dir.join(f).exists(), "{f}");
        }
        assert!(dir.join("notes.txt").exists() && dir.join("mine/summary.json").exists());
        drop(lock);
    }
}
