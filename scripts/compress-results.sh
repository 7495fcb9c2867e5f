#!/usr/bin/env bash
# Stores result folders the way results/ keeps them (results/README.md, "How results are
# stored"), so the tree stays within its budget (tests/tree_budget.rs) and travels to a lent GPU:
# - every .json, .csv and .jsonl file larger than 256 KiB is gzip-compressed in place (NAME.gz,
#   `gzip -9n`: no name or time in the header, so the same file compresses to the same bytes);
#   `trilab compare`, `merge` and `analyze --frontier` read the compressed form as the plain one;
# - every .png is recompressed losslessly with optipng where it is installed (the same pixels;
#   older plots were written at the PNG encoder's fast level, some 6x larger).
# Usage: scripts/compress-results.sh DIR...
set -euo pipefail
if [ $# -eq 0 ]; then
  echo "usage: scripts/compress-results.sh DIR..." >&2
  exit 2
fi
limit=$((256 * 1024))
for dir in "$@"; do
  [ -d "$dir" ] || { echo "compress-results.sh: $dir: not a folder" >&2; exit 2; }
  find "$dir" -type f \( -name '*.json' -o -name '*.csv' -o -name '*.jsonl' \) -size +"$limit"c -print0 |
    while IFS= read -r -d '' f; do
      gzip -9nf "$f"
      echo "compressed $f.gz"
    done
  if command -v optipng >/dev/null; then
    find "$dir" -type f -name '*.png' -print0 | xargs -0 -r optipng -quiet -o2 -preserve
  else
    echo "compress-results.sh: optipng not installed (apt-get install optipng); PNGs left as they are" >&2
  fi
done
