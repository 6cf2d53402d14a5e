#!/usr/bin/env bash
# Packages every crate of the workspace as `cargo publish` would, builds each
# package from its .crate file, and uploads nothing. Exits non-zero when any
# crate fails to package or to build. Needs network (crates.io index) and a few
# minutes; not part of .ci/run for that reason.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo publish --dry-run --workspace "$@"
