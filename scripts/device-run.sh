#!/usr/bin/env bash
# A lent GPU's 15 minutes, prepared here and spent in one command there (README "On a lent GPU").
#
#   scripts/device-run.sh pack            here: builds what travels into .travel/ (ignored by git),
#                                          checks the size budget, prints the device tool's
#                                          `carry` list and the one command to give it
#   scripts/device-run.sh run [MINUTES]   there (and here, as CI's rehearsal on lavapipe): loaders,
#                                          `trilab devices`, `trilab roofline`, `trilab suite` with
#                                          the tinybvh peer and three layouts, everything in one
#                                          archive under $OUT
#   scripts/device-run.sh unpack ARCHIVE [ROOT]
#                                          here: the archive into ROOT/results/<device>/ (ROOT: this
#                                          checkout), stored as results/ keeps results, then
#                                          `trilab merge` of lavapipe and that device, whose
#                                          verdicts fill ROOT/results/README.md's GPU column
#
# What travels (.travel/, one `carry` path; the tracked tree travels by itself):
#   trilab            the release binary, stripped (symbols and line tables stay in target/)
#   debs/             libvulkan1 and ocl-icd-libopencl1 from Debian 12: the GPU machine has no
#                     Vulkan or OpenCL loader; `run` unpacks them into a private prefix
#   peers/tinybvh/    tinybvh_rays for portable x86-64 (-march=x86-64-v3: AVX2, as its bvh8
#                     layout needs; not -march=native, the GPU machine's CPU is another) with
#                     OpenCL, and its .cl kernels
#   COMMIT            the commit packed (TRILAB_COMMIT there, where there is no .git)
# Budget: the tracked tree, ../shared, and .travel/ together under 56 MiB (the device tool
# refuses 64 MiB). `../shared` does not travel (the device tool sends the checkout only) but is
# counted, as a run that needs a shared scene would carry it.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
travel=$root/.travel
BUDGET_MIB=56
ARCHIVE_MAX=$((16 * 1024 * 1024))
LAYOUTS=bvh2,bvh4,cwbvh

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
    [ -d "$dev" ] && cp "$log" "$dev/run.log"
  done
  say "done in $(( $(date +%s) - start )) s; archive $archive"
  return 0
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

unpack() {
  local archive=${1:?usage: device-run.sh unpack ARCHIVE [ROOT]} dest=${2:-$root}
  [ -f "$archive" ] || { echo "device-run.sh unpack: $archive: no such file" >&2; exit 2; }
  local tmp
  tmp=$(mktemp -d)
  tar -C "$tmp" -xzf "$archive"
  [ -d "$tmp/results" ] || { echo "device-run.sh unpack: $archive holds no results/ (run.log:)" >&2; cat "$tmp/run.log" >&2; exit 1; }
  mkdir -p "$dest/results"
  local dev name
  for dev in "$tmp"/results/*/; do
    name=$(basename "$dev")
    if [ -e "$dest/results/$name" ]; then
      echo "device-run.sh unpack: $dest/results/$name exists; move it away first (results are never overwritten)" >&2
      exit 1
    fi
    mv "$dev" "$dest/results/$name"
    "$root/scripts/compress-results.sh" "$dest/results/$name" >/dev/null
    echo "unpacked $dest/results/$name"
    local exe=$root/.travel/trilab
    [ -x "$exe" ] || exe=${CARGO_TARGET_DIR:-$root/target}/release/trilab
    if [ -d "$dest/results/$name/suite" ]; then
      "$exe" merge "$root/results/lavapipe/merge-widths" "$dest/results/$name/suite" --out "$dest/results/merged-$name"
      echo "merged lavapipe and $name: $dest/results/merged-$name/merge.md"
      fill_gpu_column "$dest/results/README.md" "$dest/results/merged-$name/merge.json" "$dest/results/$name/suite"
    fi
  done
  rm -rf "$tmp"
}

case ${1:-} in
  pack) pack ;;
  run) shift; run "$@" ;;
  unpack) shift; unpack "$@" ;;
  *) echo "usage: scripts/device-run.sh pack | run [MINUTES] | unpack ARCHIVE [ROOT]" >&2; exit 2 ;;
esac
