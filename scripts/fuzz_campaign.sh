#!/usr/bin/env bash
# One fuzzing campaign: TARGET for SECONDS of libFuzzer, seeded from its
# committed inputs (fuzz/corpus-min/TARGET, fuzz/regressions/TARGET), the
# project's own seeds and, when ../shared/data is present, the shared data
# (read, never copied into the repository). New inputs go to the campaign's
# corpus, fuzz/corpus/TARGET (not committed); a crash to
# fuzz/artifacts/TARGET/ and a non-zero exit. The libFuzzer summary (runs,
# coverage, corpus) is appended to fuzz/HOURS.md.
#
#   scripts/fuzz_campaign.sh [options] TARGET SECONDS
#   scripts/fuzz_campaign.sh --list
#   scripts/fuzz_campaign.sh --seeds TARGET   (its seed directories, from fuzz/)
#
# Options:
#   --no-build      use the binary scripts/fuzz_build.sh built before
#   --codegen-units N
#                   passed to scripts/fuzz_build.sh (default 1 here: the
#                   fastest fuzzing, as cargo-fuzz builds)
#   --scratch       a temporary corpus and artifact directory (under TMPDIR,
#                   removed; a crash input is printed in base64) instead of
#                   fuzz/corpus/TARGET and fuzz/artifacts/TARGET, no seeding
#                   from fuzz/corpus-min (`cargo test` replays it, and running
#                   it again would take the run's seconds), and nothing
#                   appended to HOURS.md: the short runs of CI
#   --seed N        libFuzzer's -seed (default 1: the same run every time)
#
# Targets: every binary of fuzz/Cargo.toml, c_abi included.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

# Target, then its seed directories: the project's own (relative to fuzz/),
# then the shared data's (skipped when absent).
specs=(
  "gltf seeds/gltf ../../shared/data/edge_gltf ../../shared/data/scenes"
  "obj seeds/obj ../../shared/data/edge_obj"
  "box_city seeds/box_city ../../shared/data/bench"
  "job ../data/jobs"
  "raster"
  "volumes"
  "light_views"
  "pipeline seeds/pipeline"
  "shards seeds/pipeline"
  "c_abi"
)

build=1 cgu=1 scratch=0 seed=1
args=()
while [ $# -gt 0 ]; do
  case $1 in
    --list)
      for s in "${specs[@]}"; do echo "${s%% *}"; done
      exit 0 ;;
    --seeds)
      want=${2:-}
      for s in "${specs[@]}"; do
        read -r -a spec <<<"$s"
        if [ "${spec[0]}" = "$want" ]; then
          [ ${#spec[@]} -gt 1 ] && printf '%s\n' "${spec[@]:1}"
          exit 0
        fi
      done
      echo "fuzz_campaign.sh: no target $want" >&2
      exit 2 ;;
    --no-build) build=0 ;;
    --codegen-units) cgu=$2; shift ;;
    --scratch) scratch=1 ;;
    --seed) seed=$2; shift ;;
    -*) echo "fuzz_campaign.sh: unknown option $1" >&2; exit 2 ;;
    *) args+=("$1") ;;
  esac
  shift
done
if [ ${#args[@]} -ne 2 ]; then
  echo "usage: scripts/fuzz_campaign.sh [--no-build] [--codegen-units N] [--scratch] [--seed N] TARGET SECONDS" >&2
  exit 2
fi
target=${args[0]} seconds=${args[1]}
seeds=()
for s in "${specs[@]}"; do
  set -- $s
  if [ "$1" = "$target" ]; then
    shift
    seeds=("$@")
    found=1
  fi
done
if [ -z "${found:-}" ]; then
  echo "fuzz_campaign.sh: no target $target (targets: $(for s in "${specs[@]}"; do printf '%s ' "${s%% *}"; done))" >&2
  exit 2
fi
case $seconds in
  '' | *[!0-9]*) echo "fuzz_campaign.sh: SECONDS must be a whole number, not $seconds" >&2; exit 2 ;;
esac

[ "$build" = 1 ] && scripts/fuzz_build.sh --codegen-units "$cgu" "$target"
triple=$(rustc +nightly -vV | sed -n 's/^host: //p')
bin=$root/fuzz/target/$triple/release/$target
if [ ! -x "$bin" ]; then
  echo "fuzz_campaign.sh: $bin is not built (scripts/fuzz_build.sh $target)" >&2
  exit 1
fi

cd fuzz
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
if [ "$scratch" = 1 ]; then
  corpus=$work/corpus artifacts=$work/artifacts
else
  corpus=corpus/$target artifacts=artifacts/$target
fi
mkdir -p "$corpus" "$artifacts"
committed=("corpus-min/$target" "regressions/$target")
[ "$scratch" = 1 ] && committed=("regressions/$target")
dirs=()
for d in "${committed[@]}" "${seeds[@]}"; do
  if [ -d "$d" ]; then dirs+=("$d"); fi
done
start=$(date -u +%Y-%m-%dT%H:%M:%SZ)
t0=$SECONDS
status=0
ASAN_OPTIONS="detect_odr_violation=0${ASAN_OPTIONS:+:$ASAN_OPTIONS}" \
  "$bin" "$corpus" "${dirs[@]}" -max_total_time="$seconds" -seed="$seed" -rss_limit_mb=4096 \
  -print_final_stats=1 -artifact_prefix="$artifacts/" 2>"$work/log" || status=$?
wall=$((SECONDS - t0))
# The last status line (#N DONE / #N pulse ...) and the final stats.
last=$(grep -E '^#[0-9]+' "$work/log" | tail -n 1 || true)
runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$work/log" | tail -n 1)
cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$last")
ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$last")
corp=$(sed -n 's/.* corp: \([^ ]*\).*/\1/p' <<<"$last")
if [ "$status" = 0 ]; then crashes=none; else crashes="exit $status, see fuzz/artifacts/$target/"; fi
echo "fuzz $target: ${wall} s, ${runs:-?} runs, cov ${cov:-?}, ft ${ft:-?}, corpus ${corp:-?}, crashes: $crashes"
if [ "$status" != 0 ]; then
  tail -n 60 "$work/log" >&2
  if [ "$scratch" = 1 ]; then
    for f in "$artifacts"/*; do
      [ -f "$f" ] && echo "fuzz $target: $(basename "$f") (base64): $(base64 -w0 "$f")" >&2
    done
  fi
fi
if [ "$scratch" = 0 ]; then
  if ! grep -q '^## Campaigns of scripts/fuzz_campaign.sh' HOURS.md; then
    {
      echo
      echo '## Campaigns of scripts/fuzz_campaign.sh'
      echo
      echo 'One row per campaign, appended by the script (wall seconds; libFuzzer'"'"'s'
      echo 'final counts; the corpus is fuzz/corpus/TARGET on the machine that ran it).'
      echo
      echo '| target | campaign start (UTC) | commit | wall s | runs | cov | ft | corpus | crashes |'
      echo '|---|---|---|---|---|---|---|---|---|'
    } >>HOURS.md
  fi
  commit=$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo '?')
  echo "| \`$target\` | $start | \`$commit\` | $wall | ${runs:-?} | ${cov:-?} | ${ft:-?} | ${corp:-?} | $crashes |" >>HOURS.md
fi
exit "$status"
