#!/usr/bin/env bash
# Runs an ensemble of 10 000 pendulum runs as a Slurm array job of 8 tasks
# (ensemble.sbatch), merges the shards with `ensemble::merge` and checks the
# merged result against a serial run bit for bit; prints each command it
# runs and the wall times. Expects a running cluster (setup.sh on this
# machine, or a real one). From the repository root:
# scripts/slurm/run.sh [MEMBERS] [OUTPUT DIR]
set -euo pipefail
cd "$(dirname "$0")/../.."
members=${1:-10000}
dir=$(realpath -m "${2:-target/slurm-ensemble}")
target=$(realpath -m "${CARGO_TARGET_DIR:-target}")
binary=$target/release/examples/ensemble_shard

# Each command, shown before it runs.
run() {
    echo "\$ $*"
    "$@"
}

echo "# $(date -u '+%Y-%m-%d %H:%M UTC'), $(hostname -s): $(sinfo --noheader --format='%P %D node(s), %c CPUs, %m MB, %T')"
run cargo build --quiet --release --example ensemble_shard
rm -rf "$dir" && mkdir -p "$dir"

start=$(date +%s.%N)
run sbatch --wait --output="$dir/slurm-%A_%a.out" scripts/slurm/ensemble.sbatch "$binary" "$members" "$dir"
array=$(date +%s.%N)
run cat "$dir"/slurm-*.out
shards=$(ls "$dir"/shard-*.json | wc -l)
run "$binary" merge --members "$members" --shards "$shards" --dir "$dir"
end=$(date +%s.%N)
printf '# wall time: array job %.1f s (submission to the end of the last task), merge and serial check %.1f s\n' \
    "$(echo "$array - $start" | bc)" "$(echo "$end - $array" | bc)"
