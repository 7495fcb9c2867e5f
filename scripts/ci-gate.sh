#!/usr/bin/env bash
# The lavapipe regression gate, the last step of README's test command (and so of CI). It judges
# the code only on evidence about the code (`trilab gate`, src/commands/gate.rs):
#
# - counts and correctness against the committed baseline, results/lavapipe/baseline/ (exact):
#   the suite at its smoke sizes (`--size 0`), the SPIR-V counts of every kernel variant and what
#   AMD's compiler makes of the studied kernels on two real GPUs without one (RADV's null device:
#   pitcairn, the paper's HD 7850, and navi31, ACO, wave64: VGPRs, SGPRs, spills, scratch,
#   subgroups per SIMD, instructions), measured here and compared with `trilab compare --timings
#   ignore --count-threshold 0`: SPIR-V instructions, scene bytes, SAH cost, EPO, lavapipe's
#   machine code where the baseline's host compiled for the same CPU, RADV's statistics where
#   this Mesa is the baseline's (another Mesa build's are not judged, and the gate says so);
#   agreement with the f64 reference, leaks, NaN hits;
# - timings only inside this run: `trilab ab` of the build the baseline was measured at (side A,
#   built here from the baseline's commit in a git worktree, its dependencies taken from this
#   build's target folder, so only the trilab crate compiles; cached by commit in
#   $TRILAB_GATE_CACHE, default ~/.cache/trilab/gate-base) against this build (side B), each
#   cell's two sides timed back to back on this host; a kernel fails when it is slower beyond
#   the gate's threshold with its whole 95 % interval past it, in that A/B and again when timed
#   once more. When no kernel code changed since the baseline's commit, both sides run this
#   build.
#
# Where there is no base build (a shallow clone, the baseline's commit missing, a baseline
# measured on a tree with uncommitted changes) the gate says so and judges counts and correctness
# alone: a timing from another run, on another host, is no evidence about the code.
#
# Usage: scripts/ci-gate.sh             the gate
#        scripts/ci-gate.sh --refresh   rewrite the baseline from this build (a clean tree: its
#                                       commit becomes the base every later gate builds; commit
#                                       the folder it writes)
#        scripts/ci-gate.sh --which-base   say which base build the gate would use, and stop
set -euo pipefail
cd "$(dirname "$0")/.."
baseline=results/lavapipe/baseline
# The base build shares this build's target folder (a worktree's own would rebuild shaderc).
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$PWD/target}"
out="$CARGO_TARGET_DIR/ci-gate"
cache="${TRILAB_GATE_CACHE:-$HOME/.cache/trilab/gate-base}"
# What a kernel's build is made of: when none of these differ from the baseline's commit, the
# base build is this build.
code_paths=(src glsl build.rs Cargo.toml Cargo.lock)

# The baseline's commit, as its suite's provenance names it.
baseline_commit() {
  python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["provenance"]["commit"])' "$baseline/suite.json"
}

# Sets base_commit, and either base_bin (the build to time against; "." for this build) or
# no_base (why there is none).
which_base() {
  base_commit=$(baseline_commit)
  base_bin=""
  no_base=""
  case "$base_commit" in
    "" | unknown | *-dirty)
      no_base="the baseline names no clean commit (\`$base_commit\`): it was measured on a tree with uncommitted changes"
      return
      ;;
  esac
  if ! git cat-file -e "$base_commit^{commit}" 2>/dev/null; then
    if [ "$(git rev-parse --is-shallow-repository 2>/dev/null)" = true ]; then
      no_base="the baseline's commit $base_commit is not in this shallow clone (git fetch --unshallow gives it)"
    else
      no_base="the baseline's commit $base_commit is not in this repository"
    fi
    return
  fi
  if git diff --quiet "$base_commit" -- "${code_paths[@]}" &&
    [ -z "$(git status --porcelain --untracked-files=all -- "${code_paths[@]}")" ]; then
    base_bin=.
  else
    base_bin="$cache/$base_commit/trilab"
  fi
}

# Builds the baseline's commit in a worktree beside this one and keeps its executable in the
# cache. Its target folder is a copy of this build's made of hard links, less trilab's own
# artifacts: every dependency is already built there (shaderc too), so only the trilab crate
# compiles, and this build's artifacts are never touched (two checkouts of one package share
# artifact names, so building the other in the same folder would rebuild both, each time).
build_base() {
  local tmp wt tgt start
  tmp=$(mktemp -d)
  wt="$tmp/base-$base_commit"
  tgt="$CARGO_TARGET_DIR/gate-base-target"
  start=$SECONDS
  rm -rf "$tgt"
  mkdir -p "$tgt"
  cp -al "$CARGO_TARGET_DIR/release" "$tgt/release"
  rm -rf "$tgt"/release/.fingerprint/trilab-* "$tgt"/release/build/trilab-* "$tgt"/release/deps/*trilab* \
    "$tgt"/release/trilab "$tgt"/release/trilab.d "$tgt"/release/libtrilab.*
  git worktree add --detach -q "$wt" "$base_commit"
  if ! (cd "$wt" && CARGO_TARGET_DIR="$tgt" cargo build --release --locked -q --bin trilab); then
    git worktree remove --force "$wt"
    rm -rf "$tgt" "$tmp"
    echo "ci-gate: the baseline's commit $base_commit does not build here" >&2
    exit 2
  fi
  mkdir -p "$cache/$base_commit"
  cp "$tgt/release/trilab" "$cache/$base_commit/trilab.part"
  mv "$cache/$base_commit/trilab.part" "$cache/$base_commit/trilab"
  git worktree remove --force "$wt"
  rm -rf "$tgt" "$tmp"
  echo "ci-gate: built the base ($base_commit) in $((SECONDS - start)) s, kept in $cache/$base_commit/" >&2
}

# The GPU targets whose compiled statistics the baseline holds (RADV's null device).
radv_targets=pitcairn:aco:64,navi31:aco:64

# The suite's smoke sizes, the SPIR-V counts and the studied kernels compiled for the RADV
# targets (only the rows: the disassembly and the reports stay behind).
measure() {
  local dest=$1 name
  name=$(basename "$dest")
  "$trilab" suite --size 0 --no-threads --out "$dest" > "$out/suite.txt"
  "$trilab" spirv --out "$out/spirv" > /dev/null
  mkdir -p "$dest/spirv"
  cp "$out/spirv/rows.jsonl" "$dest/spirv/rows.jsonl"
  local start=$SECONDS
  "$trilab" driver-stats --targets "$radv_targets" --kernels studied --out "$out/radv-$name" > /dev/null
  mkdir -p "$dest/radv"
  cp "$out/radv-$name/rows.jsonl" "$dest/radv/rows.jsonl"
  echo "ci-gate: the studied kernels compiled for $radv_targets in $((SECONDS - start)) s" >&2
}

if [ "${1:-}" = "--which-base" ]; then
  which_base
  if [ -n "$no_base" ]; then
    echo "no base build: $no_base"
  elif [ "$base_bin" = . ]; then
    echo "base: this build (no kernel code changed since the baseline's commit $base_commit)"
  elif [ -x "$base_bin" ]; then
    echo "base: $base_commit, cached at $base_bin"
  else
    echo "base: $base_commit, to be built into $base_bin"
  fi
  exit 0
fi

cargo build --release -q --bin trilab
trilab="$CARGO_TARGET_DIR/release/trilab"
rm -rf "$out"
mkdir -p "$out"

if [ "${1:-}" = "--refresh" ]; then
  # The baseline's commit is the base every later gate builds: it must be a commit, not a tree
  # with changes on top of one.
  if [ -n "$(git status --porcelain --untracked-files=no)" ]; then
    echo "ci-gate: uncommitted changes; commit them first (the baseline names the commit it was measured at, and later gates build it)" >&2
    exit 2
  fi
  # Two runs: their counts and correctness must agree exactly, or a count is not deterministic
  # and every later gate would fail on it.
  measure "$out/first"
  measure "$out/second"
  if ! "$trilab" gate "$out/first" "$out/second" --no-base "the refresh's own check" > "$out/refresh-check.txt"; then
    cat "$out/refresh-check.txt"
    echo "ci-gate: two runs of this build disagree on counts or correctness; baseline not refreshed" >&2
    exit 1
  fi
  rm -rf "$baseline"
  cp -r "$out/first" "$baseline"
  # Stored as results/ keeps results (bulky rows compressed): the tree has a size budget.
  scripts/compress-results.sh "$baseline"
  echo "ci-gate: baseline refreshed in $baseline at $(git rev-parse --short=12 HEAD) (a second run agreed on every count)"
  exit 0
fi

which_base
if [ -z "$no_base" ] && [ "$base_bin" != . ] && [ ! -x "$base_bin" ]; then
  build_base
fi
measure "$out/suite"
if [ -n "$no_base" ]; then
  base_args=(--no-base "$no_base")
else
  [ "$base_bin" = . ] && base_bin=$trilab
  base_args=(--base-bin "$base_bin" --base-commit "$base_commit")
fi
"$trilab" gate "$baseline" "$out/suite" "${base_args[@]}" --out "$out/gate"
