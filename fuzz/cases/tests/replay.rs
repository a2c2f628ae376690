//! Every committed fuzz input (`fuzz/regressions`, `fuzz/corpus-min`) through
//! its target, on the toolchain that runs the suite: the stable half of the
//! fuzzing check (`.ci/run` adds fresh fuzzing with nightly).

use std::process::Command;

#[test]
fn every_committed_input_replays_without_a_finding() {
    let out = Command::new(env!("CARGO_BIN_EXE_fuzz_replay"))
        .output()
        .expect("fuzz_replay runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    print!("{stdout}");
    assert!(
        out.status.success(),
        "fuzz_replay failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // One line per target, and every target has committed inputs.
    for t in fuzz_cases::TARGETS {
        let line = (stdout.lines())
            .find(|l| l.starts_with(&format!("replay {}: ", t.name)))
            .unwrap_or_else(|| panic!("no replay line for {}", t.name));
        assert!(
            !line.starts_with(&format!("replay {}: 0 inputs", t.name)),
            "{line}: the target has no committed inputs"
        );
    }
}
