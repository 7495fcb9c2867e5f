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
# Writes OUT/runs.jsonl.gz (one line per run: what each called) and OUT/README.md, the table
# scripts/ab-sensitivity-table.py makes of it; the runs' own folders stay in a temporary
# directory. Run it on an idle host.
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
# One line per run: every cell's verdict (and B/A with its interval) by ab, every timing compare
# called a change. scripts/ab-sensitivity-table.py makes the table of it.
python3 - "$work" "$OUT" "$REPEATS" "$FACTORS" <<'EOF'
import gzip, json, os, sys
work, out, repeats, factors = sys.argv[1:]
with gzip.open(os.path.join(out, 'runs.jsonl.gz'), 'wt') as g:
    for r in range(1, int(repeats) + 1):
        for f in factors.split():
            run = os.path.join(work, f'{f}-{r}')
            ab = json.load(open(os.path.join(run, 'ab.json')))
            cmp = json.load(open(os.path.join(run, 'compare.json')))
            line = {'factor': float(f), 'repeat': r, 'ab_stopped_by': ab['stopped_by'], 'ab_rounds': ab['a']['rounds'],
                    'ab_seconds': round(ab['seconds'], 1), 'ab': [], 'compare': []}
            for c in ab['cells']:
                ratio = c['ratio'] and [round(c['ratio'][k], 4) for k in ('ratio', 'low', 'high')]
                line['ab'].append({'cell': f"{c['cell']['set']} {c['cell']['method']}", 'verdict': c['verdict'], 'ratio': ratio})
            for ch in cmp['changes']:
                if ch['figure'] == 'mrays_per_s':
                    cell = dict(kv.split('=', 1) for kv in ch['cell'].split())
                    line['compare'].append({'cell': f"{cell['set']} {cell['method']}", 'verdict': ch['verdict'],
                                            'beyond_threshold': ch['beyond_threshold'], 'factor': round(ch['factor'], 4)})
            g.write(json.dumps(line) + '\n')
EOF
PLANT=$PLANT TOOK=$took VERSION="$("$TRILAB" --version) at $(git rev-parse --short HEAD)" \
  python3 scripts/ab-sensitivity-table.py "$OUT"
