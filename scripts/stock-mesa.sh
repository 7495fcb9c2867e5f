#!/usr/bin/env bash
# Debian 12's own lavapipe (Mesa 22.3.6, `mesa-vulkan-drivers` from bookworm, not backports)
# beside the installed one, without installing it: downloads the .deb with `apt-get download`,
# unpacks it with `dpkg -x` into a folder, and writes an ICD JSON naming the unpacked driver, for
# the Vulkan loader's VK_DRIVER_FILES. Any library the old driver needs that this machine lacks
# (say libLLVM-15 where only backports' LLVM is installed) is unpacked beside it the same way,
# and LD_LIBRARY_PATH is then part of what to set. Never installs, never needs root; safe to run
# repeatedly (a folder already complete is only checked).
#
# Usage: scripts/stock-mesa.sh [--quiet] [DIR]
#   DIR: default $TRILAB_STOCK_MESA, else $HOME/.cache/trilab/stock-mesa.
# Writes DIR/lvp_icd.json, DIR/env (the variables to set, KEY=VALUE lines; tests/stock_mesa.rs
# reads it), DIR/version (the Debian package version), DIR/root/ (the unpacked packages); prints
# the variables as one line to put before a command:
#   env $(cat ~/.cache/trilab/stock-mesa/env) trilab devices
set -euo pipefail

quiet=0
if [ "${1:-}" = "--quiet" ]; then quiet=1; shift; fi
dir=${1:-${TRILAB_STOCK_MESA:-$HOME/.cache/trilab/stock-mesa}}
release=bookworm
pkg=mesa-vulkan-drivers
say() { [ $quiet -eq 1 ] || echo "stock-mesa: $*" >&2; }
die() { echo "stock-mesa: error: $*" >&2; exit 1; }

for tool in apt-get apt-cache dpkg dpkg-deb ldd; do
  command -v "$tool" >/dev/null || die "needs $tool (Debian's apt and dpkg); this script unpacks Debian 12's package"
done

# The unpacked driver and the libraries it resolves to; prints the `not found` ones.
unresolved() {
  local lib=$1 extra=$2
  LD_LIBRARY_PATH="$extra${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" ldd "$lib" | awk '/not found/ {print $1}'
}

# Already complete: check it still resolves and print it.
if [ -f "$dir/env" ] && [ -f "$dir/lvp_icd.json" ] && [ -f "$dir/version" ]; then
  lib=$(sed -n 's/.*"library_path": *"\([^"]*\)".*/\1/p' "$dir/lvp_icd.json")
  extra=$(sed -n 's/^LD_LIBRARY_PATH=//p' "$dir/env")
  if [ -f "$lib" ] && [ -z "$(unresolved "$lib" "$extra")" ]; then
    say "$pkg $(cat "$dir/version") already unpacked in $dir"
    tr '\n' ' ' <"$dir/env" | sed 's/ $/\n/'
    exit 0
  fi
  say "$dir is incomplete or its libraries no longer resolve: unpacking again"
fi

# The bookworm version apt knows (not backports'): `apt-cache madison` lists each version with
# the archive it comes from.
version=$(apt-cache madison "$pkg" 2>/dev/null | awk -F'|' -v r="$release/main" '$3 ~ r && $3 !~ /backports/ {gsub(/ /, "", $2); print $2; exit}')
if [ -z "$version" ]; then
  die "apt knows no $pkg from $release (apt-cache madison $pkg lists none). This needs Debian 12's main archive in apt's sources and fresh lists: run \`sudo apt-get update\` (the script itself never installs)."
fi

mkdir -p "$dir/debs"
rm -rf "$dir/root.new"
mkdir -p "$dir/root.new"
fetch() { # package -> the .deb's path
  local p=$1 v
  v=$(apt-cache madison "$p" 2>/dev/null | awk -F'|' -v r="$release/main" '$3 ~ r && $3 !~ /backports/ {gsub(/ /, "", $2); print $2; exit}')
  [ -n "$v" ] || die "apt knows no $p from $release (needed by the unpacked driver); run \`sudo apt-get update\`"
  local f
  f=$(ls "$dir/debs/${p}_"*"$(echo "$v" | sed 's/^[0-9]*://')_"*.deb 2>/dev/null | head -1 || true)
  if [ -z "$f" ]; then
    say "downloading $p $v ($release)"
    local log
    log=$( (cd "$dir/debs" && apt-get download -q "$p=$v") 2>&1) ||
      die "apt-get download $p=$v failed (is the Debian mirror reachable?): $(echo "$log" | grep -v '^W:' | tail -3)"
    f=$(ls "$dir/debs/${p}_"*"$(echo "$v" | sed 's/^[0-9]*://')_"*.deb 2>/dev/null | head -1 || true)
    [ -n "$f" ] || die "apt-get download $p=$v wrote no .deb in $dir/debs"
  fi
  echo "$f"
}

deb=$(fetch "$pkg")
say "unpacking $(basename "$deb") into $dir/root"
dpkg -x "$deb" "$dir/root.new"
lib=$(find "$dir/root.new" -name libvulkan_lvp.so -print -quit)
icd=$(find "$dir/root.new/usr/share/vulkan/icd.d" -name 'lvp_icd*.json' -print -quit 2>/dev/null || true)
[ -n "$lib" ] && [ -n "$icd" ] || die "$(basename "$deb") holds no libvulkan_lvp.so or lvp_icd*.json"
libdir=$(dirname "$lib")

# Libraries the old driver needs that this machine lacks: unpack their bookworm packages too
# (only the dependencies not installed at all; an installed newer version satisfies the soname).
extra=""
if [ -n "$(unresolved "$lib" "")" ]; then
  deps=$(dpkg-deb -f "$deb" Depends | tr ',' '\n' | sed 's/|.*//; s/(.*)//; s/:any//; s/ //g')
  for d in $deps; do
    case "$d" in libvulkan1 | python3*) continue ;; esac
    dpkg -s "$d" >/dev/null 2>&1 && continue
    dpkg -x "$(fetch "$d")" "$dir/root.new"
  done
  extra=$libdir
  missing=$(unresolved "$lib" "$extra")
  [ -z "$missing" ] || die "the unpacked driver still misses: $missing (ldd $lib)"
fi

# Swap the new tree in, then point the ICD at its absolute path.
rm -rf "$dir/root"
mv "$dir/root.new" "$dir/root"
lib=${lib/$dir\/root.new/$dir/root}
icd=${icd/$dir\/root.new/$dir/root}
[ -z "$extra" ] || extra=${extra/$dir\/root.new/$dir/root}
sed "s|\"library_path\": *\"[^\"]*\"|\"library_path\": \"$lib\"|" "$icd" >"$dir/lvp_icd.json.tmp"
mv "$dir/lvp_icd.json.tmp" "$dir/lvp_icd.json"
{
  echo "VK_DRIVER_FILES=$dir/lvp_icd.json"
  [ -z "$extra" ] || echo "LD_LIBRARY_PATH=$extra"
} >"$dir/env.tmp"
mv "$dir/env.tmp" "$dir/env"
echo "$version" >"$dir/version"
say "$pkg $version unpacked; to run trilab on it, set:"
tr '\n' ' ' <"$dir/env" | sed 's/ $/\n/'
