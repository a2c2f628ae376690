#!/usr/bin/env bash
# Submits a shadowcull batch job as a Slurm array of N shards and a merge that
# runs when every shard succeeded.
#
#   examples/cluster/submit.sh JOB.ron OUT N [RUN ARGS...]
#
# The merged output lands in OUT/merged; a failed shard leaves the merge
# pending (afterok), and rerunning that one task with
# `sbatch --array=I slurm_array.sh JOB.ron OUT` then `shadowcull merge` finishes it.
set -euo pipefail
job=${1:?usage: submit.sh JOB.ron OUT N [RUN ARGS...]}
out=${2:?usage: submit.sh JOB.ron OUT N [RUN ARGS...]}
n=${3:?usage: submit.sh JOB.ron OUT N [RUN ARGS...]}
shift 3
here=$(cd "$(dirname "$0")" && pwd)
shadowcull=${SHADOWCULL:-shadowcull}
shards=()
for ((i = 0; i < n; i++)); do shards+=("$out/shard_$i"); done
array=$(sbatch --parsable --array="0-$((n - 1))" "$here/slurm_array.sh" "$job" "$out" "$@")
sbatch --parsable --dependency="afterok:$array" --job-name=shadowcull-merge \
  --wrap "$(printf '%q ' "$shadowcull" merge "$out/merged" "${shards[@]}")"
