#!/usr/bin/env bash
# Instructions per step of constrained steps (and of the same systems in
# minimal coordinates), counted by valgrind's callgrind: they do not depend
# on the load of the machine. Each count is (Ir of STEPS steps − Ir of none)
# / STEPS, so start-up and the process itself cancel. The runs are the
# example `bench/examples/constrained_steps.rs` (release build); the Newton
# iterations per step are those the example prints.
#
#   bench/constrained-instructions.sh
#   BIN=/path/to/constrained_steps bench/constrained-instructions.sh   # another build of the example
set -euo pipefail
cd "$(dirname "$0")/.."

STEPS=2000
# case and step size
CASES=(
  "pendulum-angle-midpoint 0.01" "pendulum-midpoint 0.01"
  "double-angle-midpoint 0.01" "double-midpoint 0.01"
  "double-galerkin2 0.01" "double-galerkin4 0.01" "double-galerkin4 0.05"
  "double-yoshida4 0.01" "double-yoshida6 0.021" "double-kahan-li8 0.021"
  "double-angle-galerkin4 0.01" "double-angle-galerkin4 0.05"
)

source scripts/callgrind.sh
if [[ -z "${BIN:-}" ]]; then
  cargo build --release -p lagrangian-bench --example constrained_steps >&2
fi
bin=${BIN:-${CARGO_TARGET_DIR:-target}/release/examples/constrained_steps}

count() { # case h steps -> total Ir
  callgrind_total "$bin" "$1" "$3" "$2"
}

echo "| case | h | instructions per step | Newton iterations per step |"
echo "| --- | --- | --- | --- |"
for c in "${CASES[@]}"; do
  read -r case h <<<"$c"
  full=$(count "$case" "$h" $STEPS)
  newton=$(grep -o 'per step: [0-9.]*' "$callgrind_dir/err" | awk '{print $3}')
  none=$(count "$case" "$h" 0)
  echo "| $case | $h | $(( (full - none + STEPS / 2) / STEPS )) | $newton |"
done
