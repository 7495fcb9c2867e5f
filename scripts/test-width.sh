#!/usr/bin/env bash
# The GPU correctness tests once more at another lavapipe SIMD width, and optionally for a smaller
# CPU (scripts/test-matrix.sh runs it; docs/building.md; issues 16 and 51): lavapipe runs 8 lanes
# per subgroup by default, 4 with LP_NATIVE_VECTOR_WIDTH=128 and 16 with 512, and with
# GALLIUM_OVERRIDE_CPU_CAPS=CAPS it compiles for a CPU without the features CAPS removes (`avx`:
# no AVX-512, so an AVX-512 host compiles as a Zen 3 or a Skylake client does; `sse4.1`: no AVX),
# and the kernels must give the same answers at each. Every test below compares the kernels'
# hits (or images) with the CPU f64 reference under the validation layer, as in the main pass.
# Fails unless the device reports the width's subgroup size: first here, then in every GPU test
# (tests/common: TRILAB_EXPECT_SUBGROUP_SIZE), so a driver that ignored the setting cannot pass
# silently at its default width. Widths lavapipe cannot give (16, 32, 64 lanes) are proved on
# the CPU by tests/subgroup_widths.rs, which the main pass runs.
#
#   scripts/test-width.sh 128|256|512 [CAPS]
#
# The pass names the CPU features lavapipe compiles for (`trilab devices`, "compiles for (CPU)")
# and fails unless they are those CAPS leaves. Needs lavapipe as the device trilab picks (the CI
# machine has no other).
set -euo pipefail
cd "$(dirname "$0")/.."

bits=${1:-}
case $bits in
128) lanes=4 ;;
256) lanes=8 ;;
512) lanes=16 ;;
*)
    echo "usage: scripts/test-width.sh 128|256|512 [CAPS] (LP_NATIVE_VECTOR_WIDTH: lavapipe's SIMD width in bits; CAPS: GALLIUM_OVERRIDE_CPU_CAPS, e.g. avx)" >&2
    exit 2
    ;;
esac
# CAPS given, else the one the caller runs under (scripts/soak.sh --cpu-caps).
caps=${2:-${GALLIUM_OVERRIDE_CPU_CAPS:-}}
case $caps in
'' | nosse | sse | sse2 | sse3 | ssse3 | sse4.1 | avx) ;;
*)
    echo "test-width: CAPS '$caps' is not a value Mesa knows (nosse, sse, sse2, sse3, ssse3, sse4.1, avx)" >&2
    exit 2
    ;;
esac

# The kernels' correctness tests: every ray-casting kernel, layout and traversal, the path
# tracer, the f64 kernel, the GPU traversal counters against the CPU mirror, the edge cases,
# the profile's subgroup-scope clock and size sweep.
tests=(raycast_bunny layouts_gpu traversals_gpu cwbvh_gpu subgroup_widths traversal_stats edge_cases f64_kernel watertight render profile)

# Mesa's shader cache of its own for this width and CPU: lavapipe 25.0.7 keys its cached image
# functions without the width and would call the default pass's 8-lane code at this one
# (docs/driver-defects.md; trilab itself does the same, trilab::env::keep_lavapipe_cache_per_target).
export LP_NATIVE_VECTOR_WIDTH=$bits TRILAB_EXPECT_SUBGROUP_SIZE=$lanes
setting="LP_NATIVE_VECTOR_WIDTH=$bits"
folder=mesa-shader-cache-lp$bits
if [[ -n $caps ]]; then
    export GALLIUM_OVERRIDE_CPU_CAPS=$caps
    setting+=" GALLIUM_OVERRIDE_CPU_CAPS=$caps"
    folder+=-$caps
fi
export MESA_SHADER_CACHE_DIR=${MESA_SHADER_CACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/trilab}/$folder
start=$SECONDS
devices=$(cargo run --release --quiet -- devices --json)
reported=$(printf '%s\n' "$devices" | grep -m1 '"subgroup_size"' | tr -dc '0-9')
if [[ $reported != "$lanes" ]]; then
    echo "test-width: LP_NATIVE_VECTOR_WIDTH=$bits should give subgroups of $lanes lanes, the device reports '${reported:-none}':" >&2
    printf '%s\n' "$devices" | grep -m2 -E '"name"|"subgroup_size"' >&2
    exit 1
fi
# What lavapipe compiles for, as `trilab devices` names it (gpu::lavapipe_cpu; tests/lavapipe_cpu.rs
# holds that naming to Mesa's own GALLIUM_DUMP_CPU).
compiles_for=$(cargo run --release --quiet -- devices | grep -m1 'compiles for (CPU):' | sed 's/^ *compiles for (CPU): *//')
if [[ -z $compiles_for ]]; then
    echo "test-width: trilab devices names no CPU features for lavapipe" >&2
    exit 1
fi
if [[ -n $caps && $compiles_for != *"GALLIUM_OVERRIDE_CPU_CAPS=$caps"* ]]; then
    echo "test-width: GALLIUM_OVERRIDE_CPU_CAPS=$caps is not in what lavapipe compiles for: $compiles_for" >&2
    exit 1
fi
echo "test-width: $setting, subgroup size $reported; lavapipe compiles for: $compiles_for"
echo "test-width: tests: ${tests[*]}"
cargo test --release --no-fail-fast $(printf -- '--test %s ' "${tests[@]}")
echo "test-width: $setting passed in $((SECONDS - start)) s"
