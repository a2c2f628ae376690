#!/usr/bin/env bash
# The sharding contract on a job (default: data/jobs/default_city_40.ron):
# a single run against merged shards, N = 1, 2, 3 and 8.
# - Always byte-identical: every *_mask.png, *_reference.png, *_shaded.png
#   and the mask-derived columns (checked; a difference fails).
# - Listed: the columns and images that depend on coherent history.
# - With --keyframe K (K = 5; shard boundaries of N = 1, 2 and 8 fall on
#   multiples of 5): identical in every column but the times, and every
#   image (checked).
# Set WARMUP_STUDY=1 to also list the differences of N = 8 with warm-up 0
# and 2× the default.
#
#   scripts/shard_check.sh [JOB] [BIN]
set -euo pipefail
cd "$(dirname "$0")/.."
job=${1:-data/jobs/default_city_40.ron}
bin=${2:-target/release/shadowcull}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
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
run "$work/single_k5" --keyframe 5
for n in 1 2 3 8; do
  echo "N = $n (warm-up: the default):"
  sharded plain "$n"
  scripts/stats_diff.sh "$work/single" "$work/plain_merged$n" --exact "${mask_cols[@]}" | sed 's/^/    /'
done
for n in 1 2 8; do
  echo "N = $n, --keyframe 5:"
  sharded key "$n" --keyframe 5
  scripts/stats_diff.sh "$work/single_k5" "$work/key_merged$n" --exact-non-timing | sed 's/^/    /'
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
