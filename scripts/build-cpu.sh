#!/usr/bin/env bash
# CPU time of a cold `cargo test --workspace --no-run`, per compilation unit.
# Wall time on a shared machine says little (it depends on the load and on
# the order in which cargo happens to start the large test binaries); the
# user + system CPU of each rustc process does not depend on either, so
# this is the number to compare before and after a change to the build.
#
#   scripts/build-cpu.sh             # cold build in a scratch target dir, top 15 units
#   scripts/build-cpu.sh 30          # top 30
#   BUILD_CPU_TARGET=/tmp/x scripts/build-cpu.sh   # another scratch dir (deleted first)
#
# Prints the whole build's wall and CPU (cargo and its children), the sum of
# the rustc processes' CPU, and the largest units: CPU seconds, wall seconds,
# crate name, kind (`test,` for test harnesses) and package. Needs GNU time. Cargo's
# `--timings` report lands in `$target/cargo-timings/cargo-timing.html`, for
# `scripts/critical-path.py $target/cargo-timings/cargo-timing.html $target.log`.
set -euo pipefail

# Called by cargo as the rustc wrapper: run rustc under GNU time, append one
# line per unit to the log.
if [[ -n "${BUILD_CPU_LOG:-}" ]]; then
  rustc="$1"
  shift
  name="?"
  kind=""
  args=("$@")
  for ((i = 0; i < ${#args[@]}; i++)); do
    case "${args[$i]}" in
      --crate-name) name="${args[$((i + 1))]}" ;;
      --test) kind="${kind}test," ;;
      --crate-type) kind="${kind}${args[$((i + 1))]}," ;;
    esac
  done
  # The package as the sixth field: two packages may have test targets of
  # the same name (the facade's and `verification-tests/`' `verification`).
  exec /usr/bin/time -a -o "$BUILD_CPU_LOG" -f "%U %S %e $name $kind ${CARGO_PKG_NAME:-?}" "$rustc" "$@"
fi

cd "$(dirname "$0")/.."
top="${1:-15}"
target="${BUILD_CPU_TARGET:-${TMPDIR:-/tmp}/lagrangian-build-cpu}"
log="$target.log"
rm -rf "$target" "$log"
/usr/bin/time -o "$target.total" -f '%e s wall, %U s user + %S s system CPU' \
  env BUILD_CPU_LOG="$log" RUSTC_WRAPPER="$PWD/scripts/build-cpu.sh" CARGO_TARGET_DIR="$target" \
  cargo test --workspace --no-run --timings --quiet
echo "cold cargo test --workspace --no-run: $(cat "$target.total")"
# Cargo also runs the wrapper to query rustc (`-vV`, target info): no crate name, no CPU to speak of.
awk '$4 != "?" { s += $1 + $2 } END { printf "rustc processes: %.1f s CPU\n", s }' "$log"
awk '$4 != "?" { printf "%7.1f %7.1f  %s %s %s\n", $1 + $2, $3, $4, $5, $6 }' "$log" | sort -rn | head -n "$top" |
  (echo "    CPU    wall  unit kind package"; cat)
