#!/usr/bin/env bash
# Builds the tinybvh peer (tinybvh_rays from the project's shared peers, ../shared/peers/tinybvh;
# never copied into this repository), used by `trilab bench --tinybvh` to run tinybvh's CPU
# layouts and OpenCL kernels on the same ray files in the same run. Installs PoCL and the OpenCL
# headers first where they are missing (Debian/Ubuntu apt), so the ocl-* layouts are compiled in.
# Benchmark-only: the main build never needs it. `-march=native`: the binary is for this machine.
# Usage: scripts/tinybvh-peer.sh [BUILD_DIR [PEER_SRC]]
#   BUILD_DIR default target/peers/tinybvh; PEER_SRC default ../shared/peers/tinybvh (beside the
#   repository) or $TRILAB_TINYBVH_SRC. Prints the binary's path on the last line.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$root/target/peers/tinybvh}
src=${2:-${TRILAB_TINYBVH_SRC:-}}
if [ -z "$src" ]; then
  for d in "$root/../shared/peers/tinybvh" "$root/../../shared/peers/tinybvh"; do
    if [ -f "$d/build.sh" ]; then src=$d; break; fi
  done
fi
if [ -z "$src" ] || [ ! -f "$src/build.sh" ]; then
  echo "tinybvh-peer.sh: no tinybvh peer source (build.sh) found; give it as the second argument" >&2
  exit 1
fi
missing=()
for p in pocl-opencl-icd ocl-icd-opencl-dev opencl-headers; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ] && command -v apt-get >/dev/null; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null \
    || { $SUDO apt-get update -qq >/dev/null && $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null; } \
    || echo "tinybvh-peer.sh: could not install ${missing[*]}; building the CPU layouts only" >&2
fi
mkdir -p "$out"
out=$(cd "$out" && pwd)
bash "$src/build.sh" "$out" >&2
# tinyocl picks its vendor define from the OpenCL device's name, and PoCL names its CPU device
# "pthread-<cpu>-<model>": on an AMD EPYC or Ryzen host that reads as an AMD GPU (ISAMD), which
# turns on USE_VLOAD_VSTORE, whose cast of a __global pointer to a private one PoCL's OpenCL C 3.0
# refuses ("changes address space of pointer"), so no OpenCL kernel could run there. A kernel
# compiled for an x86-64 CPU is no GPU vendor's: it gets ISOTHER, the define an Intel host's PoCL
# device already gets in effect (neither uses vload). An AMD GPU's compile (amdgcn) is unchanged.
cl="$out/tinybvh_cl/traverse.cl"
if [ -f "$cl" ] && ! grep -q "trilab: PoCL CPU device" "$cl"; then
  tmp=$(mktemp "$cl.XXXXXX")
  {
    printf '// trilab: PoCL CPU device named after an AMD CPU is not an AMD GPU (scripts/tinybvh-peer.sh)\n'
    printf '#if defined(ISAMD) && defined(__x86_64__)\n#undef ISAMD\n#define ISOTHER\n#endif\n'
    cat "$cl"
  } >"$tmp"
  mv "$tmp" "$cl"
fi
echo "$out/tinybvh_rays"
