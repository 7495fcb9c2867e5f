#!/usr/bin/env bash
# A lent GPU's 15 minutes, prepared here and spent in one command there (docs/suite-and-device-run.md).
#
#   scripts/device-run.sh pack            here: builds what travels into .travel/ (ignored by git),
#                                          checks the size budget, prints the device tool's
#                                          `carry` list and the one command to give it
#   scripts/device-run.sh run [MINUTES]   there (and here, as CI's rehearsal on lavapipe): loaders,
#                                          `trilab devices`, `trilab roofline`, `trilab suite` with
#                                          the tinybvh peer and four layouts, everything in one
#                                          archive under $OUT
#   scripts/device-run.sh unpack ARCHIVE [ROOT]
#                                          here: the archive into ROOT/results/<device>/ (ROOT: this
#                                          checkout), stored as results/ keeps results, then
#                                          `trilab merge` of lavapipe and that device, whose
#                                          verdicts fill ROOT/results/README.md's GPU column.
#                                          The archive is untrusted: all of it is checked before
#                                          anything is written, and it is refused whole (exit 1,
#                                          naming each offending entry and why) for anything but
#                                          regular files and folders under results/<device>/ (and
#                                          run.log beside results/), for a device name trilab does
#                                          not write, and when damaged or cut. It is unpacked into
#                                          ROOT/results/.unpack.XXXXXX/ and each device's folder
#                                          renamed into place: a failure leaves results/ as it was.
#                                          A device already under ROOT/results/ (a second unpack,
#                                          a rerun on the same GPU) is refused, naming the files
#                                          the archive would overwrite and which git tracks:
#                                          results are never overwritten; move the folder away
#                                          first (git mv results/<device> results/<device>-before) or unpack
#                                          into another ROOT.
#
# What travels (.travel/, one `carry` path; the tracked tree travels by itself):
#   trilab            the release binary, stripped (symbols and line tables stay in target/)
#   debs/             libvulkan1 and ocl-icd-libopencl1 from Debian 12: the GPU machine has no
#                     Vulkan or OpenCL loader; `run` unpacks them into a private prefix
#   peers/tinybvh/    tinybvh_rays for portable x86-64 (-march=x86-64-v3: AVX2, as its bvh8
#                     layout needs; not -march=native, the GPU machine's CPU is another) with
#                     OpenCL, and its .cl kernels
#   COMMIT            the commit packed (TRILAB_COMMIT there, where there is no .git)
# Budget: the tracked tree, ../shared, and .travel/ together under 60 MiB (the device tool
# refuses 64 MiB; 56 until issue 50's results/radv/ and its code brought the whole to 56.8 MiB,
# 58 until issue 53's packet and hybrid kernels, 288 of them, 1.9 MiB deflated in the binary,
# brought it to 59.5 MiB, of which 52.4 MiB travel).
# `../shared` does not travel (the device tool sends the checkout only) but is counted, as a run
# that needs a shared scene would carry it.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
travel=$root/.travel
BUDGET_MIB=60
ARCHIVE_MAX=$((16 * 1024 * 1024))
LAYOUTS=bvh2,bvh4,qbvh4,cwbvh
# The repros' scene: 2,000 triangles, a repro of 0.4 MB (docs/repro.md).
REPRO_SCENE=synth:soup:2000

mib() { awk -v b="$1" 'BEGIN { printf "%.2f", b / 1048576 }'; }
bytes_of() { if [ -e "$1" ]; then du -sb --apparent-size "$1" | cut -f1; else echo 0; fi; }

# --- pack -------------------------------------------------------------------------------------
pack() {
  cd "$root"
  export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$root/target}
  cargo build --release -q
  mkdir -p "$travel/debs" "$travel/peers"
  strip --strip-all -o "$travel/trilab.tmp" "$CARGO_TARGET_DIR/release/trilab"
  mv "$travel/trilab.tmp" "$travel/trilab"

  # The loaders, as the device tool's README fetches them (any host processor: amd64 forced).
  if ! ls "$travel"/debs/libvulkan1_*.deb "$travel"/debs/ocl-icd-libopencl1_*.deb >/dev/null 2>&1; then
    local lists=/tmp/trilab-amd64-lists
    mkdir -p "$lists/partial"
    local o=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists="$lists")
    apt-get "${o[@]}" update -qq >/dev/null
    (cd "$travel/debs" && apt-get "${o[@]}" download -qq libvulkan1 ocl-icd-libopencl1 >/dev/null)
  fi

  # tinybvh's peer, portable (its own build.sh builds for -march=native).
  local src=${TRILAB_TINYBVH_SRC:-}
  for d in "$root/../shared/peers/tinybvh" "$root/../../shared/peers/tinybvh"; do
    if [ -z "$src" ] && [ -f "$d/tinybvh_rays.cpp" ]; then src=$d; fi
  done
  if [ -n "$src" ]; then
    for p in ocl-icd-opencl-dev opencl-headers; do
      dpkg -s "$p" >/dev/null 2>&1 || apt-get install -y -qq --no-install-recommends "$p" >/dev/null
    done
    local peer=$travel/peers/tinybvh
    mkdir -p "$peer/tinybvh_cl"
    g++ -O3 -march=x86-64-v3 -std=c++20 -DWITH_OPENCL -static-libstdc++ -static-libgcc \
      -o "$peer/tinybvh_rays" "$src/tinybvh_rays.cpp" -lOpenCL -lpthread
    strip --strip-all "$peer/tinybvh_rays"
    cp "$src"/traverse.cl "$src"/traverse_bvh2.cl "$src"/traverse_bvh4.cl "$src"/traverse_cwbvh.cl "$peer/tinybvh_cl/"
  else
    rm -rf "$travel/peers/tinybvh"
    echo "device-run.sh pack: no tinybvh source (../shared/peers/tinybvh or TRILAB_TINYBVH_SRC): the run has no peer" >&2
  fi

  # GFXReconstruct's replay and capture layer (scripts/gfxreconstruct.sh; 6 MB, 2.5 compressed)
  # and a repro made here on lavapipe (issue 41): there, the repro is checked on the GPU's driver
  # (trilab's dispatch and gfxrecon-replay's, hits ray by ray), and one made there comes back.
  rm -rf "$travel/repro-here" "$travel/gfxreconstruct.tar.gz"
  local g=${TRILAB_GFXRECON:-$HOME/.cache/trilab/gfxreconstruct}
  if [ -x "$g/bin/gfxrecon-replay" ]; then
    tar -C "$g" -czf "$travel/gfxreconstruct.tar.gz" bin/gfxrecon-replay lib layer version
    local rays=$travel/repro-rays.tmp
    "$CARGO_TARGET_DIR/release/trilab" rays primary --scene "$REPRO_SCENE" --width 32 --height 32 --out "$rays" >/dev/null
    TRILAB_GFXRECON=$g "$CARGO_TARGET_DIR/release/trilab" repro --scene "$REPRO_SCENE" --rays "$rays" \
      --capture required --out "$travel/repro-here" >/dev/null
    rm -f "$rays" "$rays.json"
  else
    echo "device-run.sh pack: no GFXReconstruct ($g; scripts/gfxreconstruct.sh): the run makes no repro" >&2
  fi

  local commit
  commit=$(git rev-parse --short=12 HEAD)
  [ -z "$(git status --porcelain --untracked-files=no)" ] || commit="$commit-dirty"
  echo "$commit" > "$travel/COMMIT"

  # The budget: what the device tool copies, and ../shared.
  local tree shared pack total
  # (A tracked file deleted in the working tree does not travel: stat's error is ignored.)
  tree=$( (git ls-files -z | xargs -0 stat -c %s 2>/dev/null || true) | awk '{ s += $1 } END { print s + 0 }')
  shared=$(bytes_of "$root/../shared")
  pack=$(bytes_of "$travel")
  total=$((tree + shared + pack))
  {
    echo "what travels                        MiB"
    printf '  tracked tree (git ls-files)   %7s\n' "$(mib "$tree")"
    printf '  ../shared (counted)           %7s\n' "$(mib "$shared")"
    printf '  .travel/trilab (stripped)     %7s\n' "$(mib "$(bytes_of "$travel/trilab")")"
    printf '  .travel/debs (loaders)        %7s\n' "$(mib "$(bytes_of "$travel/debs")")"
    printf '  .travel/peers (tinybvh)       %7s\n' "$(mib "$(bytes_of "$travel/peers")")"
    printf '  .travel/gfxreconstruct, repro %7s\n' "$(mib $(( $(bytes_of "$travel/gfxreconstruct.tar.gz") + $(bytes_of "$travel/repro-here") )))"
    printf '  total                         %7s  (budget %s, device tool limit 64)\n' "$(mib "$total")" "$BUDGET_MIB"
  } | tee "$travel/SIZES"
  if [ "$total" -gt $((BUDGET_MIB * 1024 * 1024)) ]; then
    echo "device-run.sh pack: $(mib "$total") MiB is over the $BUDGET_MIB MiB budget" >&2
    exit 1
  fi
  cat <<EOF

Packed commit $commit. Give the device tool (one call; no kind: an H100, or an H200):
  carry:     [".travel"]
  timeout_s: 590
  command:   bash scripts/device-run.sh run 8.5
Then, here: scripts/device-run.sh unpack /work/.device/<files_at>/trilab-results.tar.gz
(give_back at once unless you rerun).
EOF
}

# --- run --------------------------------------------------------------------------------------
run() {
  local minutes=${1:-8.5}
  local start deadline
  start=$(date +%s)
  deadline=$(awk -v s="$start" -v m="$minutes" 'BEGIN { printf "%d", s + m * 60 }')
  cd "$root"
  local out=${OUT:-$root/target/device-run/out}
  mkdir -p "$out"
  # Globals: the EXIT trap that writes the archive runs after this function has returned.
  work=$(mktemp -d /tmp/trilab-device-run.XXXXXX)
  log=$work/run.log
  archive=$out/trilab-results.tar.gz
  local exe=$travel/trilab
  [ -x "$exe" ] || { echo "device-run.sh run: $exe missing: run \`scripts/device-run.sh pack\` first" >&2; exit 2; }

  say() { echo "[device-run $(( $(date +%s) - start )) s] $*" | tee -a "$log" >&2; }
  left() { echo $(( deadline - $(date +%s) )); }
  # The archive, rewritten after every step: a run stopped at any point leaves what finished.
  pack_results() {
    local files=(run.log)
    [ -d "$work/results" ] && files+=(results)
    tar -C "$work" -czf "$archive.tmp" "${files[@]}"
    if [ "$(stat -c %s "$archive.tmp")" -gt "$ARCHIVE_MAX" ]; then
      say "archive over 16 MiB: packing it again without the PNG plots"
      tar -C "$work" --exclude='*.png' -czf "$archive.tmp" "${files[@]}"
    fi
    mv "$archive.tmp" "$archive"
  }
  trap pack_results EXIT

  local rc
  say "run: $minutes minutes, commit $(cat "$travel/COMMIT" 2>/dev/null || echo unknown), host $(uname -n), $(nproc) CPUs"
  # Loaders in a private prefix (never over /): the Vulkan loader (libvulkan.so.1, which trilab
  # opens) and the OpenCL ICD loader (which tinybvh_rays links).
  local prefix=$work/loaders
  mkdir -p "$prefix"
  for f in "$travel"/debs/*.deb; do
    [ -e "$f" ] && dpkg -x "$f" "$prefix"
  done
  export LD_LIBRARY_PATH=$prefix/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
  # NVIDIA's ICDs where the machine keeps them (the device tool's README).
  local nv=/usr/local/nvidia
  if [ -z "${VK_DRIVER_FILES:-}${VK_ICD_FILENAMES:-}" ] && [ -f $nv/share/vulkan/icd.d/nvidia_icd.json ]; then
    export VK_DRIVER_FILES=$nv/share/vulkan/icd.d/nvidia_icd.json
  fi
  if [ -z "${OCL_ICD_VENDORS:-}" ] && ! ls /etc/OpenCL/vendors/*.icd >/dev/null 2>&1; then
    local cl
    cl=$(ls $nv/lib64/libnvidia-opencl.so.1 $nv/lib/libnvidia-opencl.so.1 \
      /usr/lib/x86_64-linux-gnu/libnvidia-opencl.so.1 2>/dev/null | head -1 || true)
    if [ -n "$cl" ]; then
      mkdir -p "$prefix/vendors"
      echo "$cl" > "$prefix/vendors/nvidia.icd"
      export OCL_ICD_VENDORS=$prefix/vendors
    fi
  fi
  export TRILAB_COMMIT=${TRILAB_COMMIT:-$(cat "$travel/COMMIT" 2>/dev/null || echo unknown)}
  say "VK_DRIVER_FILES=${VK_DRIVER_FILES:-} OCL_ICD_VENDORS=${OCL_ICD_VENDORS:-} TRILAB_COMMIT=$TRILAB_COMMIT"
  command -v nvidia-smi >/dev/null && nvidia-smi >> "$log" 2>&1 || true

  say "trilab devices"
  if ! "$exe" devices >> "$log" 2>&1; then
    say "trilab devices failed: no usable Vulkan device (see above); nothing else can run"
    exit 1
  fi
  repro_step
  local peer=() peer_exe=$travel/peers/tinybvh/tinybvh_rays
  if [ -x "$peer_exe" ]; then
    export TINYBVH_CL_DIR=$travel/peers/tinybvh/tinybvh_cl
    peer=(--tinybvh "$peer_exe")
  else
    say "no tinybvh peer packed: the bench runs without it"
  fi

  # The traversal roofline (`trilab roofline`: node steps per second per working set and access
  # path, what the suite's kernels can be held against), before the suite and outside its budget:
  # seconds on a GPU. A run of under 4 minutes (the rehearsal on lavapipe, where the full sweep
  # takes a minute or more) sweeps two small sizes only; one of under 90 s skips it.
  local roof=(roofline --rounds 3) roof_s=$(( $(left) / 6 ))
  [ "$roof_s" -le 90 ] || roof_s=90
  if [ "$(left)" -lt 240 ]; then
    roof=(roofline --rounds 2 --sizes 16K,1M --invocations 65536)
    roof_s=20
  fi
  if [ "$(left)" -ge 90 ]; then
    say "trilab ${roof[*]} (at most $roof_s s)"
    rc=0
    (cd "$work" && timeout -k 5 "$roof_s" "$exe" "${roof[@]}" >> "$log" 2>&1) || rc=$?
    case $rc in
      0) say "roofline completed" ;;
      124 | 137) say "roofline stopped after $roof_s s: no roofline in this archive" ;;
      *) say "roofline exit $rc (see above)" ;;
    esac
    pack_results
  else
    say "roofline skipped: $(left) s left is too short a run"
  fi

  # Every traversal on every layout, bench-validated against the f64 reference before it reports:
  # the subgroup-cooperative, packet and hybrid kernels at the GPU's own subgroup width (32 on
  # NVIDIA), which lavapipe (4-16 lanes) and the CPU lane model cannot show on real hardware
  # (issue 53: do packets pay where loads of a uniform address are scalar? do tiles of primary
  # rays help a 32-lane packet? do the per-ray kernels with their stacks in scratch, sized for
  # AMD's registers (results/radv/stack-53/), run well on NVIDIA?). Skipped in a run
  # under 4 minutes (the rehearsal); at most 90 s. Its folder joins the device's after the suite.
  local trav_s=90
  if [ "$(left)" -ge 240 ]; then
    say "trilab bench --traversals (every traversal and layout, bunny and dragon; at most $trav_s s)"
    rc=0
    (cd "$work" && timeout -s INT -k 10 "$trav_s" "$exe" bench --scene-dir "$root/scenes" \
      --scenes bunny,dragon --methods mt,quad-unit,watertight --repeat 5 \
      --traversals while-if,while-while,coop,persistent,packet,hybrid --layouts bvh2,bvh4,qbvh4,bvh8,cwbvh \
      --orders given,tiles \
      --out "$work/extra/traversals" >> "$log" 2>&1) || rc=$?
    case $rc in
      0) say "traversals bench completed" ;;
      124 | 130 | 137) say "traversals bench stopped after $trav_s s" ;;
      *) say "traversals bench exit $rc (see above)" ;;
    esac
  fi

  # The suite's budget: what is left but a minute (the archive, a part that overruns its
  # prediction); the suite scales every part to it from its own probe of this device, and a
  # hard stop 30 s before the deadline keeps the whole inside the device tool's 10 minutes.
  local budget_s=$(( $(left) - 60 ))
  [ "$budget_s" -ge 30 ] || budget_s=30
  local budget_min
  budget_min=$(awk -v s="$budget_s" 'BEGIN { printf "%.2f", s / 60 }')
  say "trilab suite --budget-minutes $budget_min --layouts $LAYOUTS ${peer[*]}"
  rc=0
  (cd "$work" && timeout -s INT -k 15 $(( $(left) - 30 )) "$exe" suite --budget-minutes "$budget_min" --no-threads \
    --layouts "$LAYOUTS" --scene-dir "$root/scenes" "${peer[@]}" >> "$log" 2>&1) || rc=$?
  case $rc in
    0) say "suite completed" ;;
    124 | 130 | 137) say "suite stopped at the deadline (exit $rc): the archive holds the parts that finished" ;;
    *) say "suite exit $rc: a part did not complete (summary.md says which and why)" ;;
  esac
  local dev
  for dev in "$work"/results/*/; do
    [ -d "$dev" ] || continue
    [ -d "$work/extra/traversals" ] && cp -r "$work/extra/traversals" "$dev/traversals"
    [ -d "$work/extra/repro" ] && cp -r "$work/extra/repro" "$dev/repro"
    cp "$log" "$dev/run.log"
  done
  say "done in $(( $(date +%s) - start )) s; archive $archive"
  return 0
}

# The repro made where `pack` ran, checked on this driver (trilab's dispatch of its files, and
# gfxrecon-replay's of its capture, hits ray by ray), and one made here, which `unpack` brings
# into results/<device>/repro/ to be checked on the CPU drivers. Seconds; a failure is logged.
repro_step() {
  [ -f "$travel/gfxreconstruct.tar.gz" ] || { say "no GFXReconstruct packed: no repro"; return 0; }
  local g=$work/gfxreconstruct
  mkdir -p "$g" "$work/extra/repro"
  tar -C "$g" -xzf "$travel/gfxreconstruct.tar.gz"
  sed -i "s|\"library_path\": *\"[^\"]*\"|\"library_path\": \"$g/lib/libVkLayer_gfxreconstruct.so\"|" \
    "$g/layer/VkLayer_gfxreconstruct.json"
  export TRILAB_GFXRECON=$g
  local rc=0
  say "trilab repro --check (the repro made on $(jq_field "$travel/repro-here/cell.json" made.driver))"
  (cd "$work" && timeout -k 5 60 "$exe" repro --check "$travel/repro-here" --gfxrecon --json \
    > "$work/extra/repro/check-of-packed.json" 2>> "$log") || rc=$?
  say "repro check exit $rc"
  rc=0
  (cd "$work" && timeout -k 5 60 "$exe" rays primary --scene "$REPRO_SCENE" --width 32 --height 32 \
    --out "$work/repro.rays" >> "$log" 2>&1 &&
    timeout -k 5 60 "$exe" repro --scene "$REPRO_SCENE" --rays "$work/repro.rays" --capture required \
      --out "$work/extra/repro/made-here" >> "$log" 2>&1) || rc=$?
  say "repro made here: exit $rc"
}

# A field of a JSON file (dotted path), or `unknown`.
jq_field() {
  python3 -c 'import json,sys
v=json.load(open(sys.argv[1]))
for k in sys.argv[2].split("."): v=v[k]
print(v)' "$1" "$2" 2>/dev/null || echo unknown
}

# --- unpack -----------------------------------------------------------------------------------
# results/README.md's claims table gets the device's verdicts in its last ("real GPU") column:
# header = the device's label, each claim's cell = "**verdict.** summary" from the merge of
# lavapipe and that device. Written to a temporary file and renamed (never half a README).
fill_gpu_column() {
  local readme=$1 merged=$2 suite=$3
  if [ ! -f "$readme" ]; then
    echo "no $readme: the GPU column is $merged's claims (fill it by hand)"
    return 0
  fi
  python3 - "$readme" "$merged" "$suite" <<'PY'
import json, os, sys
readme, merged, suite = sys.argv[1:]
m = json.load(open(merged))
suite = os.path.realpath(suite)
ours = {d["label"] for d in m["devices"]
        if any(os.path.realpath(f).startswith(suite + os.sep) for f in d["files"])}
found = [c for c in m["claims"] if c["device"] in ours]
if not found:
    sys.exit(f"device-run.sh unpack: {merged} has no study claims from {suite} (the study part did not complete?); results/README.md left as it was")
dev = found[0]
verdict = {c["id"]: f"**{c['verdict'].replace('-', ' ')}.** {c['summary']}".replace("|", "/") for c in dev["claims"]}
lines = open(readme).read().split("\n")
head = next((i for i, l in enumerate(lines) if l.startswith("| claim |") and l.rstrip().endswith("|")), None)
if head is None:
    sys.exit(f"device-run.sh unpack: {readme} has no claims table ('| claim | ...')")
def set_last(line, text):
    cells = line.rstrip().rstrip("|").split("|")
    cells[-1] = f" {text} "
    return "|".join(cells) + "|"
lines[head] = set_last(lines[head], f"{dev['device']} ({dev['measured']} of {dev['planned']} cells, {dev['repeat']} rounds)")
filled = 0
for i in range(head + 2, len(lines)):
    if not lines[i].startswith("| ("):
        break
    cid = lines[i][3]
    if cid in verdict:
        lines[i] = set_last(lines[i], verdict[cid])
        filled += 1
tmp = readme + ".tmp"
open(tmp, "w").write("\n".join(lines))
os.replace(tmp, readme)
print(f"filled {readme}'s GPU column: {filled} claims from {dev['device']}")
PY
}

# The archive is untrusted (it comes back from a machine lent for minutes, and a run stopped at
# any point may leave it cut): `check_archive check` reads all of it before anything is written
# and refuses, entry by entry, anything but regular files and folders under results/<device>/
# (and run.log beside results/): links of either kind, devices, absolute paths, `..`, empty or
# `.` components, names outside printable ASCII or with a backslash, a device name that is not
# one trilab writes (DeviceInfo::results_dir: lower-case letters and digits, single `-` between;
# not merged-*, the merges' folders), a name twice, a path under a name the archive holds as a
# file or link, over 2 GiB unpacked; a damaged or cut archive (gzip -t, then GNU tar and
# Python's tarfile must both read it to the end and list the same names); and a device whose
# results/<device>/ already exists under ROOT (naming the files it would overwrite, and which
# git tracks). It prints the devices, one a line. `check_archive extract ARCHIVE STAGE` checks
# again (the file may have changed since) and writes each device's files under STAGE/<device>/,
# itself: only folders and regular files, created new (O_EXCL, O_NOFOLLOW), so no entry can
# reach past STAGE.
check_archive() {
  python3 - "$@" <<'PY'
import os, re, shutil, subprocess, sys, tarfile, zlib
mode, archive, where = sys.argv[1:]
DEVICE = re.compile(r"[a-z0-9]+(-[a-z0-9]+)*")
MAX_BYTES = 2 << 30

def fail(what, lines):
    lines = list(lines)
    shown = lines[:20] + ([f"... and {len(lines) - 20} more"] if len(lines) > 20 else [])
    sys.exit("\n  ".join([f"device-run.sh unpack: {archive}: {what}, nothing unpacked:"] + shown))

def damaged(why):
    fail("damaged or truncated (a cut archive, or not what `run` wrote)", [why])

def kind(m):
    if m.issym(): return f"a symbolic link (-> {m.linkname!r})"
    if m.islnk(): return f"a hard link (to {m.linkname!r})"
    if m.ischr(): return "a character device"
    if m.isblk(): return "a block device"
    if m.isfifo(): return "a FIFO"
    return f"an entry of tar type {m.type!r}"

def norm(name, is_dir):
    while name.startswith("./"):
        name = name[2:]
    return name.rstrip("/") if is_dir else name

# The gzip stream whole (a cut anywhere, even in its 8-byte trailer, fails its length or CRC).
r = subprocess.run(["gzip", "-t", "--", archive], capture_output=True)
if r.returncode:
    damaged(r.stderr.decode(errors="replace").strip() or f"gzip -t exit {r.returncode}")
r = subprocess.run(["tar", "--quoting-style=literal", "-tzf", archive], capture_output=True)
if r.returncode:
    damaged("tar -t: " + r.stderr.decode(errors="replace").strip())
listed = r.stdout.decode("utf-8", "surrogateescape").split("\n")[:-1]
try:
    tf = tarfile.open(archive, "r:gz")
    members = tf.getmembers()
except (tarfile.TarError, EOFError, OSError, zlib.error) as e:
    damaged(f"Python's tarfile: {type(e).__name__}: {e}")

problems, names, seen, not_dirs, devices, total = [], [], set(), {}, [], 0
for m in members:
    raw, why = m.name, []
    name = norm(raw, m.isdir())
    names.append(name)
    if m.isdir() and name in ("", "."):
        continue  # the archive's own top folder
    if not (m.isreg() or m.isdir()):
        why.append(f"{kind(m)}: only regular files and folders are unpacked")
    if any(not " " <= c <= "~" or c == "\\" for c in raw):
        why.append("a control, non-ASCII or backslash character in its name")
    parts = name.split("/")
    if raw.startswith("/"):
        why.append("an absolute path: it would be written outside results/<device>/")
    else:
        if ".." in parts:
            why.append("a '..' component: it would climb out of results/<device>/")
        if "" in parts or "." in parts:
            why.append("an empty or '.' component")
        if parts[0] == "results" and len(parts) > 1:
            dev = parts[1]
            if not DEVICE.fullmatch(dev) or dev.startswith("merged-"):
                why.append(f"device name {dev!r} is not a folder trilab writes under results/ "
                           "(lower-case letters and digits, single '-' between, not merged-*)")
            elif len(parts) == 2 and not m.isdir():
                why.append("a file where the device's folder belongs")
            elif dev not in devices:
                devices.append(dev)
        elif parts[0] == "results" and not m.isdir():
            why.append("a file where the results/ folder belongs")
        elif parts[0] != "results" and not (name == "run.log" and m.isreg()):
            why.append("outside results/<device>/ (only run.log may sit beside results/)")
    if name in seen:
        why.append("a second entry of that name")
    seen.add(name)
    if not m.isdir():
        not_dirs[name] = "a symbolic link" if m.issym() else "a hard link" if m.islnk() else "a file"
    if m.isreg():
        total += m.size
    if why:
        problems.append(f"{raw!r}: " + "; ".join(why))
for m, name in zip(members, names):
    parts = name.split("/")
    for i in range(1, len(parts)):
        above = "/".join(parts[:i])
        if above in not_dirs:
            problems.append(f"{m.name!r}: under {above!r}, which the archive holds as {not_dirs[above]} "
                            "(written through a link, it would land wherever the link points)")
            break
if total > MAX_BYTES:
    problems.append(f"{total / 2**30:.1f} GiB unpacked, over the {MAX_BYTES >> 30} GiB an archive of results may hold")
if problems:
    fail("refused", problems)
# GNU tar and Python read the same archive: the same names, in the same order.
ours = [n for n, m in zip(names, members) if not (m.isdir() and n in ("", "."))]
theirs = [n for n in (norm(l, True) for l in listed) if n not in ("", ".")]
if ours != theirs:
    diff = next((i for i, (a, b) in enumerate(zip(ours, theirs)) if a != b), min(len(ours), len(theirs)))
    damaged(f"GNU tar and Python's tarfile read it differently (entry {diff}: "
            f"{theirs[diff:diff + 1]!r} and {ours[diff:diff + 1]!r}; {len(theirs)} and {len(ours)} entries)")

if mode == "check":
    clashes = []
    for dev in devices:
        rel = f"results/{dev}"
        there = os.path.join(where, rel)
        if not os.path.lexists(there):
            continue
        r = subprocess.run(["git", "-C", where, "ls-files", "-z", "--", rel], capture_output=True)
        tracked = set(r.stdout.decode(errors="replace").split("\0")) - {""} if r.returncode == 0 else set()
        existing = [n for n, m in zip(names, members) if m.isreg() and n.startswith(rel + "/")
                    and os.path.lexists(os.path.join(where, n))]
        held = sum(len(fs) for _, _, fs in os.walk(there))
        said = [f"{n} (tracked by git)" if n in tracked else n for n in existing[:10]]
        more = f", and {len(existing) - 10} more" if len(existing) > 10 else ""
        clashes.append(
            f"{rel}: already exists in {where} ({held} files, {len(tracked)} tracked by git); the archive would "
            f"overwrite {len(existing)} of them" + (": " + ", ".join(said) + more if said else "")
            + f"; results are never overwritten: move it away first (git mv {rel} {rel}-before) "
            "or unpack into another ROOT")
    if clashes:
        fail("refused", clashes)
    print("\n".join(devices))
    sys.exit(0)

# extract: each device's files under STAGE/<device>/, created here, never through a link.
for m, name in zip(members, names):
    parts = name.split("/")
    if parts[0] != "results" or len(parts) < 2:
        continue  # run.log beside results/, results/ itself (checked: results/<device> is a folder)
    target = os.path.join(where, *parts[1:])
    try:
        if m.isdir():
            os.makedirs(target, 0o755, exist_ok=True)
            continue
        os.makedirs(os.path.dirname(target), 0o755, exist_ok=True)
        fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o755 if m.mode & 0o111 else 0o644)
        with os.fdopen(fd, "wb") as out, tf.extractfile(m) as data:
            shutil.copyfileobj(data, out)
    except (OSError, tarfile.TarError, EOFError, zlib.error) as e:
        fail("cannot unpack", [f"{m.name!r}: {type(e).__name__}: {e}"])
PY
}

unpack() {
  local archive=${1:?usage: device-run.sh unpack ARCHIVE [ROOT]} dest=${2:-$root}
  [ -f "$archive" ] || { echo "device-run.sh unpack: $archive: no such file" >&2; exit 2; }
  [ -d "$dest" ] || { echo "device-run.sh unpack: $dest: no such folder (the checkout root to unpack into)" >&2; exit 2; }
  local devices name
  # 1. The whole archive checked; nothing written yet.
  devices=$(check_archive check "$archive" "$dest") || exit 1
  if [ -z "$devices" ]; then
    echo "device-run.sh unpack: $archive holds no results/<device>/ (run.log:)" >&2
    tar -xzOf "$archive" run.log >&2 2>/dev/null || echo "(and no run.log)" >&2
    exit 1
  fi
  # 2. Into a staging folder beside the devices' folders (the same file system), then each
  # device's folder renamed into place whole. A failure until then leaves results/ as it was.
  # (Globals: the EXIT trap runs after this function has returned.)
  unpack_made_results=
  [ -d "$dest/results" ] || unpack_made_results=$dest/results
  mkdir -p "$dest/results"
  unpack_stage=$(mktemp -d "$dest/results/.unpack.XXXXXX")
  trap 'rm -rf "$unpack_stage"; [ -z "$unpack_made_results" ] || rmdir "$unpack_made_results" 2>/dev/null || true' EXIT
  check_archive extract "$archive" "$unpack_stage" || exit 1
  while IFS= read -r name; do
    # -T: onto results/<device> itself, never into a folder of that name made meanwhile.
    mv -T "$unpack_stage/$name" "$dest/results/$name"
  done <<< "$devices"
  rm -rf "$unpack_stage"
  trap - EXIT
  # 3. Stored as results/ keeps results; merged with lavapipe where the suite ran.
  while IFS= read -r name; do
    "$root/scripts/compress-results.sh" "$dest/results/$name" >/dev/null
    echo "unpacked $dest/results/$name"
    local exe=$root/.travel/trilab
    [ -x "$exe" ] || exe=${CARGO_TARGET_DIR:-$root/target}/release/trilab
    if [ -d "$dest/results/$name/suite" ]; then
      "$exe" merge "$root/results/lavapipe/merge-widths" "$dest/results/$name/suite" --out "$dest/results/merged-$name"
      echo "merged lavapipe and $name: $dest/results/merged-$name/merge.md"
      fill_gpu_column "$dest/results/README.md" "$dest/results/merged-$name/merge.json" "$dest/results/$name/suite"
    fi
  done <<< "$devices"
}

case ${1:-} in
  pack) pack ;;
  run) shift; run "$@" ;;
  unpack) shift; unpack "$@" ;;
  *) echo "usage: scripts/device-run.sh pack | run [MINUTES] | unpack ARCHIVE [ROOT]" >&2; exit 2 ;;
esac
