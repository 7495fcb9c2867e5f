#!/usr/bin/env bash
# What the regression gate's timing A/B catches and how often it cries wolf (issue 36): `trilab
# gate` with this build on both sides (as CI has when no kernel code changed), its default
# workload (every method on every layout, the bunny's three ray sets), under host conditions and
# with a planted slowdown of one intersector's kernels on side B only
# (TRILAB_INJECT_SLOWDOWN=raycast.unit.closest:F: the unit kernel on every layout, 4 of the 32
# kernels), each judged once (`--no-repeat`: what one A/B decides; the gate itself fails a kernel
# only when a second A/B agrees).
#
#   scripts/gate-sensitivity.sh OUT [REPEATS]      (OUT must not exist)
#   CASES="idle:1 load1:1 cpu1:1 idle:1.05 idle:1.1 idle:1.2 idle:1.5"   condition:factor
#
# Conditions: idle (nothing else started here), load1 (a busy-looping process beside the run),
# cpu1 (the run pinned to one CPU: taskset -c 0), nopt (lavapipe without LLVM's optimiser on
# both sides: a slower driver). Cases go round-robin (repeat 1 of every case, then repeat 2), so
# a drift of the host lands on all alike. Writes OUT/<case>-<repeat>.json.gz (the gate's report),
# OUT/runs.jsonl (one line per run: every kernel's B/A, interval and verdict) and OUT/README.md
# (the table, by scripts/gate-sensitivity-table.py).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: scripts/gate-sensitivity.sh OUT [REPEATS]}
repeats=${2:-2}
CASES=${CASES:-"idle:1 load1:1 cpu1:1 nopt:1 idle:1.05 idle:1.1 idle:1.2 idle:1.5 load1:1.2"}
PLANT=raycast.unit.closest
if [ -e "$out" ]; then
  echo "gate-sensitivity: $out exists; give another folder (nothing is overwritten)" >&2
  exit 2
fi
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$PWD/target}"
cargo build --release -q --bin trilab
exe="$CARGO_TARGET_DIR/release/trilab"
work=$(mktemp -d)
busy=()
stop_load() { for p in "${busy[@]}"; do kill "$p" 2>/dev/null || true; done; wait "${busy[@]}" 2>/dev/null || true; busy=(); }
trap 'stop_load; rm -rf "$work"' EXIT
mkdir -p "$out"
# Counts for the gate to judge (any measured folder: these runs are about the timings).
"$exe" suite --size 0 --parts bench --no-threads --no-driver-stats --out "$work/measured" > /dev/null 2>&1
start=$SECONDS
for r in $(seq "$repeats"); do
  for case in $CASES; do
    cond=${case%%:*}
    f=${case#*:}
    run="$out/$cond-$f-$r.json"
    args=(gate "$work/measured" "$work/measured" --base-bin "$exe" --base-commit same-build --no-repeat --json)
    [ "$f" != 1 ] && args+=(--b-env "TRILAB_INJECT_SLOWDOWN=$PLANT:$f")
    [ "$cond" = nopt ] && args+=(--a-env GALLIVM_PERF=nopt --b-env GALLIVM_PERF=nopt)
    echo "gate-sensitivity: repeat $r, $cond, factor $f (load $(cut -d' ' -f1 /proc/loadavg))" >&2
    t0=$SECONDS
    case "$cond" in
      load1) (while :; do :; done) & busy+=($!) ;;
    esac
    pin=()
    [ "$cond" = cpu1 ] && pin=(taskset -c 0)
    "${pin[@]}" "$exe" "${args[@]}" > "$run" 2> "$work/$cond-$f-$r.log" || [ $? = 1 ]
    stop_load
    python3 - "$run" "$cond" "$f" "$r" "$((SECONDS - t0))" "$PLANT" >> "$out/runs.jsonl" <<'EOF'
import json, sys
path, cond, factor, rep, seconds, plant = sys.argv[1:]
g = json.load(open(path))
ab = g["timings"]["ab"]
method = plant.split(".")[1]
print(json.dumps({
    "condition": cond, "factor": float(factor), "repeat": int(rep), "seconds": int(seconds),
    "rounds": ab["a"]["rounds"], "stopped_by": ab["stopped_by"],
    "host": ab["a"]["provenance"].get("host", {}).get("cpu_model"),
    "kernels": [{"kernel": k["kernel"], "planted": factor != "1" and k["method"] == method,
                 "ratio": (k["ratio"] or {}).get("ratio"), "low": (k["ratio"] or {}).get("low"),
                 "high": (k["ratio"] or {}).get("high"), "verdict": k["verdict"]} for k in ab["kernels"]],
}))
EOF
  done
done
# The reports gzipped (the tree has a size budget); runs.jsonl holds what the table reads.
gzip -9 -n "$out"/*.json
python3 scripts/gate-sensitivity-table.py "$out/runs.jsonl" "$((SECONDS - start))" > "$out/README.md"
cat "$out/README.md"
