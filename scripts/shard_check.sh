#!/usr/bin/env bash
# The sharding contract on a job (default: data/jobs/default_city_40.ron):
# a single run against merged shards, N = 1, 2, 3 and 8.
# - Always byte-identical: every *_mask.png, *_reference.png, *_shaded.png
#   and the mask-derived columns (checked; a difference fails).
# - Listed: the columns and images that depend on coherent history.
# - With keyframes every K frames (K must divide F/8, so that the shard
#   boundaries of N = 1, 2 and 8 fall on keyframes): identical in every
#   column but the times, and every image (checked).
# Set WARMUP_STUDY=1 to also list the differences of N = 8 with warm-up 0
# and 2x the default.
#
#   scripts/shard_check.sh [--frames F] [--keyframe K] [--resolution WxH] [JOB] [BIN]
#
# --frames F and --resolution WxH run a copy of the job with `frames: F` and
# `resolution: (W, H)` (the job must state both); the defaults are the job's
# own F and resolution, and K = F/8.
set -euo pipefail
cd "$(dirname "$0")/.."
frames= keyframe= resolution=
args=()
while [ $# -gt 0 ]; do
  case $1 in
    --frames) frames=$2; shift ;;
    --keyframe) keyframe=$2; shift ;;
    --resolution) resolution=$2; shift ;;
    -*) echo "shard_check.sh: unknown option $1" >&2; exit 2 ;;
    *) args+=("$1") ;;
  esac
  shift
done
job=${args[0]:-data/jobs/default_city_40.ron}
bin=${args[1]:-target/release/shadowcull}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
job_frames=$(sed -n 's/^ *frames: *\([0-9]*\),.*/\1/p' "$job")
if [ -z "$job_frames" ]; then
  echo "shard_check.sh: $job has no 'frames: N,' line" >&2
  exit 2
fi
if [ -n "$frames" ] || [ -n "$resolution" ]; then
  copy=$work/$(basename "$job")
  sed -e "s/^\( *frames: *\)[0-9]*,/\1${frames:-$job_frames},/" "$job" >"$copy"
  if [ -n "$resolution" ]; then
    w=${resolution%x*} h=${resolution#*x}
    grep -q '^ *resolution: *([0-9]*, *[0-9]*),' "$copy" || {
      echo "shard_check.sh: $job has no 'resolution: (W, H),' line" >&2
      exit 2
    }
    sed -i "s/^\( *resolution: *\)([0-9]*, *[0-9]*),/\1($w, $h),/" "$copy"
  fi
  # A job's scene file is relative to its directory, which the copy lacks.
  if grep -q '^ *scene: *[A-Za-z]*( *"' "$copy"; then
    echo "shard_check.sh: $job loads a scene file; --frames and --resolution take built-in scenes" >&2
    exit 2
  fi
  job=$copy
fi
frames=${frames:-$job_frames}
keyframe=${keyframe:-$((frames / 8))}
if [ "$keyframe" -lt 1 ] || [ $((frames % 8)) -ne 0 ] || [ $((frames / 8 % keyframe)) -ne 0 ]; then
  echo "shard_check.sh: F = $frames must be a multiple of 8 and K = $keyframe must divide F/8" >&2
  exit 2
fi
echo "shard check: $job, F = $frames frames, keyframes every K = $keyframe"
mask_cols=(lit shadow unlit background ambiguous shadowed_pixels mismatch_pixels
  mismatch_off_boundary ambiguous_pixels compared_pixels)

run() { # out, args...
  local out=$1
  shift
  local t0=$EPOCHREALTIME
  "$bin" run "$job" --out "$out" "$@" >/dev/null 2>"$work/log" || { cat "$work/log" >&2; exit 1; }
  awk -v a="$t0" -v b="$EPOCHREALTIME" -v n="$(basename "$out")" 'BEGIN { printf "  %-28s %6.1f s\n", n, b - a }'
}
sharded() { # tag, N, args...
  local tag=$1 n=$2
  shift 2
  local dirs=()
  for ((i = 0; i < n; i++)); do
    run "$work/${tag}_${i}of$n" --shard "$i/$n" "$@"
    dirs+=("$work/${tag}_${i}of$n")
  done
  "$bin" merge "$work/${tag}_merged$n" "${dirs[@]}" 2>/dev/null
}

echo "single runs:"
run "$work/single"
run "$work/single_k" --keyframe "$keyframe"
for n in 1 2 3 8; do
  echo "N = $n (warm-up: the default):"
  sharded plain "$n"
  scripts/stats_diff.sh "$work/single" "$work/plain_merged$n" --exact "${mask_cols[@]}" | sed 's/^/    /'
done
for n in 1 2 8; do
  echo "N = $n, --keyframe $keyframe:"
  sharded key "$n" --keyframe "$keyframe"
  scripts/stats_diff.sh "$work/single_k" "$work/key_merged$n" --exact-non-timing | sed 's/^/    /'
done
if [ "${WARMUP_STUDY:-0}" = 1 ]; then
  revisit=5 # the job's pipeline.chcpp.revisit (the default)
  for w in 0 $((2 * revisit)); do
    echo "N = 8, --warmup $w:"
    sharded "w$w" 8 --warmup "$w"
    scripts/stats_diff.sh "$work/single" "$work/w${w}_merged8" --exact "${mask_cols[@]}" | sed 's/^/    /'
  done
fi
echo "shard check: masks and mask-derived columns equal for every N; with keyframes every non-timing column"
