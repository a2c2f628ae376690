#!/usr/bin/env bash
# One shard of a shadowcull batch job per task of a Slurm job array.
#
#   sbatch --array=0-7 examples/cluster/slurm_array.sh JOB.ron OUT [RUN ARGS...]
#
# Task I of N writes OUT/shard_I (stats.csv, frames/, summary.json and, last,
# shard.json) and its per-frame log as JSON lines in OUT/shard_I.jsonl. When
# every task has finished, `shadowcull merge OUT/merged OUT/shard_*/` gives the
# single run's output (submit.sh chains the two). Extra RUN ARGS go to
# `shadowcull run` (`--keyframe 5`, `--warmup 10`, `--frames 40`); every task
# must get the same ones. Any other array scheduler works the same way: pass
# its task index and count as `--shard I/N`.
#SBATCH --job-name=shadowcull
#SBATCH --cpus-per-task=2
#SBATCH --mem=8G
#SBATCH --time=02:00:00
#SBATCH --output=slurm-%A_%a.out
set -euo pipefail
job=${1:?usage: slurm_array.sh JOB.ron OUT [RUN ARGS...]}
out=${2:?usage: slurm_array.sh JOB.ron OUT [RUN ARGS...]}
shift 2
i=${SLURM_ARRAY_TASK_ID:?submit with sbatch --array=0-(N-1)}
# The array's size: its task count, or its largest index + 1 (indices from 0).
n=${SLURM_ARRAY_TASK_COUNT:-$((${SLURM_ARRAY_TASK_MAX:?no array size} + 1))}
shadowcull=${SHADOWCULL:-shadowcull}
mkdir -p "$out"
# Rayon uses the task's CPUs, not the node's.
export RAYON_NUM_THREADS=${SLURM_CPUS_PER_TASK:-2}
"$shadowcull" run "$job" --out "$out/shard_$i" --shard "$i/$n" --log-format json "$@" \
  > "$out/shard_$i.jsonl"
