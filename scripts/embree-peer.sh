#!/usr/bin/env bash
# Builds the Embree 3 peer (benches/peers/embree_rays.cpp, Debian's libembree-dev) used by
# `trilab bench --embree` to run Embree on the same ray files in the same run.
# Usage: scripts/embree-peer.sh [OUT_DIR]   (default: target/peers); prints the binary's path.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$root/target/peers}
mkdir -p "$out"
if ! dpkg -s libembree-dev >/dev/null 2>&1; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
  $SUDO apt-get install -y -qq --no-install-recommends libembree-dev >/dev/null
fi
g++ -O2 -std=c++17 -o "$out/embree_rays" "$root/benches/peers/embree_rays.cpp" -lembree3 -lpthread
echo "$out/embree_rays"
