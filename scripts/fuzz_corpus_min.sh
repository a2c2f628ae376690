#!/usr/bin/env bash
# Refreshes a target's committed corpus, fuzz/corpus-min/TARGET: SECONDS of
# fuzzing seeded from the project's own inputs only (the target's seeds
# under fuzz/ or data/, its regressions and the corpus-min it replaces; never
# ../shared/data, whose files stay out of the repository), then libFuzzer's
# merge (what `cargo fuzz cmin` runs) of everything into the smallest set of
# inputs that keeps the coverage, at most 256 KiB (the largest inputs go
# first when the set is bigger). `cargo test` replays the result on stable
# (fuzz_replay) and `.ci/run` seeds its nightly runs with it.
#
#   scripts/fuzz_corpus_min.sh [--no-build] TARGET SECONDS
set -euo pipefail
cd "$(dirname "$0")/.."
build=1
if [ "${1:-}" = --no-build ]; then
  build=0
  shift
fi
if [ $# -ne 2 ]; then
  echo "usage: scripts/fuzz_corpus_min.sh [--no-build] TARGET SECONDS" >&2
  exit 2
fi
target=$1 seconds=$2
cap=$((256 * 1024))
# The project's own seeds: the spec of scripts/fuzz_campaign.sh without the
# shared data.
own=()
for d in $(scripts/fuzz_campaign.sh --seeds "$target"); do
  case $d in
    ../../shared/*) ;;
    *) own+=("$d") ;;
  esac
done
[ "$build" = 1 ] && scripts/fuzz_build.sh --codegen-units 1 "$target"
triple=$(rustc +nightly -vV | sed -n 's/^host: //p')
bin=$PWD/fuzz/target/$triple/release/$target
cd fuzz
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/grown" "$work/min" "$work/artifacts" "corpus-min/$target"
dirs=()
for d in "corpus-min/$target" "regressions/$target" "${own[@]}"; do
  if [ -d "$d" ]; then dirs+=("$d"); fi
done
export ASAN_OPTIONS="detect_odr_violation=0${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
"$bin" "$work/grown" "${dirs[@]}" -max_total_time="$seconds" -rss_limit_mb=4096 \
  -artifact_prefix="$work/artifacts/" -print_final_stats=1 2>"$work/log" || {
  tail -n 40 "$work/log" >&2
  echo "fuzz_corpus_min.sh: $target stopped on a finding (above); fix it first" >&2
  exit 1
}
merge=("$work/grown")
for d in "corpus-min/$target" "${own[@]}"; do
  if [ -d "$d" ]; then merge+=("$d"); fi
done
"$bin" -merge=1 "$work/min" "${merge[@]}" -rss_limit_mb=4096 2>>"$work/log"
# Within the cap: drop the largest inputs first.
while [ "$(cat "$work"/min/* 2>/dev/null | wc -c)" -gt "$cap" ]; do
  rm -f "$(ls -S "$work"/min/* | head -n 1)"
done
rm -rf "corpus-min/$target"
mkdir -p "corpus-min/$target"
cp "$work"/min/* "corpus-min/$target/" 2>/dev/null || true
echo "corpus-min/$target: $(ls "corpus-min/$target" | wc -l) inputs," \
  "$(cat "corpus-min/$target"/* 2>/dev/null | wc -c) bytes"
