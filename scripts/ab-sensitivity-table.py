#!/usr/bin/env python3
"""The sensitivity table of `trilab ab` beside `compare` (issue 25), from the runs.jsonl.gz that
scripts/ab-sensitivity.sh writes: `scripts/ab-sensitivity-table.py OUT` writes OUT/README.md.
PLANT, TOOK and VERSION (environment) name the planted kernel, the seconds taken and the binary."""
import gzip
import json
import os
import statistics
import sys

out = sys.argv[1]
plant = os.environ.get('PLANT', '.unit.')
method = plant.strip('.')
runs = [json.loads(line) for line in gzip.open(os.path.join(out, 'runs.jsonl.gz'), 'rt')]
factors = sorted({r['factor'] for r in runs})
repeats = max(r['repeat'] for r in runs)
HURT = ('hurt', 'hurt-beyond-threshold')


def tally(f):
    rs = [r for r in runs if r['factor'] == f]

    def planted(cell):
        return f != 1 and cell.split()[1] == method

    t = dict(runs=len(rs), planted=0, ab_hurt=0, ab_beyond=0, cmp_slower=0, cmp_beyond=0, others=0, ab_fa=0,
             ab_fa_beyond=0, cmp_fa=0, ab_failed=0, cmp_failed=0)
    ratios, widths, stopped = [], [], set()
    for r in rs:
        stopped.add(f"{r['ab_stopped_by']} ({r['ab_rounds']} rounds)")
        for c in r['ab']:
            if c['ratio']:
                widths.append((c['ratio'][2] / c['ratio'][1]) ** 0.5 - 1)
            if planted(c['cell']):
                t['planted'] += 1
                ratios.append(c['ratio'][0])
                t['ab_hurt'] += c['verdict'] in HURT
                t['ab_beyond'] += c['verdict'] == 'hurt-beyond-threshold'
            else:
                t['others'] += 1
                t['ab_fa'] += c['verdict'] != 'same'
                t['ab_fa_beyond'] += c['verdict'] == 'hurt-beyond-threshold'
        t['ab_failed'] += any(c['verdict'] == 'hurt-beyond-threshold' and not planted(c['cell']) for c in r['ab'])
        for c in r['compare']:
            if planted(c['cell']):
                t['cmp_slower'] += c['verdict'] == 'slower'
                t['cmp_beyond'] += c['verdict'] == 'slower' and c['beyond_threshold']
            else:
                t['cmp_fa'] += c['verdict'] in ('slower', 'faster')
        t['cmp_failed'] += any(c['verdict'] == 'slower' and c['beyond_threshold'] and not planted(c['cell'])
                               for c in r['compare'])
    size = f"{statistics.median(ratios):.3f} ({min(ratios):.3f}-{max(ratios):.3f})" if ratios else "-"
    return size, t, statistics.median(widths), '; '.join(sorted(stopped))


rows = [(f, *tally(f)) for f in factors]
md = [
    "# How sensitive `trilab ab` is: planted slowdowns beside `compare` of two runs\n",
    f"Made by `scripts/ab-sensitivity.sh` ({os.environ.get('VERSION', 'trilab')}; {repeats} repeats of each factor, "
    f"round-robin, {os.environ.get('TOOK', '?')} s in all) on this project's 2-core AMD EPYC (AVX-512) with lavapipe "
    f"(Mesa 25.0.7); `runs.jsonl.gz` holds every call. Side B runs with `TRILAB_INJECT_SLOWDOWN={plant}:F`: the "
    f"`{method}` kernel does F times its work (the whole dispatch floor(F) times, then the first frac(F) of its rays "
    "again), so 3 of the 24 default cells are slowed and 21 are not. Factor 1 is A against A.\n",
    "- **ab**: `trilab ab` at its defaults (bunny, 8 methods, bvh2; 6 to 20 rounds a side, each round a cell's "
    "median of 3 runs, until every 95 % interval is within +-2 %). *hurt*: the interval of B/A lies wholly above "
    "1; *beyond*: wholly above 1.05, the default threshold, which fails the run.",
    "- **compare**: two separate `trilab bench` runs of the same cells (its default 5 timed runs each), without "
    "and with the slowdown, then `trilab compare BASE NEW`. *slower*: the two min-max ranges are apart; *beyond*: "
    "and past its default 10 % threshold, which fails the run.",
    "- *measured size*: ab's B/A on the planted cells, median (min-max) over the repeats: what the plant cost "
    "(the first rays of a set are not its average, and each estimate carries the noise below).",
    "- *false calls*: calls either way on the cells not planted; *runs failed wrongly*: runs that an unplanted "
    "cell alone would fail.\n",
    "## Detection (planted cells)\n",
    "| F | measured size | planted cells | ab hurt | ab beyond 5 % | compare slower | compare beyond 10 % |",
    "|---|---|---:|---:|---:|---:|---:|",
]
for f, size, t, _, _ in rows:
    if f != 1:
        md.append(f"| {f:g} | {size} | {t['planted']} | {t['ab_hurt']} | {t['ab_beyond']} | {t['cmp_slower']} "
                  f"| {t['cmp_beyond']} |")
md += [
    "\n## False calls (cells not planted)\n",
    "| F | runs | cells | ab false calls | ab beyond 5 % | ab runs failed wrongly | compare false calls "
    "| compare runs failed wrongly | ab interval half-width, median | ab stopped by |",
    "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|",
]
total = dict(runs=0, others=0, ab_fa=0, ab_fa_beyond=0, ab_failed=0, cmp_fa=0, cmp_failed=0)
for f, _, t, width, stopped in rows:
    md.append(f"| {f:g} | {t['runs']} | {t['others']} | {t['ab_fa']} | {t['ab_fa_beyond']} | {t['ab_failed']} | "
              f"{t['cmp_fa']} | {t['cmp_failed']} | +-{width * 100:.1f} % | {stopped} |")
    for k in total:
        total[k] += t[k]
pct = lambda n: f"{n} ({n / total['others'] * 100:.1f} %)"  # noqa: E731
md.append(f"| all | {total['runs']} | {total['others']} | {pct(total['ab_fa'])} | {total['ab_fa_beyond']} | "
          f"{total['ab_failed']} | {pct(total['cmp_fa'])} | {total['cmp_failed']} | | |")
open(os.path.join(out, 'README.md'), 'w').write('\n'.join(md) + '\n')
print('\n'.join(md))
