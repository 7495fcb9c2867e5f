#!/usr/bin/env bash
# LunarG's GFXReconstruct (Vulkan API capture and replay) beside the drivers, without installing
# anything: Debian 12's `gfxreconstruct` 0.9.18 package, downloaded with `apt-get download` (about
# 5 MB, once) and unpacked with `dpkg -x`. Keeps its capture layer (libVkLayer_gfxreconstruct.so),
# the layer's manifest rewritten to name the library by its absolute path (the loader finds it
# through VK_LAYER_PATH), and its tools (gfxrecon-replay, gfxrecon-info, gfxrecon-extract,
# gfxrecon-convert). `trilab repro` captures through the layer; its tests replay with
# gfxrecon-replay. Never installs, never needs root; safe to run repeatedly (a folder already
# complete is only checked).
#
# Usage: scripts/gfxreconstruct.sh [--quiet] [DIR]
#   DIR: default $TRILAB_GFXRECON, else $HOME/.cache/trilab/gfxreconstruct.
# Writes DIR/layer/VkLayer_gfxreconstruct.json, DIR/lib/libVkLayer_gfxreconstruct.so,
# DIR/bin/gfxrecon-*, DIR/version (the Debian version); prints DIR, which `trilab repro` also
# finds by itself there (or through TRILAB_GFXRECON).
set -euo pipefail

quiet=0
if [ "${1:-}" = "--quiet" ]; then quiet=1; shift; fi
dir=${1:-${TRILAB_GFXRECON:-$HOME/.cache/trilab/gfxreconstruct}}
pkg=gfxreconstruct
say() { [ $quiet -eq 1 ] || echo "gfxreconstruct: $*" >&2; }
die() { echo "gfxreconstruct: error: $*" >&2; exit 1; }

for tool in apt-get apt-cache dpkg ldd; do
  command -v "$tool" >/dev/null || die "needs $tool (Debian's apt and dpkg); this script unpacks Debian 12's $pkg"
done

unresolved() { ldd "$1" | awk '/not found/ {print $1}'; }
tools=(gfxrecon-replay gfxrecon-info gfxrecon-extract gfxrecon-convert)

complete() {
  [ -f "$dir/version" ] && [ -f "$dir/layer/VkLayer_gfxreconstruct.json" ] &&
    [ -f "$dir/lib/libVkLayer_gfxreconstruct.so" ] &&
    [ -z "$(unresolved "$dir/lib/libVkLayer_gfxreconstruct.so")" ] || return 1
  local t
  for t in "${tools[@]}"; do
    [ -x "$dir/bin/$t" ] && [ -z "$(unresolved "$dir/bin/$t")" ] || return 1
  done
}

if complete; then
  say "$pkg $(cat "$dir/version") already unpacked in $dir"
  echo "$dir"
  exit 0
fi

version=$(apt-cache policy "$pkg" 2>/dev/null | awk '/Candidate:/ {print $2; exit}')
if [ -z "$version" ] || [ "$version" = "(none)" ]; then
  die "apt knows no $pkg (apt-cache policy $pkg): run \`sudo apt-get update\` with Debian 12's main archive in apt's sources (the script itself never installs)"
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
say "downloading $pkg $version (about 5 MB)"
log=$( (cd "$work" && apt-get download -q "$pkg=$version") 2>&1) ||
  die "apt-get download $pkg=$version failed (is the Debian mirror reachable?): $(echo "$log" | grep -v '^W:' | tail -3)"
deb=$(ls "$work"/${pkg}_*.deb 2>/dev/null | head -1)
[ -n "$deb" ] || die "apt-get download $pkg=$version wrote no .deb"
dpkg -x "$deb" "$work/root"
lib=$(find "$work/root" -name libVkLayer_gfxreconstruct.so -print -quit)
manifest=$(find "$work/root" -name 'VkLayer_gfxreconstruct.json' -print -quit)
[ -n "$lib" ] && [ -n "$manifest" ] || die "$(basename "$deb") holds no capture layer (libVkLayer_gfxreconstruct.so and its manifest)"
missing=$(unresolved "$lib")
for t in "${tools[@]}"; do
  [ -x "$work/root/usr/bin/$t" ] || die "$(basename "$deb") holds no $t"
  missing="$missing $(unresolved "$work/root/usr/bin/$t")"
done
missing=$(echo "$missing" | tr ' ' '\n' | sort -u | tr '\n' ' ' | sed 's/^ *//; s/ *$//')
[ -z "$missing" ] || die "GFXReconstruct needs libraries this machine lacks: $missing (apt-get install liblz4-1 libzstd1)"

# Written beside, then renamed into place: a run stopped half way leaves no half folder.
stage=$(mktemp -d "$(dirname "$dir")/.gfxreconstruct.XXXXXX" 2>/dev/null || { mkdir -p "$(dirname "$dir")" && mktemp -d "$(dirname "$dir")/.gfxreconstruct.XXXXXX"; })
mkdir -p "$stage/layer" "$stage/lib" "$stage/bin"
cp "$lib" "$stage/lib/"
for t in "${tools[@]}"; do cp "$work/root/usr/bin/$t" "$stage/bin/"; done
sed "s|\"library_path\": *\"[^\"]*\"|\"library_path\": \"$dir/lib/libVkLayer_gfxreconstruct.so\"|" "$manifest" \
  >"$stage/layer/VkLayer_gfxreconstruct.json"
echo "$version" >"$stage/version"
rm -rf "$dir"
mv "$stage" "$dir"
say "GFXReconstruct $version unpacked in $dir (trilab repro finds it there)"
echo "$dir"
