#!/usr/bin/env bash
# The lavapipe regression gate, the last step of README's test command (and so of CI): the suite
# at its smoke sizes (`--size 0`: pinned, so every cell matches the baseline's), then
# `trilab compare` against the committed baseline, results/lavapipe/baseline/ (made the same way
# on this machine; refresh it with `scripts/ci-gate.sh --refresh` when a change is meant to move
# the numbers, and commit it).
#
# Thresholds, stated: timings fail only when a cell's min-max ranges are apart AND it is slower
# by more than 150 % (x2.5): on this shared 2-core machine three runs of one binary differed per
# cell by up to x2.0 with their ranges apart (6 pairwise compares, load average 2-5), so a
# tighter timing gate would fail on noise. Counts (lavapipe's machine instructions, spills and
# helper calls per kernel, SPIR-V and scene bytes, SAH cost) are exact: any increase fails
# (`--count-threshold 0`). Correctness (agreement with the f64 reference, leaks, NaN hits) fails
# on any worsening, whatever the threshold.
set -euo pipefail
cd "$(dirname "$0")/.."
baseline=results/lavapipe/baseline
out="${CARGO_TARGET_DIR:-target}/ci-gate"
rm -rf "$out"
mkdir -p "$out"
if [ "${1:-}" = "--refresh" ]; then
    rm -rf "$baseline"
    cargo run --release -q -- suite --size 0 --no-threads --out "$baseline"
    exit 0
fi
cargo run --release -q -- suite --size 0 --no-threads --out "$out/suite" > "$out/suite.txt"
cargo run --release -q -- compare "$baseline" "$out/suite" --threshold 150 --count-threshold 0
