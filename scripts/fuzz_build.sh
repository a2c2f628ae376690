#!/usr/bin/env bash
# Builds every fuzz target of fuzz/ as a libFuzzer binary with the nightly
# toolchain: coverage instrumentation, AddressSanitizer, debug assertions
# and `--cfg fuzzing`, the flags `cargo fuzz build` uses (cargo-fuzz 0.13),
# without needing cargo-fuzz installed. The binaries land in
# fuzz/target/x86_64-unknown-linux-gnu/release/TARGET, where `cargo fuzz run`
# looks too.
#
#   scripts/fuzz_build.sh [--codegen-units N] [--opt-level N] [TARGET...]
#
# --codegen-units: cargo-fuzz builds with 1 (faster fuzzing, slower build);
# the default here is 16. --opt-level: cargo-fuzz's is 3, the default here
# too. CI's few seconds per target build fastest with both lowered;
# scripts/fuzz_campaign.sh builds with one codegen unit at level 3.
set -euo pipefail
cd "$(dirname "$0")/../fuzz"
cgu=16 opt=3
bins=()
while [ $# -gt 0 ]; do
  case $1 in
    --codegen-units) cgu=$2; shift ;;
    --opt-level) opt=$2; shift ;;
    -*) echo "fuzz_build.sh: unknown option $1" >&2; exit 2 ;;
    *) bins+=(--bin "$1") ;;
  esac
  shift
done
[ ${#bins[@]} -gt 0 ] || bins=(--bins)
triple=$(rustc +nightly -vV | sed -n 's/^host: //p')
flags=(
  -Cpasses=sancov-module
  -Cllvm-args=-sanitizer-coverage-level=4
  -Cllvm-args=-sanitizer-coverage-inline-8bit-counters
  -Cllvm-args=-sanitizer-coverage-pc-table
  -Cllvm-args=-sanitizer-coverage-trace-compares
  -Cllvm-args=-sanitizer-coverage-stack-depth
  -Cllvm-args=-simplifycfg-branch-fold-threshold=0
  --cfg fuzzing
  -Zsanitizer=address
  -Cdebug-assertions
  "-Ccodegen-units=$cgu"
)
# --target keeps the flags off build scripts and proc macros.
RUSTFLAGS="${flags[*]} ${RUSTFLAGS:-}" cargo +nightly build --release --target "$triple" \
  --config 'profile.release.debug="line-tables-only"' --config "profile.release.opt-level=$opt" \
  "${bins[@]}"
