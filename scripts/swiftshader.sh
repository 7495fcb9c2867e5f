#!/usr/bin/env bash
# Google's SwiftShader Vulkan driver (not Mesa: its own JIT, Subzero) beside lavapipe, without
# installing anything: Debian 12's `chromium-common` ships it as usr/lib/chromium/libvk_swiftshader.so
# with vk_swiftshader_icd.json beside it. Downloads that package with `apt-get download` (about
# 32 MB, once), unpacks it with `dpkg -x`, keeps the driver and its ICD file only, and writes an
# ICD JSON naming the kept driver by its absolute path, for the Vulkan loader's VK_DRIVER_FILES.
# Never installs, never needs root; safe to run repeatedly (a folder already complete is only
# checked).
#
# Usage: scripts/swiftshader.sh [--quiet] [DIR]
#   DIR: default $TRILAB_SWIFTSHADER, else $HOME/.cache/trilab/swiftshader.
# Writes DIR/vk_swiftshader_icd.json, DIR/libvk_swiftshader.so, DIR/env (the variables to set,
# KEY=VALUE lines), DIR/version (chromium-common's Debian version, which names the SwiftShader
# build); prints the variables as one line to put before a command:
#   env $(cat ~/.cache/trilab/swiftshader/env) trilab devices
set -euo pipefail

quiet=0
if [ "${1:-}" = "--quiet" ]; then quiet=1; shift; fi
dir=${1:-${TRILAB_SWIFTSHADER:-$HOME/.cache/trilab/swiftshader}}
pkg=chromium-common
say() { [ $quiet -eq 1 ] || echo "swiftshader: $*" >&2; }
die() { echo "swiftshader: error: $*" >&2; exit 1; }

for tool in apt-get apt-cache dpkg ldd; do
  command -v "$tool" >/dev/null || die "needs $tool (Debian's apt and dpkg); this script unpacks Debian 12's $pkg"
done

unresolved() { ldd "$1" | awk '/not found/ {print $1}'; }

if [ -f "$dir/env" ] && [ -f "$dir/vk_swiftshader_icd.json" ] && [ -f "$dir/version" ] &&
  [ -f "$dir/libvk_swiftshader.so" ] && [ -z "$(unresolved "$dir/libvk_swiftshader.so")" ]; then
  say "$pkg $(cat "$dir/version") (SwiftShader) already unpacked in $dir"
  tr '\n' ' ' <"$dir/env" | sed 's/ $/\n/'
  exit 0
fi

# The version apt would install (bookworm-security carries Chromium's updates).
version=$(apt-cache policy "$pkg" 2>/dev/null | awk '/Candidate:/ {print $2; exit}')
if [ -z "$version" ] || [ "$version" = "(none)" ]; then
  die "apt knows no $pkg (apt-cache policy $pkg): run \`sudo apt-get update\` with Debian 12's main and security archives in apt's sources (the script itself never installs)"
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
say "downloading $pkg $version (about 32 MB)"
log=$( (cd "$work" && apt-get download -q "$pkg=$version") 2>&1) ||
  die "apt-get download $pkg=$version failed (is the Debian mirror reachable?): $(echo "$log" | grep -v '^W:' | tail -3)"
deb=$(ls "$work"/${pkg}_*.deb 2>/dev/null | head -1)
[ -n "$deb" ] || die "apt-get download $pkg=$version wrote no .deb"
dpkg -x "$deb" "$work/root"
lib=$(find "$work/root" -name libvk_swiftshader.so -print -quit)
icd=$(find "$work/root" -name 'vk_swiftshader_icd.json' -print -quit)
[ -n "$lib" ] && [ -n "$icd" ] || die "$(basename "$deb") holds no libvk_swiftshader.so or vk_swiftshader_icd.json"
missing=$(unresolved "$lib")
[ -z "$missing" ] || die "SwiftShader needs libraries this machine lacks: $missing (ldd $lib)"

mkdir -p "$dir"
cp "$lib" "$dir/libvk_swiftshader.so.tmp"
mv "$dir/libvk_swiftshader.so.tmp" "$dir/libvk_swiftshader.so"
sed "s|\"library_path\": *\"[^\"]*\"|\"library_path\": \"$dir/libvk_swiftshader.so\"|" "$icd" >"$dir/vk_swiftshader_icd.json.tmp"
mv "$dir/vk_swiftshader_icd.json.tmp" "$dir/vk_swiftshader_icd.json"
echo "VK_DRIVER_FILES=$dir/vk_swiftshader_icd.json" >"$dir/env.tmp"
mv "$dir/env.tmp" "$dir/env"
echo "$version" >"$dir/version"
say "SwiftShader from $pkg $version unpacked; to run trilab on it, set:"
tr '\n' ' ' <"$dir/env" | sed 's/ $/\n/'
