#!/usr/bin/env bash
# Measures what the CI gate's thresholds rest on: runs of one trilab binary at the suite's smoke
# sizes (as scripts/ci-gate.sh runs them) under several host conditions, interleaved, then
# `trilab compare` of every run against the first idle one, by both timing rules.
#
#   scripts/gate-noise.sh OUT [ROUNDS] [CONDITIONS...]
#
# ROUNDS 0 measures nothing and judges the runs already in OUT again (the first condition's
# round 1 stays the base).
#
# Conditions (default: idle load1 load2 cpu1 nopt slow):
#   idle   nothing else started by this script
#   load1  one busy-looping process beside the run (half of a 2-core host)
#   load2  as many busy-looping processes as CPUs
#   cpu1   the run pinned to one CPU (taskset -c 0): a smaller host
#   nopt   GALLIVM_PERF=nopt: lavapipe without LLVM's optimisation (a slower driver)
#   slow   TRILAB_INJECT_SLOWDOWN=raycast.unit.closest:2: one kernel's dispatches twice
#
# Writes OUT/<condition>-<round>/ (suite folders), OUT/compare/<run>.{raw,calibrated,gate,old-gate}.json, and
# OUT/noise.md: per run, the gate's verdict by each rule and the figures behind it.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: scripts/gate-noise.sh OUT [ROUNDS] [CONDITIONS...]}
rounds=${2:-3}
shift $(( $# >= 2 ? 2 : $# ))
conditions=("$@")
[ ${#conditions[@]} -gt 0 ] || conditions=(idle load1 load2 cpu1 nopt slow)
cargo build --release -q
exe="${CARGO_TARGET_DIR:-target}/release/trilab"
mkdir -p "$out/compare"
cpus=$(nproc)

busy=()
start_load() { for _ in $(seq "$1"); do (while :; do :; done) & busy+=($!); done; }
stop_load() { for p in "${busy[@]}"; do kill "$p" 2>/dev/null || true; done; wait "${busy[@]}" 2>/dev/null || true; busy=(); }
trap stop_load EXIT

suite() { "$exe" suite --size 0 --no-threads --out "$1" > "$1.txt" 2>&1; }

# The first idle run is every comparison's BASE, as the committed baseline is the gate's.
runs=()
if [ "$rounds" = 0 ]; then
  # Judge the runs already in OUT again (after a change to compare's rule), measuring nothing.
  for d in "$out"/*/; do
    d=$(basename "$d")
    [ "$d" = compare ] || runs+=("$d")
  done
  mapfile -t runs < <(printf '%s\n' "${runs[@]}" | sort -t- -k2,2n -s)
fi
for r in $(seq "$rounds"); do
  for c in "${conditions[@]}"; do
    d="$out/$c-$r"
    rm -rf "$d"
    echo "gate-noise: $c round $r (load $(cut -d' ' -f1 /proc/loadavg))"
    case "$c" in
      idle) suite "$d" ;;
      load1) start_load 1; suite "$d"; stop_load ;;
      load2) start_load "$cpus"; suite "$d"; stop_load ;;
      cpu1) taskset -c 0 "$exe" suite --size 0 --no-threads --out "$d" > "$d.txt" 2>&1 ;;
      nopt) GALLIVM_PERF=nopt suite "$d" ;;
      slow) TRILAB_INJECT_SLOWDOWN=raycast.unit.closest:2 suite "$d" ;;
      *) echo "gate-noise: unknown condition $c" >&2; exit 2 ;;
    esac
    runs+=("$c-$r")
  done
done

base="${conditions[0]}-1"
kernel_pct=$(sed -n 's/^GATE_KERNEL_PCT=${GATE_KERNEL_PCT:-\([0-9.]*\)}/\1/p' scripts/ci-gate.sh)
command_pct=$(sed -n 's/^GATE_COMMAND_PCT=${GATE_COMMAND_PCT:-\([0-9.]*\)}/\1/p' scripts/ci-gate.sh)
for run in "${runs[@]}"; do
  [ "$run" = "$base" ] && continue
  # Threshold 0: every real change is listed, so the table can show the worst of each kind.
  for rule in raw calibrated; do
    "$exe" compare "$out/$base" "$out/$run" --timings "$rule" --threshold 0 --command-threshold 0 \
      --count-threshold 0 --json > "$out/compare/$run.$rule.json" || true
  done
  # The gate itself, as scripts/ci-gate.sh runs it.
  "$exe" compare "$out/$base" "$out/$run" --timings calibrated --threshold "$kernel_pct" \
    --command-threshold "$command_pct" --count-threshold 0 --json > "$out/compare/$run.gate.json" || true
  # The gate before issue 22: raw timings, x2.5 with ranges apart.
  "$exe" compare "$out/$base" "$out/$run" --timings raw --threshold 150 --count-threshold 0 --json \
    > "$out/compare/$run.old-gate.json" || true
done

python3 - "$out" "$base" "$kernel_pct" "$command_pct" "${runs[@]}" <<'EOF'
import json, sys
out, base, kpct, cpct, runs = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5:]
def load(run, kind):
    return json.load(open(f"{out}/compare/{run}.{kind}.json"))
def worst_timing(r, key):
    return max([c[key] for c in r["changes"] if c["class"] == "timing" and c["verdict"] == "slower" and c.get(key)], default=1.0)
def regressions(r):
    kinds = {}
    for c in r["changes"]:
        if c["regression"]:
            k = "correctness" if c["class"] == "correctness" else f"{c['command']} {c['class']}s"
            kinds[k] = kinds.get(k, 0) + 1
    for s in r["speed"]:
        if s.get("regression"):
            kinds[f"{s['command']} as a whole"] = 1
    for k in r.get("kernels", []):
        if k["regression"]:
            kinds[f"{k['command']} {k['kernel']}"] = 1
    return ", ".join(k + (f" x{n}" if n > 1 else "") for k, n in sorted(kinds.items())) or "-"
lines = [f"# Gate noise: every run against `{base}`\n",
         f"The gate: `compare --timings calibrated --threshold {kpct} --command-threshold {cpct} --count-threshold 0` "
         "(scripts/ci-gate.sh). Columns: the host's speed NEW/BASE by the calibration (bench's); each command's speed "
         "NEW/BASE raw and over the calibration; the slowest kernel group against its command judged slower (95 % interval "
         "above 1, most of its cells slower in every round); the slowest single timing against its command (ranges apart; printed, never failing alone); the "
         "slowest single timing raw (ranges apart); what the gate failed on; what the gate before issue 22 (raw, x2.5, "
         "ranges apart) failed on.\n",
         "| run | host speed | raw speed per command | calibrated speed per command | worst kernel group | worst single timing, calibrated | worst single timing, raw | gate | old gate |",
         "|---|---:|---|---|---|---:|---:|---|---|"]
for run in runs:
    if run == base:
        continue
    try:
        raw, cal, gate, old = (load(run, k) for k in ("raw", "calibrated", "gate", "old-gate"))
    except Exception as e:
        lines.append(f"| {run} | compare failed: {e} | | | | | | | |")
        continue
    host = next((f"{s['host_speed']:.2f}" for s in cal["speed"] if s["command"] == "bench" and s.get("host_speed")), "-")
    rawspeed = ", ".join(f"{s['command']} {s['geomean_speed']:.2f}" for s in raw["speed"])
    calspeed = ", ".join(f"{s['command']} {s['calibrated_speed']:.2f}" for s in cal["speed"] if s.get("calibrated_speed"))
    ks = [k for k in cal.get("kernels", []) if k["verdict"] == "slower"]
    k = max(ks, key=lambda k: k["factor"], default=None)
    kernel = f"{k['command']} {k['kernel']} x{k['factor']:.2f} ({k['low']:.2f}..{k['high']:.2f})" if k else "-"
    verdict = lambda r: ("pass" if r["passed"] else "FAIL: " + regressions(r))
    lines.append(f"| {run} | {host} | {rawspeed} | {calspeed} | {kernel} | x{worst_timing(cal, 'relative_factor'):.2f} | "
                 f"x{worst_timing(raw, 'factor'):.2f} | {verdict(gate)} | {verdict(old)} |")
open(f"{out}/noise.md", "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
EOF
