#!/usr/bin/env bash
# Builds the Embree 3 peers (Debian's libembree-dev): benches/peers/embree_rays.cpp, used by
# `trilab bench --embree` to run Embree (rtcIntersect1, and rtcIntersect8/16 for
# `--embree-apis packet8,packet16`) on the same ray files in the same run, and
# benches/peers/embree_build.cpp, used by `trilab build-bench --embree` to time Embree's BVH
# builder on the same triangles. Benchmark-only: the main build never needs them.
# Usage: scripts/embree-peer.sh [OUT_DIR]   (default: target/peers); prints the binaries' paths.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$root/target/peers}
mkdir -p "$out"
if ! dpkg -s libembree-dev >/dev/null 2>&1; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
  $SUDO apt-get install -y -qq --no-install-recommends libembree-dev >/dev/null
fi
g++ -O2 -std=c++17 -Wall -Wextra -o "$out/embree_rays" "$root/benches/peers/embree_rays.cpp" -lembree3 -lpthread
g++ -O2 -std=c++17 -Wall -Wextra -o "$out/embree_build" "$root/benches/peers/embree_build.cpp" -lembree3 -lpthread
echo "$out/embree_rays"
echo "$out/embree_build"
