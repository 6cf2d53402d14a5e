# Sourced by the instruction-count scripts (scripts/instructions.sh,
# bench/*-instructions.sh): `callgrind_total BIN ARGS...` prints the
# instructions valgrind's callgrind counts over one run of `BIN ARGS...`
# (they do not depend on the load of the machine). The run's stderr stays
# in "$callgrind_dir/err" for the caller to read.
command -v valgrind >/dev/null || { echo "valgrind not found" >&2; exit 1; }
callgrind_dir=$(mktemp -d)
trap 'rm -rf "$callgrind_dir"' EXIT

callgrind_total() {
  valgrind --tool=callgrind --callgrind-out-file="$callgrind_dir/out" "$@" >/dev/null 2>"$callgrind_dir/err" \
    || { cat "$callgrind_dir/err" >&2; exit 1; }
  grep -m1 '^summary:' "$callgrind_dir/out" | awk '{print $2}'
}
