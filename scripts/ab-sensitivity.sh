#!/usr/bin/env bash
# How sensitive `trilab ab` is, and how honest (issue 25, item 6): planted slowdowns of known
# factor on one method's kernel (TRILAB_INJECT_SLOWDOWN=.unit.:F on side B, so 3 of the 24 default
# cells are slowed and 21 are not), each measured two ways on the same host in the same run:
#   ab       `trilab ab` at its defaults (bunny, 8 methods, bvh2, 160x120, 2 diffuse a hit, 20,000
#            random rays; 6 to 20 rounds a side until every interval is within +-2 %, 300 s cap)
#   compare  two separate `trilab bench` runs of the same cells (its default 5 timed runs), one
#            without and one with the slowdown, then `trilab compare BASE NEW`
# Factor 1 is A against A: every call it makes is a false alarm. The factors and repeats go
# round-robin (repeat 1 of every factor, then repeat 2, ...), so a drift of the host lands on
# all of them alike.
#
# Usage: scripts/ab-sensitivity.sh [OUT]   (default results/lavapipe/ab/sensitivity; must not exist)
#   REPEATS=3 FACTORS="1 1.02 1.05 1.1 1.2 1.5" TRILAB=target/release/trilab
# Writes OUT/README.md (the table) and OUT/runs.jsonl.gz (one line per run: what each called);
# the runs' own folders stay in a temporary directory. Run it on an idle host.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-results/lavapipe/ab/sensitivity}
TRILAB=${TRILAB:-target/release/trilab}
REPEATS=${REPEATS:-3}
FACTORS=${FACTORS:-"1 1.02 1.05 1.1 1.2 1.5"}
PLANT=.unit.
if [[ -e $OUT ]]; then
  echo "ab-sensitivity: $OUT exists; give another folder (nothing is overwritten)" >&2
  exit 2
fi
[[ -x $TRILAB ]] || { echo "ab-sensitivity: $TRILAB: not built (cargo build --release)" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
bench=(bench --scenes bunny --width 160 --height 120 --diffuse-per-hit 2 --random-rays 20000)
start=$(date +%s)
for r in $(seq 1 "$REPEATS"); do
  for f in $FACTORS; do
    run=$work/$f-$r
    mkdir -p "$run/base" "$run/new"
    plant=()
    [[ $f != 1 ]] && plant=(TRILAB_INJECT_SLOWDOWN=$PLANT:$f)
    echo "repeat $r, factor $f: ab" >&2
    "$TRILAB" ab ${plant[@]+--b-env "${plant[@]}"} --json >"$run/ab.json" 2>"$run/ab.log" || [[ $? == 1 ]]
    echo "repeat $r, factor $f: two bench runs and compare" >&2
    "$TRILAB" "${bench[@]}" --out "$run/base" >/dev/null 2>"$run/base.log"
    env ${plant[@]+"${plant[@]}"} "$TRILAB" "${bench[@]}" --out "$run/new" >/dev/null 2>"$run/new.log"
    "$TRILAB" compare "$run/base" "$run/new" --json >"$run/compare.json" 2>"$run/compare.log" || [[ $? == 1 ]]
  done
done
took=$(( $(date +%s) - start ))
mkdir -p "$OUT"
python3 - "$work" "$OUT" "$PLANT" "$REPEATS" "$FACTORS" "$took" "$($TRILAB --version)" <<'EOF'
import gzip, json, os, statistics, sys
work, out, plant, repeats, factors, took, version = sys.argv[1:]
method = plant.strip('.')
factors = factors.split()
lines, table = [], []
for f in factors:
    ab_hit = ab_beyond = ab_fa = cmp_hit = cmp_beyond = cmp_fa = planted = others = 0
    ratios, stopped = [], []
    for r in range(1, int(repeats) + 1):
        run = os.path.join(work, f'{f}-{r}')
        ab = json.load(open(os.path.join(run, 'ab.json')))
        cmp = json.load(open(os.path.join(run, 'compare.json')))
        stopped.append(f"{ab['stopped_by']}, {ab['a']['rounds']} rounds")
        line = {'factor': float(f), 'repeat': r, 'ab': [], 'compare': [], 'ab_stopped_by': ab['stopped_by'],
                'ab_rounds': ab['a']['rounds'], 'ab_seconds': ab['seconds']}
        for c in ab['cells']:
            is_planted = c['cell']['method'] == method and f != '1'
            v = c['verdict']
            hurt = v in ('hurt', 'hurt-beyond-threshold')
            if is_planted:
                planted += 1
                ratios.append(c['ratio']['ratio'])
                ab_hit += hurt
                ab_beyond += v == 'hurt-beyond-threshold'
            else:
                others += 1
                ab_fa += v not in ('same', None)
            line['ab'].append({'cell': f"{c['cell']['set']} {c['cell']['method']}", 'verdict': v,
                               'ratio': c['ratio'] and round(c['ratio']['ratio'], 4)})
        for ch in cmp['changes']:
            if ch['figure'] != 'mrays_per_s':
                continue
            cell = dict(kv.split('=', 1) for kv in ch['cell'].split())
            is_planted = cell.get('method') == method and f != '1'
            if is_planted:
                cmp_hit += ch['verdict'] == 'slower'
                cmp_beyond += ch['verdict'] == 'slower' and ch['beyond_threshold']
            else:
                cmp_fa += ch['verdict'] in ('slower', 'faster')
            line['compare'].append({'cell': f"{cell.get('set')} {cell.get('method')}", 'verdict': ch['verdict'],
                                    'beyond_threshold': ch['beyond_threshold'], 'factor': round(ch['factor'], 4)})
        lines.append(line)
    size = f"{statistics.median(ratios):.3f} ({min(ratios):.3f}-{max(ratios):.3f})" if ratios else "-"
    table.append((f, size, planted, ab_hit, ab_beyond, cmp_hit, cmp_beyond, others, ab_fa, cmp_fa,
                  sorted(set(stopped))))
with gzip.open(os.path.join(out, 'runs.jsonl.gz'), 'wt') as g:
    for l in lines:
        g.write(json.dumps(l) + '\n')
md = [f"# How sensitive `trilab ab` is: planted slowdowns\n",
      f"Made by `scripts/ab-sensitivity.sh` ({version}; {repeats} repeats of each factor, round-robin, "
      f"{took} s in all). Side B runs with `TRILAB_INJECT_SLOWDOWN={plant}:F`: the `{method}` kernel does F "
      "times its work (the whole dispatch floor(F) times, then the first frac(F) of its rays again), so 3 of "
      "the 24 default cells are slowed. Factor 1 is A against A.\n",
      "- **ab**: `trilab ab` at its defaults. *hurt*: the 95 % interval of B/A lies wholly above 1; "
      "*beyond*: wholly above 1.05 (the default threshold; the run fails).",
      "- **compare**: two separate `trilab bench` runs of the same cells (5 timed runs each), without and with "
      "the slowdown, then `trilab compare`. *slower*: the two min-max ranges are apart; *beyond*: and more "
      "than its default 10 % threshold (the run fails).",
      "- *measured size*: ab's B/A on the planted cells, median (min-max) over the repeats: what the plant "
      "really cost, since the first rays of a set are not its average.",
      "- *false alarms*: calls (either way) on the cells not planted.\n",
      "| F | measured size | planted cells | ab hurt | ab beyond 5 % | compare slower | compare beyond 10 % "
      "| other cells | ab false alarms | compare false alarms | ab stopped by |",
      "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
for (f, size, planted, h, b, ch, cb, others, afa, cfa, stopped) in table:
    md.append(f"| {f} | {size} | {planted} | {h} | {b} | {ch} | {cb} | {others} | {afa} | {cfa} | {'; '.join(stopped)} |")
open(os.path.join(out, 'README.md'), 'w').write('\n'.join(md) + '\n')
print('\n'.join(md))
EOF
