#!/usr/bin/env python3
"""The table of scripts/gate-sensitivity.sh's runs: per condition and planted factor, what one
A/B of the gate called on the planted kernels (caught: hurt beyond the gate's threshold with the
whole interval) and on the others (false calls), with the kernels' interval half-widths; then,
from the same intervals, what other thresholds would have caught and falsely failed.

Usage: scripts/gate-sensitivity-table.py OUT/runs.jsonl [SECONDS]
"""
import json
import math
import statistics
import sys
from collections import OrderedDict


def main():
    runs = [json.loads(line) for line in open(sys.argv[1]) if line.strip()]
    seconds = sys.argv[2] if len(sys.argv) > 2 else None
    cases = OrderedDict()
    for r in runs:
        cases.setdefault((r["condition"], r["factor"]), []).append(r)
    host = next((r["host"] for r in runs if r.get("host")), "?")
    print("# The gate's timing A/B: what it catches and how often it cries wolf\n")
    print(
        f"Made by `scripts/gate-sensitivity.sh` on {host} with lavapipe; {len(runs)} runs"
        + (f", {int(seconds) / 60:.0f} min in all" if seconds else "")
        + ". Each run is `trilab gate` with this build on both sides and the gate's default workload "
        "(8 methods x 4 layouts = 32 kernels, the bunny's three ray sets), judged once (`--no-repeat`; "
        "the gate itself fails a kernel only when a second A/B agrees). Side B plants "
        "`TRILAB_INJECT_SLOWDOWN=raycast.unit.closest:F`: the unit intersector's kernel on every layout "
        "(4 planted kernels) does F times its work. *caught*: hurt beyond the threshold with its whole "
        "95 % interval (what fails the gate); *hurt*: the interval above 1, not all past the threshold; "
        "*false calls*: unplanted kernels hurt or helped; *false fails*: unplanted kernels that one A/B "
        "alone would fail.\n"
    )
    print(
        "| condition | F | runs | planted B/A, median (min-max) | caught | hurt | false calls | false fails "
        "| half-width, median (max) | rounds | s per run |"
    )
    print("|---|---:|---:|---|---:|---:|---:|---:|---|---:|---:|")
    for (cond, factor), rs in cases.items():
        planted = [k for r in rs for k in r["kernels"] if k["planted"]]
        others = [k for r in rs for k in r["kernels"] if not k["planted"]]
        ratios = [k["ratio"] for k in planted if k["ratio"]]
        caught = sum(k["verdict"] == "hurt-beyond-threshold" for k in planted)
        hurt = sum(k["verdict"] == "hurt" for k in planted)
        false_calls = sum(k["verdict"] not in ("same", None) for k in others)
        false_fails = sum(k["verdict"] == "hurt-beyond-threshold" for k in others)
        halves = [math.log(k["high"] / k["low"]) / 2 * 100 for r in rs for k in r["kernels"] if k["low"]]
        ratio = (
            f"{statistics.median(ratios):.3f} ({min(ratios):.3f}-{max(ratios):.3f})" if ratios else "-"
        )
        print(
            f"| {cond} | {factor:g} | {len(rs)} | {ratio} | {caught} of {len(planted)} | {hurt} "
            f"| {false_calls} of {len(others)} | {false_fails} | +-{statistics.median(halves):.1f} % "
            f"(+-{max(halves):.1f} %) | {statistics.median(r['rounds'] for r in rs):.0f} "
            f"| {statistics.median(r['seconds'] for r in rs):.0f} |"
        )
    thresholds = [3, 5, 10, 15]
    print(
        "\nThe same intervals at other thresholds: a kernel would fail one A/B when its whole interval "
        "is above 1 + threshold (planted kernels caught, of those planted; unplanted kernels falsely "
        "failed, of all unplanted kernel-runs in every case).\n"
    )
    print("| condition | F | " + " | ".join(f"caught at {t} %" for t in thresholds) + " |")
    print("|---|---:|" + "---:|" * len(thresholds))
    for (cond, factor), rs in cases.items():
        planted = [k for r in rs for k in r["kernels"] if k["planted"]]
        if not planted:
            continue
        cells = [f"{sum(1 for k in planted if k['low'] and k['low'] > 1 + t / 100)} of {len(planted)}" for t in thresholds]
        print(f"| {cond} | {factor:g} | " + " | ".join(cells) + " |")
    others = [k for r in runs for k in r["kernels"] if not k["planted"]]
    cells = [f"{sum(1 for k in others if k['low'] and k['low'] > 1 + t / 100)} of {len(others)}" for t in thresholds]
    print("| false fails, all cases | | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
