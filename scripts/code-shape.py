#!/usr/bin/env python3
"""The shape of the source tree, for a before -> after of a refactor (issue 52).

    scripts/code-shape.py [--rev REV] [--json]

Prints, for the working tree (or the tree of git revision REV):
- src/'s files and lines, and src/commands' share of them;
- the 10 largest files of src/;
- the 10 longest Rust functions of src/ (lines from `fn` to its closing brace);
- the places that plan an experiment's cells (a `fn plan_cells` or `fn kernel_label`), each
  marked by whether it maps the matrix's cells (`crate::matrix`) or crosses axes itself, and
  which axes its body still loops over (a `for` over scenes, leaf sizes, methods, layouts or
  traversals).

It reads the files as text: a function's length is found by matching braces outside string and
character literals and comments, which is exact for rustfmt-formatted code.
"""

import argparse
import json
import re
import subprocess
import sys
from pathlib import Path

FN = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?(?:const\s+)?(?:async\s+)?(?:unsafe\s+)?(?:extern\s+\"C\"\s+)?fn\s+([A-Za-z_][A-Za-z0-9_]*)")
MOD_DECL = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+([A-Za-z_][A-Za-z0-9_]*)\s*\{")
IMPL = re.compile(r"^\s*(?:unsafe\s+)?impl\b(?:<[^{]*?>)?\s+(?:[^{]*?\s+for\s+)?([A-Za-z_][A-Za-z0-9_:<>, ]*)")
PLANNERS = re.compile(r"\bfn\s+(plan_cells|kernel_label)\b")
AXIS_LOOP = re.compile(r"\bfor\b[^{]*\bin\b[^{]*\b(scenes|leaf_sizes|methods|layouts|traversals)\b")


def files(rev):
    """(path, text) of every .rs file under src/, at REV or in the working tree."""
    if rev:
        names = subprocess.run(["git", "ls-tree", "-r", "--name-only", rev, "src/"], check=True,
                               capture_output=True, text=True).stdout.split()
        for name in names:
            if name.endswith(".rs"):
                text = subprocess.run(["git", "show", f"{rev}:{name}"], check=True,
                                      capture_output=True, text=True).stdout
                yield name, text
    else:
        for path in sorted(Path("src").rglob("*.rs")):
            yield str(path), path.read_text()


def code_only(line, state):
    """The line with comments and literals blanked; state carries a block comment across lines."""
    out = []
    i = 0
    n = len(line)
    while i < n:
        if state["block"]:
            end = line.find("*/", i)
            if end < 0:
                return "".join(out)
            state["block"] = False
            i = end + 2
            continue
        c = line[i]
        if line.startswith("//", i):
            break
        if line.startswith("/*", i):
            state["block"] = True
            i += 2
            continue
        if c == '"' or (c == "r" and re.match(r'r#*"', line[i:])):
            m = re.match(r'r(#*)"', line[i:])
            if m:
                close = '"' + m.group(1)
                end = line.find(close, i + len(m.group(0)))
                if end < 0:
                    state["raw"] = close
                    return "".join(out)
                i = end + len(close)
                continue
            j = i + 1
            while j < n and line[j] != '"':
                j += 2 if line[j] == "\\" else 1
            if j >= n:
                state["raw"] = '"'
                return "".join(out)
            i = j + 1
            continue
        if c == "'":
            m = re.match(r"'(\\.[^']*|[^\\'])'", line[i:])
            if m:
                i += len(m.group(0))
                continue
        out.append(c)
        i += 1
    return "".join(out)


def functions(path, text):
    """(qualified name, first line, length in lines) of each function with a body."""
    lines = text.splitlines()
    state = {"block": False, "raw": None}
    cleaned = []
    for line in lines:
        if state["raw"]:
            end = line.find(state["raw"])
            if end < 0:
                cleaned.append("")
                continue
            line = line[end + len(state["raw"]):]
            state["raw"] = None
        cleaned.append(code_only(line, state))
    out = []
    module = path.removeprefix("src/").removesuffix(".rs").removesuffix("/mod").replace("/", "::")
    for start, line in enumerate(lines):
        m = FN.match(line)
        if not m:
            continue
        depth = 0
        opened = False
        for end in range(start, len(lines)):
            for ch in cleaned[end]:
                if ch == "{":
                    depth += 1
                    opened = True
                elif ch == "}":
                    depth -= 1
                elif ch == ";" and not opened and depth == 0:
                    break
            else:
                if opened and depth == 0:
                    out.append((f"{module}::{m.group(1)}", start + 1, end - start + 1))
                    break
                continue
            break
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rev")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    sizes = []
    fns = []
    planners = []
    for path, text in files(args.rev):
        n = text.count("\n")
        sizes.append((path, n))
        fns.extend((name, path, first, length) for name, first, length in functions(path, text))
        lines = text.splitlines()
        spans = {first: length for _, first, length in functions(path, text)}
        for i, line in enumerate(lines):
            m = PLANNERS.search(line)
            if m and not line.lstrip().startswith("//"):
                body = lines[i:i + spans.get(i + 1, 1)]
                looped = sorted({a.group(1) for b in body for a in [AXIS_LOOP.search(b)] if a})
                matrix = any(re.search(r"experiment\(|Experiment\b|\.cells\(\)|matrix::", b) for b in body)
                how = "maps the matrix's cells" if matrix else "crosses no axis" if not looped else "crosses axes itself"
                if looped:
                    how += f"; loops over {', '.join(looped)}" if matrix else f" ({', '.join(looped)})"
                planners.append(f"{path}:{i + 1} {m.group(1)}: {how}")
    total = sum(n for _, n in sizes)
    commands = [(p, n) for p, n in sizes if p.startswith("src/commands/")]
    cmd_lines = sum(n for _, n in commands)
    shape = {
        "rev": args.rev or "working tree",
        "src_files": len(sizes),
        "src_lines": total,
        "commands_files": len(commands),
        "commands_lines": cmd_lines,
        "commands_share": round(100 * cmd_lines / total, 1),
        "largest_files": sorted(sizes, key=lambda s: -s[1])[:10],
        "longest_functions": [(name, f"{path}:{first}", length)
                              for name, path, first, length in sorted(fns, key=lambda f: -f[3])[:10]],
        "functions_over_120_lines": sum(1 for f in fns if f[3] > 120),
        "cell_planners": planners,
    }
    if args.json:
        json.dump(shape, sys.stdout, indent=1)
        print()
        return
    print(f"{shape['rev']}: src/ {shape['src_files']} files, {total} lines; src/commands "
          f"{len(commands)} files, {cmd_lines} lines ({shape['commands_share']} %)")
    print("largest files:")
    for p, n in shape["largest_files"]:
        print(f"  {n:6} {p}")
    print(f"longest functions ({shape['functions_over_120_lines']} over 120 lines):")
    for name, where, length in shape["longest_functions"]:
        print(f"  {length:6} {name} ({where})")
    print(f"places that plan cells ({len(planners)}):")
    for p in planners:
        print(f"  {p}")


if __name__ == "__main__":
    main()
