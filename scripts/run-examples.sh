#!/usr/bin/env bash
# Runs every example in release mode; each prints its energy and momentum errors.
set -euo pipefail
cd "$(dirname "$0")/.."
for example in harmonic_oscillator pendulum double_pendulum kepler perturbed_pendulum slow_oscillator kepler_adaptive pythagorean fpu_chain n_link_pendulum; do
    echo "== $example"
    cargo run --quiet --release --example "$example"
done
# Forces, dissipation and Noether momentum maps (docs/theory.md §6–§7).
for example in damped_oscillator rlc_circuit sensor kepler_cartesian; do
    echo "== $example"
    cargo run --quiet --release --example "$example"
done
# Derivatives of a run: a fit with forward sensitivities, a swing-up with
# the adjoint (docs/guide/derivatives.md).
for example in fit_pendulum cart_pole; do
    echo "== $example"
    cargo run --quiet --release --example "$example"
done
# Events on dense output and a parallel ensemble: the Hénon–Heiles Poincaré section.
echo "== henon_heiles_section"
cargo run --quiet --release --example henon_heiles_section --features rayon
# An ensemble in two shards, merged and compared with the serial run bit for
# bit (scripts/slurm/run.sh runs the same as a Slurm array job).
echo "== ensemble_shard"
dir=$(mktemp -d)
for k in 0 1; do
    cargo run --quiet --release --example ensemble_shard -- shard --members 1000 --shard "$k" --shards 2 --out "$dir/shard-$k.json"
done
cargo run --quiet --release --example ensemble_shard -- merge --members 1000 --shards 2 --dir "$dir"
rm -rf "$dir"
