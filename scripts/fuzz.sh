#!/usr/bin/env bash
# Runs the cargo-fuzz targets in fuzz/ (docs/correctness.md, "Fuzzing"): each for EXECUTIONS inputs (default
# 10^6), starting from the committed seeds in fuzz/corpus/<target>/. New interesting inputs go to
# fuzz/work/<target>/ (git-ignored), crashing/leaking/slow inputs to fuzz/artifacts/<target>/.
# A panic, an allocation over 512 MB, a process over 2 GB RSS or an input taking over 10 s is a
# finding. Prints executions, exec/s, coverage and findings per target; exits 1 on a finding.
#
#   scripts/fuzz.sh [obj_pipeline|ray_file|all] [EXECUTIONS] [-- extra libFuzzer flags]
#
# Needs the nightly toolchain and cargo-fuzz (`rustup toolchain install nightly`,
# `cargo install cargo-fuzz`). Builds into $CARGO_TARGET_DIR/fuzz (default target/fuzz).
set -euo pipefail
cd "$(dirname "$0")/.."

which=${1:-all}
runs=${2:-1000000}
shift $(($# < 2 ? $# : 2))
[[ ${1:-} == -- ]] && shift
extra=("$@")
case $which in
all) targets=(obj_pipeline ray_file) ;;
obj_pipeline | ray_file) targets=("$which") ;;
*) echo "usage: $0 [obj_pipeline|ray_file|all] [executions] [-- libFuzzer flags]" >&2; exit 2 ;;
esac

target_dir=${CARGO_TARGET_DIR:-$PWD/target}/fuzz

# Optional: SHADERC_LIB_DIR=<dir with libshaderc_combined.a> (e.g. a stable build's
# <target>/release/build/shaderc-sys-*/out/build/shaderc/libshaderc) links that library into
# trilab's build script instead of compiling shaderc again for nightly (tens of minutes on a
# small host): trilab asks for shaderc-sys's `build-from-source`, which ignores
# SHADERC_LIB_DIR, so a git-ignored fuzz/.cargo/config.toml patches in a shaderc-sys whose
# build script only links. Without it, fuzz/.cargo/config.toml is removed.
if [[ -n ${SHADERC_LIB_DIR:-} ]]; then
    [[ -f $SHADERC_LIB_DIR/libshaderc_combined.a ]] || { echo "no libshaderc_combined.a in $SHADERC_LIB_DIR" >&2; exit 2; }
    orig=$(ls -d "${CARGO_HOME:-$HOME/.cargo}"/registry/src/*/shaderc-sys-0.10.1 | head -1)
    patch=$target_dir/shaderc-sys-prebuilt
    mkdir -p "$patch/src" fuzz/.cargo
    # Files are replaced only when they change: a new mtime would rebuild trilab.
    put() { if ! cmp -s "$1" "$2"; then mv "$1" "$2"; else rm "$1"; fi; }
    cp "$orig/src/lib.rs" "$patch/src/lib.rs.new" && put "$patch/src/lib.rs.new" "$patch/src/lib.rs"
    cat >"$patch/Cargo.toml.new" <<TOML
[package]
name = "shaderc-sys"
version = "0.10.1"
edition = "2015"
links = "shaderc"
build = "build.rs"
[features]
build-from-source = []
prefer-static-linking = []
[dependencies]
libc = "0.2"
link-cplusplus = "1.0"
TOML
    put "$patch/Cargo.toml.new" "$patch/Cargo.toml"
    cat >"$patch/build.rs.new" <<RS
fn main() {
    println!("cargo:rerun-if-env-changed=SHADERC_LIB_DIR");
    println!("cargo:rustc-link-search=native=$SHADERC_LIB_DIR");
    println!("cargo:rustc-link-lib=static=shaderc_combined");
}
RS
    put "$patch/build.rs.new" "$patch/build.rs"
    printf '[patch.crates-io]\nshaderc-sys = { path = "%s" }\n' "$patch" >fuzz/.cargo/config.toml.new
    put fuzz/.cargo/config.toml.new fuzz/.cargo/config.toml
else
    rm -f fuzz/.cargo/config.toml
fi
status=0
for t in "${targets[@]}"; do
    mkdir -p "fuzz/work/$t" "fuzz/artifacts/$t"
    log=fuzz/work/$t.log
    before=$(find "fuzz/artifacts/$t" -type f | wc -l)
    echo "== $t: $runs executions (log: $log)"
    rc=0
    # Run from fuzz/ so that cargo reads fuzz/.cargo/config.toml (config follows the cwd).
    (cd fuzz && cargo +nightly fuzz run --fuzz-dir . --target-dir "$target_dir" "$t" "work/$t" "corpus/$t" -- \
        -runs="$runs" -rss_limit_mb=2048 -malloc_limit_mb=512 -timeout=10 -max_len=8192 \
        -print_final_stats=1 "${extra[@]}") >"$log" 2>&1 || rc=$?
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
    speed=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
    cov=$(grep -oE 'cov: [0-9]+ ft: [0-9]+' "$log" | tail -1 || true)
    corpus=$(grep -oE 'corp: [0-9]+/[0-9]+[a-zA-Z]*' "$log" | tail -1 || true)
    after=$(find "fuzz/artifacts/$t" -type f | wc -l)
    echo "   executions: ${execs:-?}  exec/s: ${speed:-?}  ${cov:-cov: ?}  ${corpus:-}"
    if [[ $rc -ne 0 || $after -gt $before ]]; then
        status=1
        echo "   FINDING (exit $rc): $(grep -m1 -E 'ERROR: libFuzzer|panicked at|==ERROR' "$log" || tail -1 "$log")"
        find "fuzz/artifacts/$t" -type f -newer "fuzz/corpus/$t" | sed 's/^/   input: /'
    else
        echo "   findings: none"
    fi
done
exit $status
