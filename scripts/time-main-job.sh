#!/usr/bin/env bash
# Times the main job as a new user meets it: a fresh clone of this
# repository's HEAD, `cargo build --release -p lagrangian-bench` into an empty
# target directory (dependencies downloaded before the clock starts), then
# `cargo run --release -p lagrangian-bench` with the time of every output line.
# Prints the build time, the time to the first progress line, the run time and
# the load average, which the README's table of the main job quotes.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
git clone --quiet "$repo" "$work/lagrangian"
cd "$work/lagrangian"
export CARGO_TARGET_DIR="$work/target"
cargo fetch --quiet
echo "commit $(git rev-parse --short HEAD); $(nproc) cores; load at start $(cut -d' ' -f1-3 /proc/loadavg)"
start=$(date +%s.%N)
cargo build --quiet --release -p lagrangian-bench
built=$(date +%s.%N)
first=""
while IFS= read -r line; do
    now=$(date +%s.%N)
    [ -z "$first" ] && first=$(echo "$now - $built" | bc)
    printf '%8.2f s  %s\n' "$(echo "$now - $built" | bc)" "$line"
done < <(cargo run --quiet --release -p lagrangian-bench 2>&1)
done_at=$(date +%s.%N)
printf 'build %.0f s; first progress line %.2f s after the run starts; run %.0f s; total %.0f s; load at end %s\n' \
    "$(echo "$built - $start" | bc)" "$first" "$(echo "$done_at - $built" | bc)" "$(echo "$done_at - $start" | bc)" \
    "$(cut -d' ' -f1-3 /proc/loadavg)"
