#!/usr/bin/env bash
# Compares two run directories (a single run and a merge of shards):
# per stats.csv column, the rows that differ and the largest difference, and
# per image of frames/, whether its bytes are equal.
#
#   scripts/stats_diff.sh A B [--exact COLUMN...] [--exact-non-timing]
#
# Prints one line per column that differs and per image that differs.
# Exits 1 when a column named by --exact differs (with --exact-non-timing:
# any column not ending in _ms), when a *_mask.png, *_reference.png or
# *_shaded.png image differs, or when the two runs hold other images or rows.
set -euo pipefail
a=$1 b=$2
shift 2
exact=() non_timing=0 all_images=0
while [ $# -gt 0 ]; do
  case $1 in
    --exact-non-timing) non_timing=1; all_images=1 ;;
    --exact) ;;
    *) exact+=("$1") ;;
  esac
  shift
done
status=0
if [ "$(head -n 1 "$a/stats.csv")" != "$(head -n 1 "$b/stats.csv")" ]; then
  echo "stats.csv headers differ"; exit 1
fi
if [ "$(wc -l < "$a/stats.csv")" != "$(wc -l < "$b/stats.csv")" ]; then
  echo "stats.csv row counts differ"; exit 1
fi
# column name, rows differing, largest |difference|, sum over rows of A and of B
report=$(paste -d '\n' "$a/stats.csv" "$b/stats.csv" | awk -F, '
  NR == 1 { n = NF; for (i = 1; i <= NF; i++) name[i] = $i; next }
  NR == 2 { next }
  NR % 2 == 1 { for (i = 1; i <= NF; i++) x[i] = $i; next }
  {
    for (i = 1; i <= NF; i++) {
      sa[i] += x[i]; sb[i] += $i
      if (x[i] != $i) { rows[i]++; d = x[i] - $i; if (d < 0) d = -d; if (d > mx[i]) mx[i] = d }
    }
  }
  END {
    for (i = 1; i <= n; i++)
      if (rows[i] > 0) printf "%s %d %g %g %g\n", name[i], rows[i], mx[i], sa[i], sb[i]
  }')
while read -r col rows max sum_a sum_b; do
  [ -z "$col" ] && continue
  echo "column $col: $rows rows differ, max |diff| $max, sums $sum_a vs $sum_b"
  if [ $non_timing = 1 ] && [[ $col != *_ms ]]; then status=1; fi
  for e in "${exact[@]}"; do
    if [ "$e" = "$col" ]; then status=1; fi
  done
done <<< "$report"
list() { (cd "$1/frames" 2>/dev/null && ls) | sort; }
if [ "$(list "$a")" != "$(list "$b")" ]; then
  echo "frames/ hold different images"; status=1
fi
same=0 differ=0
for f in $(list "$a"); do
  if cmp -s "$a/frames/$f" "$b/frames/$f"; then
    same=$((same + 1))
  else
    differ=$((differ + 1))
    echo "image $f differs"
    case $f in
      *_mask.png|*_reference.png|*_shaded.png) status=1 ;;
      *) [ $all_images = 1 ] && status=1 ;;
    esac
  fi
done
echo "images: $same equal, $differ differ"
exit $status
