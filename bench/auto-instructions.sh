#!/usr/bin/env bash
# Instructions of the tolerance-driven solve (survey, cost model, pilot and
# final run) against the fastest project method the report calibrates to
# the same target, counted by valgrind's callgrind (they do not depend on
# the load of the machine). Each count is the run's total minus that of the
# example's set-up alone (`auto_solve PROBLEM none`). The runs are the
# example `bench/examples/auto_solve.rs` (release build).
#
# Each case is `problem target rtol fastest-method setting`: by default the
# tolerance at which the report's full suite calibrated `auto` and the
# fastest method's calibrated setting (docs/measurements.md, section "Ask
# for an accuracy"), or the tolerance `auto_solve PROBLEM calibrate` finds
# where the solve changed after that timing (the double pendulum, Kepler
# `e = 0.5` and Kepler in polar coordinates at their tight targets); `none`
# where `auto` does not reach the target. With `CALIBRATE=1` the tolerance is calibrated again
# for the build at hand (`auto_solve PROBLEM calibrate`, the report's rule),
# which a change to the solve moves.
#
#   bench/auto-instructions.sh                    # every case
#   bench/auto-instructions.sh sensor fpu-beta    # only these problems
#   CALIBRATE=1 bench/auto-instructions.sh sensor
#   BIN=/path/to/auto_solve bench/auto-instructions.sh
set -euo pipefail
cd "$(dirname "$0")/.."

CASES=(
  "pendulum 1e-4 1e-3 composition-kahan-li8 steps=427"
  "pendulum 1e-7 1.7782794100389227e-6 galerkin-fp-8 steps=180"
  "pendulum 1e-10 3.162277660168379e-9 galerkin-fp-6 steps=508"
  "kepler-0.5 1e-4 1.778279410038923e-4 tt-split-logh-kahan-li-8 sigma=0.8"
  "kepler-0.5 1e-7 1.7782794100389227e-6 tt-split-logh-kahan-li-8 sigma=0.33635856610148585"
  "kepler-0.5 1e-10 1e-9 galerkin-fp-6 steps=404"
  "kepler-0.9 1e-4 1.778279410038923e-4 tt-split-logh-kahan-li-8 sigma=0.6727171322029717"
  "kepler-0.9 1e-7 1.7782794100389227e-6 tt-split-logh-kahan-li-8 sigma=0.28284271247461906"
  "kepler-0.9 1e-10 1e-10 tt-split-logh-kahan-li-8 sigma=0.11892071150027211"
  "henon-heiles 1e-4 5.623413251903491e-4 composition-kahan-li8 steps=141"
  "henon-heiles 1e-7 5.623413251903491e-7 composition-kahan-li8 steps=336"
  "henon-heiles 1e-10 1e-9 galerkin-fp-6 steps=141"
  "outer-solar-system 1e-4 1e-4 composition-kahan-li8 steps=80"
  "outer-solar-system 1e-7 1e-7 composition-kahan-li8 steps=190"
  "outer-solar-system 1e-10 3.1622776601683794e-11 composition-kahan-li8 steps=453"
  "double-pendulum 1e-4 5.6234132519034914e-5 galerkin-fp-4 steps=141"
  "double-pendulum 1e-7 1e-6 galerkin-fp-6 steps=200"
  "double-pendulum 1e-10 5.623413251903491e-9 galerkin-fp-8 steps=200"
  "kepler-polar 1e-4 3.1622776601683796e-6 galerkin-fp-5 steps=28541"
  "kepler-polar 1e-7 1.778279410038923e-9 galerkin-fp-5 steps=57082"
  "kepler-polar 1e-10 1.7782794100389228e-12 galerkin-fp-8 steps=48000"
  "fpu-beta 1e-4 1e-3 composition-kahan-li8 steps=35"
  "fpu-beta 1e-7 1e-3 composition-kahan-li8 steps=71"
  "fpu-beta 1e-10 3.1622776601683794e-11 composition-kahan-li8 steps=168"
  "perturbed-pendulum 1e-4 1e-3 composition-kahan-li8 steps=424"
  "perturbed-pendulum 1e-7 1.7782794100389227e-6 galerkin-fp-6 steps=252"
  "perturbed-pendulum 1e-10 3.162277660168379e-9 galerkin-fp-8 steps=212"
  "sensor 1e-4 1e-3 galerkin-fp-2 steps=40"
  "sensor 1e-7 5.623413251903491e-6 galerkin-fp-4 steps=28"
  "sensor 1e-10 5.623413251903491e-7 galerkin-fp-5 steps=34"
)

source scripts/callgrind.sh
if [[ -z "${BIN:-}" ]]; then
  cargo build --release -p lagrangian-bench --example auto_solve >&2
fi
bin=${BIN:-${CARGO_TARGET_DIR:-target}/release/examples/auto_solve}

declare -A base calibrated
echo "| problem | target | rtol | auto (M instr.) | auto ran | fastest | its M instr. | auto / fastest |"
echo "| --- | --- | --- | --- | --- | --- | --- | --- |"
for c in "${CASES[@]}"; do
  read -r problem target rtol fastest setting <<<"$c"
  if (($# > 0)) && [[ " $* " != *" $problem "* ]]; then continue; fi
  if [[ -z "${base[$problem]:-}" ]]; then
    base[$problem]=$(callgrind_total "$bin" "$problem" none)
    if [[ "${CALIBRATE:-0}" == 1 ]]; then
      calibrated[$problem]=$("$bin" "$problem" calibrate | tr '\n' ';')
    fi
  fi
  if [[ "${CALIBRATE:-0}" == 1 ]]; then
    rtol=$(tr ';' '\n' <<<"${calibrated[$problem]}" | awk -v t="$target" '$1 + 0 == t + 0 { print $2 }')
  fi
  if [[ "$rtol" == none || -z "$rtol" ]]; then
    echo "| $problem | $target | not reached | | | | | |"
    continue
  fi
  auto=$(( $(callgrind_total "$bin" "$problem" "$rtol") - base[$problem] ))
  ran=$("$bin" "$problem" "$rtol" | sed -E 's/^[^:]*: ([^(]*) \(.*, pilot ([0-9]+) steps, final run ([0-9]+) steps.*/\1, pilot \2 + final \3 steps/')
  fast=$(( $(callgrind_total "$bin" "$problem" "$fastest" "$setting") - base[$problem] ))
  awk -v p="$problem" -v t="$target" -v r="$rtol" -v a="$auto" -v ran="$ran" -v f="$fastest $setting" -v b="$fast" \
    'BEGIN { printf "| %s | %s | %.2e | %.3f | %s | %s | %.3f | %.2f |\n", p, t, r, a / 1e6, ran, f, b / 1e6, a / b }'
done
