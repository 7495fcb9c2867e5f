#!/usr/bin/env bash
# Debian 12's own lavapipe (Mesa 22.3.6, `mesa-vulkan-drivers` from bookworm, not backports)
# beside the installed one, without installing it: downloads the .deb with `apt-get download`,
# unpacks it with `dpkg -x` into a folder, and writes an ICD JSON naming the unpacked driver, for
# the Vulkan loader's VK_DRIVER_FILES. Any library the old driver needs that this machine lacks
# (say libLLVM-15 where only backports' LLVM is installed) is unpacked beside it the same way,
# and LD_LIBRARY_PATH is then part of what to set. Never installs, never needs root; safe to run
# repeatedly (a folder already complete is only checked). Writes only inside DIR.
#
# Usage: scripts/stock-mesa.sh [--quiet] [--deb FILE] [DIR]
#   DIR: default $TRILAB_STOCK_MESA, else $HOME/.cache/trilab/stock-mesa. A folder of its own:
#        one that exists and holds other things (no debs/ or .stock-mesa in it) is refused.
#   --deb FILE: unpack this mesa-vulkan-drivers .deb (read, never changed) instead of asking apt
#        for bookworm's: no download for the driver itself (its version is the .deb's).
# Writes DIR/lvp_icd.json, DIR/radv_icd.json (the same package's RADV, for `trilab driver-stats
# --targets ... --mesa stock`: AMD's compiler as Mesa 22.3.6 has it, through RADV's null device),
# DIR/env (the variables to set, KEY=VALUE lines; tests/stock_mesa.rs reads it), DIR/version (the
# Debian package version), DIR/root/ (the unpacked packages); prints
# the variables as one line to put before a command:
#   env $(cat ~/.cache/trilab/stock-mesa/env) trilab devices
# Exit 0 when DIR is ready, 1 when it cannot be made (the message says why), 2 on bad arguments.
set -euo pipefail

release=bookworm
pkg=mesa-vulkan-drivers
usage="usage: scripts/stock-mesa.sh [--quiet] [--deb FILE] [DIR]"
say() { [ $quiet -eq 1 ] || echo "stock-mesa: $*" >&2; }
die() { echo "stock-mesa: error: $*" >&2; exit 1; }
bad_args() { echo "stock-mesa: error: $*" >&2; echo "$usage" >&2; exit 2; }

quiet=0
deb_given=""
dir=""
dir_given=0
while [ $# -gt 0 ]; do
  case "$1" in
    --quiet) quiet=1 ;;
    -h | --help)
      echo "$usage"
      exit 0
      ;;
    --deb)
      [ $# -ge 2 ] && [ -n "$2" ] || bad_args "--deb needs a FILE (a $pkg .deb)"
      deb_given=$2
      shift
      ;;
    --deb=*) deb_given=${1#--deb=} ;;
    --) shift; break ;;
    -*) bad_args "unknown option \`$1\`" ;;
    *)
      [ $dir_given -eq 0 ] || bad_args "one DIR at most (given \`$dir\` and \`$1\`)"
      dir=$1
      dir_given=1
      ;;
  esac
  shift
done
if [ $# -gt 0 ]; then
  [ $# -eq 1 ] && [ $dir_given -eq 0 ] || bad_args "one DIR at most"
  dir=$1
  dir_given=1
fi
if [ $dir_given -eq 1 ] && [ -z "$dir" ]; then bad_args "DIR is empty"; fi
[ -n "$dir" ] || dir=${TRILAB_STOCK_MESA:-$HOME/.cache/trilab/stock-mesa}
# An absolute DIR: the ICD and env files name paths in it.
case "$dir" in /*) ;; *) dir="$PWD/$dir" ;; esac
dir=${dir%/}
[ -n "$dir" ] || die "DIR is / : the script needs a folder of its own"

for tool in apt-get apt-cache dpkg dpkg-deb ldd; do
  command -v "$tool" >/dev/null || die "needs $tool (Debian's apt and dpkg); this script unpacks Debian 12's package"
done

# DIR is the script's: missing, empty, or one it made before (debs/, or its mark). Anything
# else is refused: the script replaces DIR/root and DIR/debs' contents.
if [ -e "$dir" ] && [ ! -d "$dir" ]; then
  die "DIR $dir exists and is not a folder"
fi
if [ -d "$dir" ] && [ -n "$(ls -A "$dir")" ] && [ ! -e "$dir/.stock-mesa" ] && [ ! -d "$dir/debs" ]; then
  die "DIR $dir holds other things and is not this script's folder (no debs/ or .stock-mesa in it): give an empty or new folder"
fi

# --deb: a readable mesa-vulkan-drivers package; its version is the one unpacked.
deb_version=""
if [ -n "$deb_given" ]; then
  [ -e "$deb_given" ] || die "--deb $deb_given: no such file"
  [ -f "$deb_given" ] || die "--deb $deb_given: not a file"
  [ -r "$deb_given" ] || die "--deb $deb_given: cannot be read"
  fields=$(dpkg-deb --field "$deb_given" Package Version 2>&1) ||
    die "--deb $deb_given: not a Debian package ($(echo "$fields" | tail -1))"
  got=$(echo "$fields" | sed -n 's/^Package: *//p')
  deb_version=$(echo "$fields" | sed -n 's/^Version: *//p')
  [ "$got" = "$pkg" ] || die "--deb $deb_given: the package is \`$got\`, not $pkg"
  [ -n "$deb_version" ] || die "--deb $deb_given: the package names no version"
  deb_given=$(cd "$(dirname "$deb_given")" && pwd)/$(basename "$deb_given")
fi

# The unpacked driver and the libraries it resolves to; prints the `not found` ones.
unresolved() {
  local lib=$1 extra=$2
  LD_LIBRARY_PATH="$extra${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" ldd "$lib" | awk '/not found/ {print $1}'
}

# Already complete: check it still resolves and print it.
# (An unpack made before radv_icd.json was written, of a package that has RADV, is unpacked again.)
radv_written() {
  [ -f "$dir/radv_icd.json" ] || [ -z "$(find "$dir/root" -name libvulkan_radeon.so -print -quit 2>/dev/null)" ]
}
if [ -f "$dir/env" ] && [ -f "$dir/lvp_icd.json" ] && [ -f "$dir/version" ] && radv_written; then
  lib=$(sed -n 's/.*"library_path": *"\([^"]*\)".*/\1/p' "$dir/lvp_icd.json")
  extra=$(sed -n 's/^LD_LIBRARY_PATH=//p' "$dir/env")
  if [ -f "$lib" ] && [ -z "$(unresolved "$lib" "$extra")" ] &&
    { [ -z "$deb_version" ] || [ "$deb_version" = "$(cat "$dir/version")" ]; }; then
    say "$pkg $(cat "$dir/version") already unpacked in $dir"
    tr '\n' ' ' <"$dir/env" | sed 's/ $/\n/'
    exit 0
  fi
  say "$dir is incomplete, no longer resolves, or holds another version: unpacking again"
fi

# The bookworm version apt knows (not backports'): `apt-cache madison` lists each version with
# the archive it comes from.
if [ -n "$deb_version" ]; then
  version=$deb_version
else
  version=$(apt-cache madison "$pkg" 2>/dev/null | awk -F'|' -v r="$release/main" '$3 ~ r && $3 !~ /backports/ {gsub(/ /, "", $2); print $2; exit}')
  if [ -z "$version" ]; then
    die "apt knows no $pkg from $release (apt-cache madison $pkg lists none). This needs Debian 12's main archive in apt's sources and fresh lists: run \`sudo apt-get update\` (the script itself never installs)."
  fi
fi

mkdir -p "$dir/debs" 2>/dev/null || die "cannot make $dir/debs (is $dir writable?)"
touch "$dir/.stock-mesa"
# What a failed run leaves half made is removed; what was complete before stays.
trap 'rm -rf "$dir/root.new" "$dir/lvp_icd.json.tmp" "$dir/radv_icd.json.tmp" "$dir/env.tmp"' EXIT
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

# `dpkg -x` into this folder, never `dpkg -i`: nothing outside DIR changes. A .deb that does
# not unpack (a download cut short, a corrupt file) is named, and left as it is.
unpack() { # .deb [what to do about it]
  local log
  log=$(dpkg -x "$1" "$dir/root.new" 2>&1) ||
    die "$1 cannot be unpacked, it is not a whole .deb (dpkg -x: $(echo "$log" | tail -1)); ${2:-delete it and run again (it is downloaded anew)}"
}

if [ -n "$deb_given" ]; then
  deb=$deb_given
else
  deb=$(fetch "$pkg")
fi
say "unpacking $(basename "$deb") into $dir/root"
if [ -n "$deb_given" ]; then unpack "$deb" "given by --deb: it is left as it is"; else unpack "$deb"; fi
lib=$(find "$dir/root.new" -name libvulkan_lvp.so -print -quit)
icd=$(find "$dir/root.new/usr/share/vulkan/icd.d" -name 'lvp_icd*.json' -print -quit 2>/dev/null || true)
[ -n "$lib" ] && [ -n "$icd" ] || die "$(basename "$deb") holds no libvulkan_lvp.so or lvp_icd*.json"
# The package's RADV, where it has one (Debian's does).
radv_lib=$(find "$dir/root.new" -name libvulkan_radeon.so -print -quit)
radv_icd=$(find "$dir/root.new/usr/share/vulkan/icd.d" -name 'radeon_icd*.json' -print -quit 2>/dev/null || true)
libdir=$(dirname "$lib")

# Libraries the old driver needs that this machine lacks: unpack their bookworm packages too
# (only the dependencies not installed at all; an installed newer version satisfies the soname).
extra=""
if [ -n "$(unresolved "$lib" "")" ]; then
  deps=$(dpkg-deb -f "$deb" Depends | tr ',' '\n' | sed 's/|.*//; s/(.*)//; s/:any//; s/ //g')
  for d in $deps; do
    case "$d" in libvulkan1 | python3*) continue ;; esac
    dpkg -s "$d" >/dev/null 2>&1 && continue
    unpack "$(fetch "$d")"
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
radv_lib=${radv_lib/$dir\/root.new/$dir/root}
radv_icd=${radv_icd/$dir\/root.new/$dir/root}
[ -z "$extra" ] || extra=${extra/$dir\/root.new/$dir/root}
sed "s|\"library_path\": *\"[^\"]*\"|\"library_path\": \"$lib\"|" "$icd" >"$dir/lvp_icd.json.tmp"
mv "$dir/lvp_icd.json.tmp" "$dir/lvp_icd.json"
if [ -n "$radv_lib" ] && [ -n "$radv_icd" ]; then
  sed "s|\"library_path\": *\"[^\"]*\"|\"library_path\": \"$radv_lib\"|" "$radv_icd" >"$dir/radv_icd.json.tmp"
  mv "$dir/radv_icd.json.tmp" "$dir/radv_icd.json"
else
  rm -f "$dir/radv_icd.json"
  say "$(basename "$deb") has no RADV (libvulkan_radeon.so): no radv_icd.json, so no --mesa stock targets"
fi
{
  echo "VK_DRIVER_FILES=$dir/lvp_icd.json"
  [ -z "$extra" ] || echo "LD_LIBRARY_PATH=$extra"
} >"$dir/env.tmp"
mv "$dir/env.tmp" "$dir/env"
echo "$version" >"$dir/version"
say "$pkg $version unpacked; to run trilab on it, set:"
tr '\n' ' ' <"$dir/env" | sed 's/ $/\n/'
