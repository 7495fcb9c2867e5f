#!/usr/bin/env bash
# The whole test suite N times back to back, to count flaky tests (issue 39): every run goes on
# past a failing test binary (--no-fail-fast), and the end lists each test that failed at least
# once, with how many runs it failed in, and each test binary that crashed (a signal).
#
#   scripts/soak.sh [-n N] [--busy] [--taskset CPUS] [--cpu-caps CAPS] [--out DIR] [-- ARGS for cargo test]
#
#   -n N            runs (default 10)
#   --cpu-caps CAPS lavapipe compiles for a smaller CPU in every run (GALLIUM_OVERRIDE_CPU_CAPS:
#                   `avx` makes an AVX-512 host's code a Zen 3's; issue 51), with a shader cache
#                   of its own
#   --busy          one busy loop per CPU beside the tests (a loaded CI host)
#   --taskset CPUS  every run pinned to these CPUs (`--taskset 0`: one core)
#   --out DIR       where the logs and summary.txt go (default: target/soak/<UTC time>)
#
# Builds once before the first run; the runs then test that build. Exit 0 when no run failed,
# 1 when some did (summary.txt says which), 2 on bad usage. Timings are not compared here.
set -euo pipefail
cd "$(dirname "$0")/.."

runs=10
busy=0
cpus=
caps=
out=
while [[ $# -gt 0 ]]; do
    case $1 in
    -n) runs=${2:?-n needs a number}; shift 2 ;;
    --busy) busy=1; shift ;;
    --taskset) cpus=${2:?--taskset needs CPUs}; shift 2 ;;
    --cpu-caps) caps=${2:?--cpu-caps needs a value}; shift 2 ;;
    --out) out=${2:?--out needs a folder}; shift 2 ;;
    --) shift; break ;;
    *) echo "soak: unknown argument '$1' (see the header of $0)" >&2; exit 2 ;;
    esac
done
[[ $runs =~ ^[1-9][0-9]*$ ]] || { echo "soak: -n $runs: a positive number of runs" >&2; exit 2; }
if [[ -n $cpus ]] && ! command -v taskset >/dev/null; then
    echo "soak: --taskset needs taskset (util-linux)" >&2
    exit 2
fi
case $caps in
'' | nosse | sse | sse2 | sse3 | ssse3 | sse4.1 | avx) ;;
*) echo "soak: --cpu-caps $caps: not a value Mesa knows (nosse, sse, sse2, sse3, ssse3, sse4.1, avx)" >&2; exit 2 ;;
esac
if [[ -n $caps ]]; then
    # The tests' GPU helper wants a cache folder per setting (tests/common: lavapipe reuses image
    # functions cached at another width, docs/driver-defects.md).
    export GALLIUM_OVERRIDE_CPU_CAPS=$caps
    export MESA_SHADER_CACHE_DIR=${MESA_SHADER_CACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/trilab}/mesa-shader-cache-$caps
fi
target=${CARGO_TARGET_DIR:-target}
out=${out:-$target/soak/$(date -u +%Y%m%dT%H%M%SZ)}
mkdir -p "$out"
pin=()
[[ -n $cpus ]] && pin=(taskset -c "$cpus")

echo "soak: building the tests once"
cargo test --release --no-run "$@" >"$out/build.log" 2>&1 || { echo "soak: the build failed: $out/build.log" >&2; exit 1; }

loops=()
stop_busy() { for p in "${loops[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap stop_busy EXIT
if ((busy)); then
    for _ in $(seq "$(nproc)"); do
        (while :; do :; done) &
        loops+=($!)
    done
    echo "soak: ${#loops[@]} busy loops beside the tests"
fi

failed_runs=0
for i in $(seq "$runs"); do
    log=$out/run-$i.log
    start=$SECONDS
    if "${pin[@]}" cargo test --release --no-fail-fast "$@" >"$log" 2>&1; then
        echo "soak: run $i of $runs passed ($((SECONDS - start)) s)"
    else
        failed_runs=$((failed_runs + 1))
        echo "soak: run $i of $runs FAILED ($((SECONDS - start)) s): $log"
    fi
done

# Each failing test once per run, and each test binary that died of a signal.
{
    echo "soak: $runs runs, $failed_runs failed; busy loops: ${#loops[@]}; taskset: ${cpus:-none}; GALLIUM_OVERRIDE_CPU_CAPS: ${caps:-none}; $(date -u)"
    echo "host: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//'), $(nproc) CPUs"
    echo "lavapipe compiles for: $(cargo run --release --quiet -- devices 2>/dev/null | grep -m1 'compiles for (CPU):' | sed 's/^ *compiles for (CPU): *//')"
    echo
    echo "tests that failed (runs failed in, test):"
    for i in $(seq "$runs"); do
        grep -E '^test .* \.\.\. FAILED$' "$out/run-$i.log" | sed -E 's/^test (.*) \.\.\. FAILED$/\1/' | sort -u || true
    done | sort | uniq -c | sort -rn
    echo
    echo "test binaries that crashed or failed (runs, binary and status):"
    # shellcheck disable=SC2016
    for i in $(seq "$runs"); do
        grep -oE "process didn't exit successfully: \`[^\`]*\` \([^)]*\)" "$out/run-$i.log" |
            sed -E 's#`([^ `]*/)?([^ /`]*)[^`]*`#\2#' | sort -u || true
    done | sort | uniq -c | sort -rn
} >"$out/summary.txt"
cat "$out/summary.txt"
((failed_runs == 0))
