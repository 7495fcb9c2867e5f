#!/usr/bin/env python3
"""builds-ab.py OLD NEW --workload FILE --rounds N --out DIR

Two builds of trilab side by side in one session, for a change that must not make a kernel
slower (a GLSL refactor: its SPIR-V moved, its results did not). `trilab ab` compares drivers and
driver settings under one binary; this compares two binaries on one driver.

The workload file holds trilab command lines, one per line (`#` comments), each either
  bench ...      its cells are read from the rows it writes (`--out` is added), or
  raycast ...    one cell, read from its `--json` report (`--json` is added);
`{RAYS}` in a line is replaced by --rays-dir, `{OUT}` by the run's own output folder. Rounds interleave the builds (OLD NEW, NEW OLD, ...),
every command of a round under one build before the other, so a slow spell of a shared host
falls on both. Per cell: each build's median of its rounds' Mrays/s with [min, max], NEW/OLD,
and whether the two ranges overlap (only a cell whose ranges do not overlap is called changed).
Writes DIR/ab.md (and each run's output under DIR/old, DIR/new) and prints the table.
"""
import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys
import time


def run(binary, line, out_dir, rays_dir):
    os.makedirs(out_dir, exist_ok=True)
    args = shlex.split(line.replace("{RAYS}", rays_dir).replace("{OUT}", out_dir))
    cmd = args[0]
    if cmd == "bench":
        with open(os.path.join(out_dir, "stderr.txt"), "w") as err:
            subprocess.run([binary] + args + ["--out", out_dir], check=True, stdout=subprocess.DEVNULL, stderr=err)
        cells = {}
        with open(os.path.join(out_dir, "rows.jsonl")) as f:
            for row in map(json.loads, f):
                if row.get("type") != "row" or "mrays_per_s" not in row.get("figures", {}):
                    continue
                cell = dict(row["cell"])
                cell.pop("rays", None)
                # Rows of a build without a coordinate (older builds name no `access`) still
                # match: the access path is the command line's, which the key holds.
                cell.pop("access", None)
                access = next((a for a in args if a.startswith("--scene-access")), None)
                if access:
                    i = args.index(access)
                    cell["access"] = access.split("=", 1)[1] if "=" in access else args[i + 1]
                key = "bench " + " ".join(f"{k}={v}" for k, v in sorted(cell.items()))
                cells[key] = row["figures"]["mrays_per_s"]["median"]
        return cells
    if cmd == "raycast":
        out = subprocess.run([binary] + args + ["--json"], check=True, capture_output=True, text=True).stdout
        r = json.loads(out)
        rays = next((a for a in args if a.endswith(".rays")), "?")
        key = f"raycast {os.path.basename(rays)} {r['method']} {r['layout']} {r['traversal']} {r['scene_access']}"
        return {key: r["mrays_per_s"]}
    sys.exit(f"builds-ab.py: {line!r}: only `bench` and `raycast` lines are understood")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("old")
    p.add_argument("new")
    p.add_argument("--workload", required=True)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--out", required=True)
    p.add_argument("--rays-dir", default=".")
    a = p.parse_args()
    lines = [l.strip() for l in open(a.workload) if l.strip() and not l.startswith("#")]
    if os.path.exists(a.out):
        sys.exit(f"builds-ab.py: {a.out} exists; give a new folder")
    results = {"old": {}, "new": {}}
    start = time.time()
    for rnd in range(a.rounds):
        order = ["old", "new"] if rnd % 2 == 0 else ["new", "old"]
        for side in order:
            binary = a.old if side == "old" else a.new
            for i, line in enumerate(lines):
                cells = run(binary, line, os.path.join(a.out, side, f"round{rnd}", str(i)), a.rays_dir)
                for k, v in cells.items():
                    results[side].setdefault(k, []).append(v)
        print(f"round {rnd + 1}/{a.rounds} done, {time.time() - start:.0f} s", file=sys.stderr)
    rows = []
    for key in sorted(set(results["old"]) & set(results["new"])):
        o, n = results["old"][key], results["new"][key]
        mo, mn = statistics.median(o), statistics.median(n)
        overlap = not (min(n) > max(o) or max(n) < min(o))
        rows.append((key, mo, min(o), max(o), mn, min(n), max(n), mn / mo, overlap))
    ratios = [r[7] for r in rows]
    geo = statistics.geometric_mean(ratios) if ratios else float("nan")
    text = [
        f"OLD {a.old}",
        f"NEW {a.new}",
        f"{a.rounds} rounds interleaved, {time.time() - start:.0f} s; workload {a.workload}:",
        *[f"    trilab {l}" for l in lines],
        "",
        "| cell | OLD Mrays/s median [min, max] | NEW Mrays/s median [min, max] | NEW/OLD | ranges overlap |",
        "|---|---|---|---:|---|",
    ]
    for key, mo, lo, ho, mn, ln, hn, ratio, overlap in rows:
        text.append(f"| {key} | {mo:.3f} [{lo:.3f}, {ho:.3f}] | {mn:.3f} [{ln:.3f}, {hn:.3f}] | {ratio:.3f} | {'yes' if overlap else 'NO'} |")
    slower = [r for r in rows if not r[8] and r[7] < 1]
    faster = [r for r in rows if not r[8] and r[7] > 1]
    text += [
        "",
        f"{len(rows)} cells; geometric mean NEW/OLD {geo:.3f} (range {min(ratios):.3f}-{max(ratios):.3f}); "
        f"ranges apart: {len(slower)} slower, {len(faster)} faster",
    ]
    with open(os.path.join(a.out, "ab.md"), "w") as f:
        f.write("\n".join(text) + "\n")
    print("\n".join(text))


if __name__ == "__main__":
    main()
