#!/usr/bin/env bash
# Instructions per step of `DynConstrained` (midpoint, h = 1e-3) on a hanging
# chain of 100 … 10 000 planar links in Cartesian coordinates (N = 2 links
# coordinates, M = links constraints), counted by valgrind's callgrind (they
# do not depend on the load of the machine), and the least-squares exponent
# of the count in the number of links. Each count is (Ir of STEPS steps − Ir
# of none) / STEPS, so the start (the structure probe, the first
# factorisations) and the process cancel. The runs are the runtime's unit
# test `steps_of_a_chain_for_callgrind` (test profile, opt-level 2).
#
#   scripts/constrained-chain-instructions.sh
set -euo pipefail
cd "$(dirname "$0")/.."

STEPS=10
SIZES=(100 300 1000 3000 10000)

command -v valgrind >/dev/null || { echo "valgrind not found" >&2; exit 1; }
bin=$(cargo test -p lagrangian-runtime --lib --no-run --message-format=json 2>/dev/null \
  | python3 -c 'import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["name"] == "lagrangian_runtime":
        print(m["executable"])')
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

count() { # links steps -> total Ir
  LINKS=$1 STEPS=$2 valgrind --tool=callgrind --callgrind-out-file="$tmp/out" "$bin" --ignored --exact \
    constrained::dynamic::tests::steps_of_a_chain_for_callgrind --test-threads=1 >/dev/null 2>"$tmp/err" \
    || { cat "$tmp/err" >&2; exit 1; }
  grep -m1 '^summary:' "$tmp/out" | awk '{print $2}'
}

echo "| links | N | M | instructions per step |"
echo "| --- | --- | --- | --- |"
points=""
for links in "${SIZES[@]}"; do
  full=$(count "$links" $STEPS)
  none=$(count "$links" 0)
  per=$(( (full - none + STEPS / 2) / STEPS ))
  echo "| $links | $((2 * links)) | $links | $per |"
  points+="$links $per"$'\n'
done
printf '%s' "$points" | python3 -c 'import math, sys
xs, ys = zip(*[(math.log(float(a)), math.log(float(b))) for a, b in (l.split() for l in sys.stdin if l.strip())])
mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
print(f"fitted exponent of the instructions per step in the number of links: {slope:.3f}")'
