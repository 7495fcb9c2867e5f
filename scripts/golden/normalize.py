#!/usr/bin/env python3
"""Normaliser for compare.sh (stdlib only): strips volatile content from CSV, Markdown and
plain-text (stdout/stderr) outputs of trilab so that two captures can be compared byte for byte.

usage: normalize.py MODE OUTDIR_PATH SRC DST [SRC DST ...]
  MODE: csv | md | text
  OUTDIR_PATH: absolute path(s) of the capture dir (':'-separated); replaced by <OUT>

Rules (keep in sync with the list in compare.sh's header):
  csv : drop columns whose header matches CSV_VOLATILE (timings, rates, RSS, date, commit).
  md  : drop the "paper's claims" section (its verdicts are derived from timings); in tables,
        drop columns whose header matches HDR_VOLATILE (and the tick statistics of the shader-
        clock table); in prose, mask dates, commit ids, load averages, tick ranges and numbers
        followed by a time or rate unit.
  text: as md prose, plus aligned text tables (header line + dashed rule) lose volatile columns
        and markdown tables lose volatile columns.
"""
import csv
import io
import json
import re
import sys

CSV_VOLATILE = re.compile(
    r"^(.*_s|.*_s_(min|max)|.*_ms|.*_ms_(min|max)|ms|seconds|.*per_s|.*per_s_(min|max)|"
    r".*per_second|mrays_(median|min|max)|date|commit|peak_rss_bytes|.*rss.*|host_load.*)$",
    re.I,
)
HDR_VOLATILE = re.compile(
    r"(\bms\b|mrays/s|msamples/s|mtris/s|samples/s|\brays/s\b|(^|[\s,])s\b|seconds|^min\.\.max$|"
    r"time / mt|peak rss|^embree$|speed-?up|\bdate\b|\bcommit\b|load average)",
    re.I,
)
# columns of the shader-clock table (profile.md section 3) that are tick statistics
TICK_COLS = re.compile(r"^(mean|median|p99|min|max)$", re.I)
CLAIMS_HEADING = re.compile(r"^#+ .*claims", re.I)

NUM = r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?"
PROSE_SUBS = [
    # ISO timestamps and dates
    (re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(?:\.\d+)?Z?"), "<DATE>"),
    (re.compile(r"\bcommit\s+[0-9a-zA-Z._-]+"), "commit <COMMIT>"),
    # load averages: "before 1.12 0.94 0.86, after ..."
    (re.compile(r"\d+\.\d\d \d+\.\d\d \d+\.\d\d"), "<LOADAVG>"),
    # the host's 1-minute load in provenance lines: "2 CPUs, load 1.28"
    (re.compile(r"\bload \d+\.\d\d\b"), "load <LOAD>"),
    # heat-map clip range in ticks; tick statistics
    (re.compile(r"\[\d+, \d+\] ticks"), "[<T>, <T>] ticks"),
    (re.compile(r"ticks per ray mean " + NUM + r", median " + NUM + r", p99 " + NUM),
     "ticks per ray mean <T>, median <T>, p99 <T>"),
    # "(min 4.601, max 4.601; GPU timestamps)" in raycast's text output
    (re.compile(r"\(min " + NUM + r", max " + NUM), "(min <T>, max <T>"),
    # "0.0583 s (0.0583-0.0583)" build-bench; "4.97..4.97" ranges of timings
    (re.compile(NUM + r" s \(" + NUM + r"-" + NUM + r"\)"), "<T> s (<T>-<T>)"),
    # "built in 9.09 + 0.05 ms" (ray-query BLAS + TLAS); "15863 rays per submit" (sized by time)
    (re.compile(NUM + r" \+ " + NUM + r" ms"), "<T> + <T> ms"),
    (re.compile(r"\d+ rays per submit"), "<N> rays per submit"),
    # numbers followed by a time or rate unit
    (re.compile(NUM + r"\s?(Mrays/s|Msamples/s|Mtris/s|Mrays|samples/s|rays/s|ms|µs|us|ns|s|seconds|sec)\b"),
     r"<T> \1"),
    # "speed-up 1.105 (range 1.105-1.105)" and "time = 0.916" live only in the claims section,
    # which md drops; in text output they are informational anyway
    (re.compile(r"(speed-up|time =) " + NUM), r"\1 <T>"),
    (re.compile(r"\(range " + NUM + r"-" + NUM + r"\)"), "(range <T>-<T>)"),
    # progress ETA, elapsed (indicatif style)
    (re.compile(r"\b\d+:\d\d(:\d\d)?\b"), "<HMS>"),
]


# study's claim verdicts and their evidence lines (derived from timings), in text output where
# there is no section heading to drop
CLAIM_LINE = re.compile(r"^\*\*\([a-z]\) |fastest at leaf|unit / MT time|speed-up at leaf|MT .* Quad unit .* speed-up")


def mask_prose(line):
    if CLAIM_LINE.search(line):
        return "<claim line dropped: derived from timings>"
    for rx, rep in PROSE_SUBS:
        line = rx.sub(rep, line)
    return line


def split_md_row(line):
    s = line.strip()
    if s.startswith("|"):
        s = s[1:]
    if s.endswith("|"):
        s = s[:-1]
    return [c.strip() for c in s.split("|")]


def md_table(lines):
    """lines: a markdown table (header, rule, rows). Returns normalised lines."""
    hdr = split_md_row(lines[0])
    ticks = any(h.lower() == "saturated" for h in hdr)
    keep = [i for i, h in enumerate(hdr)
            if not HDR_VOLATILE.search(h) and not (ticks and TICK_COLS.match(h))]
    out = []
    for ln in lines:
        cells = split_md_row(ln)
        out.append("| " + " | ".join(cells[i] if i < len(cells) else "<MISSING>" for i in keep) + " |")
    return out


def is_md_table_line(line):
    return line.lstrip().startswith("|")


def norm_md(text, drop_claims=True):
    lines = text.split("\n")
    out = []
    i = 0
    skipping_level = None
    while i < len(lines):
        ln = lines[i]
        m = re.match(r"^(#+) ", ln)
        if m:
            level = len(m.group(1))
            if skipping_level is not None and level <= skipping_level:
                skipping_level = None
            if drop_claims and CLAIMS_HEADING.match(ln):
                skipping_level = level
                out.append(ln)
                out.append("<claims section dropped: verdicts derived from timings>")
                i += 1
                continue
        if skipping_level is not None:
            i += 1
            continue
        if is_md_table_line(ln):
            j = i
            while j < len(lines) and is_md_table_line(lines[j]):
                j += 1
            out.extend(md_table(lines[i:j]))
            i = j
            continue
        out.append(mask_prose(ln))
        i += 1
    return "\n".join(out)


RULE = re.compile(r"^\s*-{2,}(\s+-{2,})*\s*$")


def text_table(lines):
    """Aligned text table: lines[0] header, lines[1] dashed rule, rest rows (until blank)."""
    rule = lines[1]
    spans = [(m.start(), m.end()) for m in re.finditer(r"-+", rule)]
    def cells(line):
        res = []
        for k, (a, b) in enumerate(spans):
            lo = spans[k - 1][1] if k > 0 else 0
            hi = spans[k + 1][0] if k + 1 < len(spans) else len(line)
            # cell is the text between the previous span's end and the next span's start,
            # restricted to what overlaps this span (right- or left-aligned)
            seg = line[lo:hi] if k + 1 < len(spans) else line[lo:]
            res.append(seg.strip())
        return res
    hdr = cells(lines[0])
    keep = [i for i, h in enumerate(hdr) if not HDR_VOLATILE.search(h)]
    out = []
    for ln in lines:
        if RULE.match(ln):
            out.append("  ".join("-" * 3 for _ in keep))
            continue
        c = cells(ln)
        out.append("  ".join(c[i] if i < len(c) else "" for i in keep))
    return out


def norm_text(text):
    lines = text.split("\n")
    # progress bars and carriage-return updates: keep only the final state of a line
    lines = [ln.split("\r")[-1] for ln in lines]
    out = []
    i = 0
    while i < len(lines):
        ln = lines[i]
        if i + 1 < len(lines) and RULE.match(lines[i + 1]) and ln.strip():
            j = i + 2
            while j < len(lines) and lines[j].strip():
                j += 1
            out.extend(text_table(lines[i:j]))
            i = j
            continue
        if is_md_table_line(ln):
            j = i
            while j < len(lines) and is_md_table_line(lines[j]):
                j += 1
            out.extend(md_table(lines[i:j]))
            i = j
            continue
        out.append(mask_prose(ln))
        i += 1
    return "\n".join(out)


def norm_csv(text):
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        return ""
    hdr = rows[0]
    keep = [i for i, h in enumerate(hdr) if not CSV_VOLATILE.match(h.strip())]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    for r in rows:
        w.writerow([r[i] if i < len(r) else "<MISSING>" for i in keep])
    return buf.getvalue()


def norm_rows(text):
    """rows.jsonl: every line as JSON with the timing figures (class `timing`) and the source's
    date, commit and host load left out; the count and correctness figures and the cells stay."""
    out = []
    for line in text.splitlines():
        if not line.strip():
            continue
        row = json.loads(line)
        figures = row.get("figures")
        if isinstance(figures, dict):
            row["figures"] = {k: v for k, v in figures.items() if v.get("class") != "timing"}
        src = row.get("source")
        if isinstance(src, dict):
            for k in ("date", "commit"):
                src.pop(k, None)
            if isinstance(src.get("host"), dict):
                src["host"].pop("load_1m", None)
        out.append(json.dumps(row, sort_keys=True))
    return "\n".join(out) + "\n"


def main():
    mode = sys.argv[1]
    outdirs = [p for p in sys.argv[2].split(":") if p]
    args = sys.argv[3:]
    for src, dst in zip(args[0::2], args[1::2]):
        with open(src, "r", encoding="utf-8", errors="surrogateescape") as f:
            text = f.read()
        for p in sorted(outdirs, key=len, reverse=True):
            text = text.replace(p, "<OUT>")
        if mode == "csv":
            text = norm_csv(text)
        elif mode == "md":
            text = norm_md(text)
        elif mode == "text":
            text = norm_text(text)
        elif mode == "rows":
            text = norm_rows(text)
        else:
            raise SystemExit("unknown mode " + mode)
        with open(dst, "w", encoding="utf-8", errors="surrogateescape") as f:
            f.write(text)


if __name__ == "__main__":
    main()
