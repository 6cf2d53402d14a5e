#!/usr/bin/env bash
# CPU time of the run of `cargo test --workspace`, per test binary, after
# the build (run `scripts/build-cpu.sh` or `cargo test --workspace --no-run`
# into the same target dir first, or the build's CPU is counted here too).
# Wall time on a shared machine says little; the user + system CPU of each
# test binary, with the processes it waits for (the report binary the bench
# tests start, trybuild's cargo), does not depend on the load as much.
#
#   CARGO_TARGET_DIR=/tmp/lagrangian-build-cpu scripts/test-run-cpu.sh      # after build-cpu.sh
#
# Prints the whole command's wall and CPU (cargo, rustdoc compiling the doc
# tests, and every test binary), then each test binary's CPU and wall
# seconds, largest first. The doc tests are compiled and run by rustdoc,
# which is in the total but not in the list.
set -euo pipefail

# Called by cargo as the test runner: run the test binary under GNU time,
# append one line per binary to the log.
if [[ -n "${TEST_RUN_CPU_LOG:-}" ]]; then
  binary="$1"
  exec /usr/bin/time -a -o "$TEST_RUN_CPU_LOG" -f "%U %S %e $(basename "$binary")" "$@"
fi

cd "$(dirname "$0")/.."
target="${CARGO_TARGET_DIR:-target}"
log="$target.run.log"
rm -f "$log"
/usr/bin/time -o "$target.run.total" -f '%e s wall, %U s user + %S s system CPU' \
  env TEST_RUN_CPU_LOG="$log" CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_RUNNER="$PWD/scripts/test-run-cpu.sh" \
  cargo test --workspace --quiet
echo "cargo test --workspace after the build: $(cat "$target.run.total")"
awk '{ s += $1 + $2 } END { printf "test binaries: %.1f s CPU\n", s }' "$log"
awk '{ printf "%7.1f %7.1f  %s\n", $1 + $2, $3, $4 }' "$log" | sort -rn | (echo "    CPU    wall  binary"; cat)
