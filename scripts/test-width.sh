#!/usr/bin/env bash
# The GPU correctness tests once more at another lavapipe SIMD width (README "Quick start",
# docs/building.md; issue 16 item 5): lavapipe runs 8 lanes per subgroup by default and 4 with LP_NATIVE_VECTOR_WIDTH=128,
# and the kernels must give the same answers at each. Every test below compares the kernels'
# hits (or images) with the CPU f64 reference under the validation layer, as in the main pass.
# Fails unless the device reports the width's subgroup size: first here, then in every GPU test
# (tests/common: TRILAB_EXPECT_SUBGROUP_SIZE), so a driver that ignored the setting cannot pass
# silently at its default width. Widths lavapipe cannot give (16, 32, 64 lanes) are proved on
# the CPU by tests/subgroup_widths.rs, which the main pass runs.
#
#   scripts/test-width.sh 128|256|512
#
# Needs lavapipe as the device trilab picks (the CI machine has no other).
set -euo pipefail
cd "$(dirname "$0")/.."

bits=${1:-}
case $bits in
128) lanes=4 ;;
256) lanes=8 ;;
512) lanes=16 ;;
*)
    echo "usage: scripts/test-width.sh 128|256|512 (LP_NATIVE_VECTOR_WIDTH: lavapipe's SIMD width in bits)" >&2
    exit 2
    ;;
esac

# The kernels' correctness tests: every ray-casting kernel, layout and traversal, the path
# tracer, the f64 kernel, the GPU traversal counters against the CPU mirror, the edge cases,
# the profile's subgroup-scope clock and size sweep.
tests=(raycast_bunny layouts_gpu traversals_gpu cwbvh_gpu subgroup_widths traversal_stats edge_cases f64_kernel watertight render profile)

# Mesa's shader cache of its own for this width: lavapipe 25.0.7 keys its cached image functions
# without the width and would call the default pass's 8-lane code at this one
# (docs/driver-defects.md; trilab itself does the same, trilab::env::keep_lavapipe_cache_per_width).
export LP_NATIVE_VECTOR_WIDTH=$bits TRILAB_EXPECT_SUBGROUP_SIZE=$lanes
export MESA_SHADER_CACHE_DIR=${MESA_SHADER_CACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/trilab/mesa-shader-cache-lp$bits}
start=$SECONDS
devices=$(cargo run --release --quiet -- devices --json)
reported=$(printf '%s\n' "$devices" | grep -m1 '"subgroup_size"' | tr -dc '0-9')
if [[ $reported != "$lanes" ]]; then
    echo "test-width: LP_NATIVE_VECTOR_WIDTH=$bits should give subgroups of $lanes lanes, the device reports '${reported:-none}':" >&2
    printf '%s\n' "$devices" | grep -m2 -E '"name"|"subgroup_size"' >&2
    exit 1
fi
echo "test-width: LP_NATIVE_VECTOR_WIDTH=$bits, subgroup size $reported; tests: ${tests[*]}"
cargo test --release $(printf -- '--test %s ' "${tests[@]}")
echo "test-width: LP_NATIVE_VECTOR_WIDTH=$bits passed in $((SECONDS - start)) s"
