//! Replays fuzz inputs through the fuzz targets' code, on any toolchain and
//! without libFuzzer: the check that every committed input still passes, and
//! the way to rerun a crash that a campaign found.
//!
//! ```text
//! fuzz_replay                    every target over its committed inputs
//! fuzz_replay TARGET PATH...     one target over files or directories
//! ```
//!
//! The committed inputs of a target are the files in `fuzz/regressions/TARGET`
//! (findings) and `fuzz/corpus-min/TARGET` (a corpus minimized with
//! `cargo fuzz cmin`, grown from the project's own seeds).
//! Prints one line per target (`replay TARGET: N inputs in S s`) and every
//! input that panicked or could not be read, and exits 1 if any did, 2 on a
//! usage error. The inputs of a target run side by side (rayon).

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use rayon::prelude::*;

use fuzz_cases::{Target, TARGETS};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let fuzz = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    // Each target to replay and where its inputs are.
    let jobs: Vec<(&Target, Vec<PathBuf>)> = match args.split_first() {
        None => TARGETS
            .iter()
            .map(|t| {
                let dirs = ["regressions", "corpus-min"].map(|d| fuzz.join(d).join(t.name));
                (t, dirs.into_iter().filter(|d| d.is_dir()).collect())
            })
            .collect(),
        Some((name, paths)) => {
            let Some(t) = TARGETS.iter().find(|t| t.name == name) else {
                let names: Vec<&str> = TARGETS.iter().map(|t| t.name).collect();
                eprintln!(
                    "fuzz_replay: no target {name:?} (targets: {})",
                    names.join(", ")
                );
                return ExitCode::from(2);
            };
            if paths.is_empty() {
                eprintln!("usage: fuzz_replay [TARGET PATH...]");
                return ExitCode::from(2);
            }
            vec![(t, paths.iter().map(PathBuf::from).collect())]
        }
    };
    // A panic's message names the input; the default hook prints it.
    let mut failed = 0;
    for (target, paths) in jobs {
        let mut files = Vec::new();
        for p in &paths {
            if let Err(e) = collect(p, &mut files) {
                eprintln!("fuzz_replay: {}: {e}", p.display());
                return ExitCode::from(2);
            }
        }
        files.sort();
        let start = Instant::now();
        // The inputs side by side; each panic is caught and named.
        let outcomes: Vec<Result<(), String>> = (files.par_iter())
            .map(|f| {
                let data = std::fs::read(f).map_err(|e| format!("{}: {e}", f.display()))?;
                match catch_unwind(AssertUnwindSafe(|| (target.run)(&data))) {
                    Ok(()) => Ok(()),
                    Err(_) => Err(format!("{}: {} panicked", target.name, f.display())),
                }
            })
            .collect();
        for e in outcomes.iter().filter_map(|o| o.as_ref().err()) {
            eprintln!("fuzz_replay: {e}");
            failed += 1;
        }
        let seconds = start.elapsed().as_secs_f64();
        println!(
            "replay {}: {} inputs in {seconds:.2} s",
            target.name,
            files.len()
        );
    }
    if failed == 0 {
        ExitCode::SUCCESS
    } else {
        eprintln!("fuzz_replay: {failed} inputs failed");
        ExitCode::FAILURE
    }
}

/// `path` itself when it is a file, else the files below it (recursively).
fn collect(path: &Path, files: &mut Vec<PathBuf>) -> std::io::Result<()> {
    if path.is_file() {
        files.push(path.to_path_buf());
        return Ok(());
    }
    for entry in std::fs::read_dir(path)? {
        collect(&entry?.path(), files)?;
    }
    Ok(())
}
