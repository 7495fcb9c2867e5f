#!/usr/bin/env bash
# The worked examples of `trilab ab` (results/lavapipe/ab/README.md), run on this machine:
#   1. Debian 12's own Mesa 22.3.6 (B, unpacked by scripts/stock-mesa.sh) against the
#      backports Mesa 25.0.7 this project installs (A);
#   2. lavapipe at LP_NATIVE_VECTOR_WIDTH=128 (B) against 256 (A).
# Each writes ab.json, ab.md, rows.jsonl and each side's rows (a/, b/) into its folder (never
# over an existing one).
# Run it on an otherwise idle host: the intervals are only as narrow as the host is quiet.
set -euo pipefail
cd "$(dirname "$0")/.."
exe=${TRILAB:-${CARGO_TARGET_DIR:-target}/release/trilab}
out=${1:-results/lavapipe/ab}
stock=$HOME/.cache/trilab/stock-mesa/lvp_icd.json
[ -f "$stock" ] || scripts/stock-mesa.sh
new=$(ls /usr/share/vulkan/icd.d/lvp_icd*.json | head -1)
for d in mesa-22.3.6-vs-25.0.7 width-128-vs-256; do
  if [ -e "$out/$d" ]; then echo "ab-examples: $out/$d exists; move it away first" >&2; exit 1; fi
done
# Besides the 24 ray-casting cells: a path-trace cell per method, the drivers' statistics of
# every kernel (22.3.6 has none, and says why) and the compute-shader invocations.
common=(--time-cap 180 --max-rounds 20 --pathtrace --driver-stats --pipeline-stats)
# Exit 1 is a verdict (B hurt), not a failure of the script.
"$exe" ab --a-icd "$new" --b-icd "$stock" "${common[@]}" --out "$out/mesa-22.3.6-vs-25.0.7" || [ $? -eq 1 ]
"$exe" ab --a-env LP_NATIVE_VECTOR_WIDTH=256 --b-env LP_NATIVE_VECTOR_WIDTH=128 "${common[@]}" \
  --out "$out/width-128-vs-256" || [ $? -eq 1 ]
