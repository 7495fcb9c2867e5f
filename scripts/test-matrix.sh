#!/usr/bin/env bash
# The test command (README "Quick start", run by .ci/run): every pass of the suite, each on past
# a failure, then one summary line per pass with its time, and exit 1 if any failed (issue 51:
# one failing test must not hide the rest).
#
#   scripts/test-matrix.sh
#
# The passes (docs/building.md, "The test matrix"):
#   suite       cargo test --release --no-fail-fast: every test, lavapipe as this host makes it
#   lp128       the GPU correctness tests at 4 lanes (scripts/test-width.sh 128)
#   avx         (the pass is named after the setting) the same at 8 lanes compiled for a CPU without AVX-512 (test-width.sh 256 avx):
#               what a Zen 3 or an Intel client host runs. Skipped, saying so, where this host
#               has no AVX-512 (the suite pass already was that run)
#   avx-lp512   the same at 16 lanes compiled without AVX-512 (test-width.sh 512 avx): lavapipe's
#               widest subgroups on a host that cannot hold them in one register
#   gate        the regression gate (scripts/ci-gate.sh)
#
# Under an outer GALLIUM_OVERRIDE_CPU_CAPS (scripts/soak.sh --cpu-caps) every pass runs under it,
# and the avx passes under the smaller of the two.
set -uo pipefail
cd "$(dirname "$0")/.."

results=()
failed=0
pass() {
    local name=$1
    shift
    local start=$SECONDS
    echo "test-matrix: pass $name: $*"
    if "$@"; then
        results+=("$(printf '%-10s passed   %5d s' "$name" $((SECONDS - start)))")
    else
        results+=("$(printf '%-10s FAILED   %5d s' "$name" $((SECONDS - start)))")
        failed=1
    fi
}
skip() {
    results+=("$(printf '%-10s skipped          (%s)' "$1" "$2")")
}

# The CPU the avx passes compile for: `avx` unless the caller already asked for less.
case ${GALLIUM_OVERRIDE_CPU_CAPS:-} in
nosse | sse | sse2 | sse3 | ssse3 | sse4.1) small=$GALLIUM_OVERRIDE_CPU_CAPS ;;
*) small=avx ;;
esac

start=$SECONDS
# What the suite pass's lavapipe compiles for (each width pass names its own).
compiles_for=$(cargo run --release --quiet -- devices | grep -m1 'compiles for (CPU):' | sed 's/^ *compiles for (CPU): *//')
echo "test-matrix: lavapipe compiles for: ${compiles_for:-(no lavapipe found)}"
pass suite cargo test --release --no-fail-fast
pass lp128 ./scripts/test-width.sh 128
# A smaller CPU that is no smaller than the suite pass's (a host without AVX-512, or an outer
# override as small) gives the suite pass's code again: that pass is then skipped.
features() {
    cargo run --release --quiet -- devices --json | tr -d ' \n' | grep -o '"features":\[[^]]*\]' | head -1
}
if [[ $(features) != "$(GALLIUM_OVERRIDE_CPU_CAPS=$small features)" ]]; then
    pass "$small" ./scripts/test-width.sh 256 "$small"
else
    skip "$small" "lavapipe compiles for the same CPU features under GALLIUM_OVERRIDE_CPU_CAPS=$small: the suite pass ran that code"
fi
pass "$small-lp512" ./scripts/test-width.sh 512 "$small"
pass gate ./scripts/ci-gate.sh

echo
echo "test-matrix: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//'), $(nproc) CPUs; $((SECONDS - start)) s in all"
echo "test-matrix: the suite's lavapipe compiles for: ${compiles_for:-(no lavapipe found)}"
printf '  %s\n' "${results[@]}"
exit $failed
