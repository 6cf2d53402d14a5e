#!/usr/bin/env bash
# Instructions per explicit step of the FPU-β chain at N = 1000 and 1024,
# counted by valgrind's callgrind (they do not depend on the load of the
# machine): the hand-written Verlet against the generated trapezoid
# (Störmer–Verlet) step, on the bench's chain and on the chain as a new user
# writes it, with the size known at compile time and at run time. Each count
# is (Ir of 2·STEPS steps − Ir of STEPS) / STEPS, the steady step: start-up
# cancels, and so does the first step's own work (the generated steps factor
# the mass matrix and size their buffers there, which over none would add
# about 3 500 per step at STEPS = 200). The runs
# are the example `bench/examples/chain_steps.rs` (release build); the last
# column is the count over the plain hand-written Verlet's.
#
#   bench/chain-instructions.sh
#   BIN=/path/to/chain_steps bench/chain-instructions.sh   # another build of the example
set -euo pipefail
cd "$(dirname "$0")/.."

STEPS=200
CASES=(
  hand hand-compensated
  trapezoid trapezoid-plain user-trapezoid user-trapezoid-plain
  dyn-trapezoid dyn-trapezoid-plain dyn-user-trapezoid dyn-user-trapezoid-plain
  stepper-trapezoid stepper-trapezoid-plain stepper-user-trapezoid stepper-user-trapezoid-plain
  problem-trapezoid problem-trapezoid-plain problem-user-trapezoid problem-user-trapezoid-plain
)

source scripts/callgrind.sh
if [[ -z "${BIN:-}" ]]; then
  cargo build --release -p lagrangian-bench --example chain_steps >&2
fi
bin=${BIN:-${CARGO_TARGET_DIR:-target}/release/examples/chain_steps}

count() { # case n steps -> total Ir
  callgrind_total "$bin" "$1" "$2" "$3"
}

echo "| N | case | instructions per step | / hand |"
echo "| --- | --- | --- | --- |"
for n in 1000 1024; do
  hand=0
  for c in "${CASES[@]}"; do
    per=$(( ($(count "$c" "$n" $((2 * STEPS))) - $(count "$c" "$n" $STEPS) + STEPS / 2) / STEPS ))
    [[ $c == hand ]] && hand=$per
    echo "| $n | $c | $per | $(awk -v a="$per" -v b="$hand" 'BEGIN { printf "%.2f", a / b }') |"
  done
done
