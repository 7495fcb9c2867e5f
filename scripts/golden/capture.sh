#!/usr/bin/env bash
# capture.sh BIN OUTDIR
#
# Golden-results capture for trilab: runs BIN (cwd = $TRILAB_SRC, default this checkout, so that
# scenes/*.obj resolve) over a broad, fast, deterministic set of workloads and stores every
# output under OUTDIR:
#
# The option spellings are those before issue 14 (`--validate`, `--count`, `--json-out`, ...):
# later binaries still take them as hidden aliases, so one script runs both sides of an A/B.
#
#   OUTDIR/commands.txt      name <TAB> exit code <TAB> command line  (paths under OUTDIR are
#                            written as <OUT>, BIN as "trilab"; compared by compare.sh)
#   OUTDIR/timings.txt       name <TAB> wall seconds  (NOT compared; for humans)
#   OUTDIR/meta/             outdir path, binary sha256, device list, env (NOT compared, except
#                            outdir which compare.sh uses to normalise embedded paths)
#   OUTDIR/log/NAME.stdout   stdout of text-mode commands   (compared as informational text)
#   OUTDIR/log/NAME.stderr   stderr of every command         (compared as informational text)
#   OUTDIR/json/NAME.json    stdout of --json commands       (compared after volatile-field strip)
#   OUTDIR/rays/*.rays       ray files                       (sha256)
#   OUTDIR/hits/*.hits       hit files                       (sha256)
#   OUTDIR/render/*.{exr,png,json}                           (sha256 / stripped JSON)
#   OUTDIR/<cmd>/...         csv/json/md/png written by bench, study, accuracy, scale, ...
#
# A command that fails is recorded (exit code + stderr) and the capture goes on: a failure is
# itself a result to compare. Every command runs under `timeout` ($GOLDEN_TIMEOUT, default 600 s)
# so a hang in a new binary shows up as exit code 124 instead of blocking the capture.
#
# Environment knobs: TRILAB_SRC (cwd, default this checkout), GOLDEN_TIMEOUT (seconds per command).
set -u

if [ $# -ne 2 ]; then
    echo "usage: $0 BIN OUTDIR" >&2
    exit 2
fi
BIN=$(readlink -f "$1")
if [ ! -x "$BIN" ]; then
    echo "capture.sh: $1 is not an executable" >&2
    exit 2
fi
SRC=${TRILAB_SRC:-$(cd "$(dirname "$(readlink -f "$0")")/../.." && pwd)}
TMO=${GOLDEN_TIMEOUT:-600}
if [ -e "$2" ] && [ -n "$(ls -A "$2" 2>/dev/null)" ]; then
    echo "capture.sh: $2 exists and is not empty; refusing to mix captures" >&2
    exit 2
fi
mkdir -p "$2" || exit 2
OUT=$(readlink -f "$2")
cd "$SRC" || { echo "capture.sh: cannot cd to $SRC" >&2; exit 2; }

# Determinism / provenance knobs: the commit string is embedded in study/accuracy/build outputs
# (it would otherwise come from `git rev-parse` of a tree that is being edited); C locale.
export TRILAB_COMMIT=golden
export LC_ALL=C
unset TRILAB_VALIDATION TRILAB_INJECT_FAULT LP_NUM_THREADS 2>/dev/null || true

mkdir -p "$OUT"/{meta,log,json,rays,hits,render,bench,build,scale,study,accuracy,profile,bench-render,spirv}
echo "$OUT" > "$OUT/meta/outdir"
echo "$BIN" > "$OUT/meta/bin"
sha256sum "$BIN" | cut -d' ' -f1 > "$OUT/meta/bin.sha256"
date -u +%Y-%m-%dT%H:%M:%SZ > "$OUT/meta/started"
uname -a > "$OUT/meta/uname"
env | grep -E '^(TRILAB_|LP_|MESA_|VK_|RUST)' | sort > "$OUT/meta/env" || true
# inputs the results depend on (the source tree's scenes); compare.sh warns when they differ
( cd "$SRC" && sha256sum scenes/* ) > "$OUT/meta/inputs.sha256" 2>/dev/null
: > "$OUT/commands.txt"
: > "$OUT/timings.txt"

NCMD=0
NFAIL=0
T0=$(date +%s.%N)

# Command line as recorded: BIN -> trilab, OUT -> <OUT>, tabs/newlines flattened.
_cmdline() {
    local s="trilab" a
    for a in "$@"; do s+=" ${a//$OUT/<OUT>}"; done
    printf '%s' "$s" | tr '\t\n' '  '
}

# _exec NAME STDOUT_FILE ARGS...: run BIN ARGS with stdout to STDOUT_FILE, stderr to log/NAME.stderr.
_exec() {
    local name=$1 so=$2; shift 2
    if grep -q "^${name}	" "$OUT/commands.txt"; then
        echo "capture.sh: duplicate command name $name" >&2
        exit 3
    fi
    local t1 t2 rc
    t1=$(date +%s.%N)
    timeout --kill-after=10 "$TMO" "$BIN" "$@" > "$so" 2> "$OUT/log/$name.stderr" < /dev/null
    rc=$?
    t2=$(date +%s.%N)
    printf '%s\t%d\t%s\n' "$name" "$rc" "$(_cmdline "$@")" >> "$OUT/commands.txt"
    printf '%s\t%.2f\n' "$name" "$(echo "$t2 - $t1" | bc -l)" >> "$OUT/timings.txt"
    NCMD=$((NCMD + 1))
    if [ "$rc" -ne 0 ]; then
        NFAIL=$((NFAIL + 1))
        printf '  [rc=%d] %s: %s\n' "$rc" "$name" "$(tail -n 1 "$OUT/log/$name.stderr" | cut -c1-200)" >&2
    fi
    return 0
}
# run NAME ARGS...   text-mode command: stdout kept as log/NAME.stdout
run()  { local n=$1; shift; _exec "$n" "$OUT/log/$n.stdout" "$@"; }
# runj NAME ARGS...  --json command: stdout kept as json/NAME.json
runj() { local n=$1; shift; _exec "$n" "$OUT/json/$n.json" "$@"; }
section() { printf '[%6.1fs] %s\n' "$(echo "$(date +%s.%N) - $T0" | bc -l)" "$*" >&2; }

METHODS=(mt unit quad-mt quad-unit watertight baldwin-weber f64)
LEAVES=(1 4 16)
BUNNY=scenes/bunny.obj
CORNELL=scenes/cornell.obj
BSDFS=scenes/bsdfs.obj
CORNELL_CAM=0.5,0.5,2.2,0.5,0.5,0,0,1,0,38
BSDFS_CAM=0.5,0.32,1.45,0.5,0.1,0.45,0,1,0,35
# scene key -> scene spec
declare -A SCENE=([bunny]=$BUNNY [terrain]=synth:terrain:20k [spheres]=synth:spheres:5k)
SKEYS=(bunny terrain spheres)
SETS=(primary diffuse random)

# ---------------------------------------------------------------------------------------------
section "devices"
runj devices devices --json
run  devices_text devices

# ---------------------------------------------------------------------------------------------
section "rays"
for k in "${SKEYS[@]}"; do
    s=${SCENE[$k]}
    run "rays_${k}_primary" rays primary --scene "$s" --out "$OUT/rays/$k.primary.rays" --width 160 --height 120
    run "rays_${k}_diffuse" rays diffuse --scene "$s" --out "$OUT/rays/$k.diffuse.rays" --width 160 --height 120 --per-hit 2
    run "rays_${k}_random"  rays random  --scene "$s" --out "$OUT/rays/$k.random.rays" --count 20000
done
# a non-default seed, a tiny set for the ray-query peer, a dragon set
run rays_bunny_diffuse_seed3 rays diffuse --scene $BUNNY --out "$OUT/rays/bunny.diffuse-seed3.rays" --width 64 --height 48 --per-hit 3 --seed 3
run rays_bunny_random_seed11 rays random --scene $BUNNY --out "$OUT/rays/bunny.random-seed11.rays" --count 5000 --seed 11
run rays_bunny_random2k rays random --scene $BUNNY --out "$OUT/rays/bunny.random2k.rays" --count 2000
run rays_dragon_random rays random --scene scenes/dragon.obj --out "$OUT/rays/dragon.random.rays" --count 10000
run rays_buddha_primary rays primary --scene scenes/buddha.obj --out "$OUT/rays/buddha.primary.rays" --width 96 --height 72
# hostile ray files for the error paths (made here, deterministic bytes)
head -c 100 "$OUT/rays/bunny.random.rays" > "$OUT/rays/bad.oddlength.rays"
{ head -c 32 "$OUT/rays/bunny.random.rays"; printf '\x00\x00\xc0\x7f'; tail -c +37 "$OUT/rays/bunny.random.rays" | head -c 60; } > "$OUT/rays/bad.nan.rays"

# ---------------------------------------------------------------------------------------------
section "raycast grid: ${#METHODS[@]} methods x closest/any x ${#SKEYS[@]} scenes x ${#SETS[@]} sets x leaf ${LEAVES[*]}"
for k in "${SKEYS[@]}"; do
    s=${SCENE[$k]}
    for set in "${SETS[@]}"; do
        for m in "${METHODS[@]}"; do
            for l in "${LEAVES[@]}"; do
                for mode in closest any; do
                    extra=()
                    [ "$mode" = any ] && extra=(--any-hit)
                    # validate the closest-hit casts at leaf 4 (agreement counts land in the JSON)
                    [ "$mode" = closest ] && [ "$l" = 4 ] && extra+=(--validate)
                    n="raycast_${k}_${set}_${m}_l${l}_${mode}"
                    runj "$n" raycast --scene "$s" --rays "$OUT/rays/$k.$set.rays" --out "$OUT/hits/$n.hits" \
                        --method "$m" --leaf-size "$l" --repeat 1 --json "${extra[@]}"
                done
            done
        done
    done
done
# the paper's other leaf sizes (2, 3, 8) on the bunny
for set in "${SETS[@]}"; do
    for m in "${METHODS[@]}"; do
        for l in 2 3 8; do
            for mode in closest any; do
                extra=()
                [ "$mode" = any ] && extra=(--any-hit)
                n="raycast_bunny_${set}_${m}_l${l}_${mode}"
                runj "$n" raycast --scene $BUNNY --rays "$OUT/rays/bunny.$set.rays" --out "$OUT/hits/$n.hits" \
                    --method "$m" --leaf-size "$l" --repeat 1 --json "${extra[@]}"
            done
        done
    done
done

section "raycast variants"
for m in "${METHODS[@]}"; do
    for k in bunny terrain; do
        s=${SCENE[$k]}
        for set in diffuse random; do
            r="$OUT/rays/$k.$set.rays"
            n="raycastv_${k}_${set}_${m}"
            runj "${n}_sah_l4"    raycast --scene "$s" --rays "$r" --out "$OUT/hits/${n}_sah_l4.hits"    --method "$m" --leaf-size 4 --leaf-policy sah --repeat 1 --json
            runj "${n}_sah_l16"   raycast --scene "$s" --rays "$r" --out "$OUT/hits/${n}_sah_l16.hits"   --method "$m" --leaf-size 16 --leaf-policy sah --repeat 1 --json
            runj "${n}_g4_l4"     raycast --scene "$s" --rays "$r" --out "$OUT/hits/${n}_g4_l4.hits"     --method "$m" --leaf-size 4 --sah-group 4 --repeat 1 --json
            runj "${n}_g4sah_l8"  raycast --scene "$s" --rays "$r" --out "$OUT/hits/${n}_g4sah_l8.hits"  --method "$m" --leaf-size 8 --sah-group 4 --leaf-policy sah --repeat 1 --json
            runj "${n}_recentre"  raycast --scene "$s" --rays "$r" --out "$OUT/hits/${n}_recentre.hits"  --method "$m" --recentre --repeat 1 --json --validate
            runj "${n}_address"   raycast --scene "$s" --rays "$r" --out "$OUT/hits/${n}_address.hits"   --method "$m" --scene-access address --repeat 1 --json
            runj "${n}_address_any" raycast --scene "$s" --rays "$r" --out "$OUT/hits/${n}_address_any.hits" --method "$m" --scene-access address --any-hit --repeat 1 --json
            runj "${n}_texel"     raycast --scene "$s" --rays "$r" --out "$OUT/hits/${n}_texel.hits"     --method "$m" --scene-access texel --repeat 1 --json
            runj "${n}_batch4k"   raycast --scene "$s" --rays "$r" --out "$OUT/hits/${n}_batch4k.hits"   --method "$m" --batch-rays 4096 --repeat 1 --json
        done
    done
    # other scenes / seeds at leaf 4
    runj "raycastv_dragon_random_${m}"       raycast --scene scenes/dragon.obj --rays "$OUT/rays/dragon.random.rays" --out "$OUT/hits/raycastv_dragon_random_${m}.hits" --method "$m" --repeat 1 --json --validate
    runj "raycastv_buddha_primary_${m}_any"  raycast --scene scenes/buddha.obj --rays "$OUT/rays/buddha.primary.rays" --out "$OUT/hits/raycastv_buddha_primary_${m}_any.hits" --method "$m" --any-hit --repeat 1 --json
    runj "raycastv_bunny_diffseed3_${m}"     raycast --scene $BUNNY --rays "$OUT/rays/bunny.diffuse-seed3.rays" --out "$OUT/hits/raycastv_bunny_diffseed3_${m}.hits" --method "$m" --leaf-size 2 --repeat 1 --json
    runj "raycastv_bunny_randseed11_${m}"    raycast --scene $BUNNY --rays "$OUT/rays/bunny.random-seed11.rays" --out "$OUT/hits/raycastv_bunny_randseed11_${m}.hits" --method "$m" --leaf-size 3 --repeat 1 --json
    runj "raycastv_spheres_primary_${m}_recentre_any" raycast --scene synth:spheres:5k --rays "$OUT/rays/spheres.primary.rays" --out "$OUT/hits/raycastv_spheres_primary_${m}_recentre_any.hits" --method "$m" --recentre --any-hit --repeat 1 --json
done
# --method auto (decision + reasons in JSON and stderr)
for k in bunny terrain spheres; do
    runj "raycastv_${k}_random_auto" raycast --scene "${SCENE[$k]}" --rays "$OUT/rays/$k.random.rays" --out "$OUT/hits/raycastv_${k}_random_auto.hits" --method auto --repeat 1 --json
done
runj raycastv_dragon_random_auto raycast --scene scenes/dragon.obj --rays "$OUT/rays/dragon.random.rays" --out "$OUT/hits/raycastv_dragon_random_auto.hits" --method auto --repeat 1 --json
run  raycastv_bunny_random_auto_text raycast --scene $BUNNY --rays "$OUT/rays/bunny.random.rays" --out "$OUT/hits/raycastv_bunny_random_auto_text.hits" --method auto --repeat 1
# text-mode output (stdout informational; hits compared)
run raycastv_bunny_primary_mt_text raycast --scene $BUNNY --rays "$OUT/rays/bunny.primary.rays" --out "$OUT/hits/raycastv_bunny_primary_mt_text.hits" --repeat 1 --validate
run raycastv_bunny_random_unit_recentre_text raycast --scene $BUNNY --rays "$OUT/rays/bunny.random.rays" --out "$OUT/hits/raycastv_bunny_random_unit_recentre_text.hits" --method unit --recentre --repeat 1
# the driver's ray query peer (slow on lavapipe: 2000 rays)
runj raycastv_bunny_random2k_rayquery       raycast --scene $BUNNY --rays "$OUT/rays/bunny.random2k.rays" --out "$OUT/hits/raycastv_bunny_random2k_rayquery.hits" --peer ray-query --repeat 1 --json --validate
runj raycastv_bunny_random2k_rayquery_any   raycast --scene $BUNNY --rays "$OUT/rays/bunny.random2k.rays" --out "$OUT/hits/raycastv_bunny_random2k_rayquery_any.hits" --peer ray-query --any-hit --repeat 1 --json
runj raycastv_bunny_random2k_mt             raycast --scene $BUNNY --rays "$OUT/rays/bunny.random2k.rays" --out "$OUT/hits/raycastv_bunny_random2k_mt.hits" --repeat 1 --json
# error paths (exit code and message are results too)
run err_raycast_oddlength raycast --scene $BUNNY --rays "$OUT/rays/bad.oddlength.rays" --out "$OUT/hits/err_oddlength.hits" --repeat 1
run err_raycast_nan       raycast --scene $BUNNY --rays "$OUT/rays/bad.nan.rays" --out "$OUT/hits/err_nan.hits" --repeat 1
run err_raycast_leaf0     raycast --scene $BUNNY --rays "$OUT/rays/bunny.random2k.rays" --out "$OUT/hits/err_leaf0.hits" --leaf-size 0 --repeat 1
run err_raycast_leaf17    raycast --scene $BUNNY --rays "$OUT/rays/bunny.random2k.rays" --out "$OUT/hits/err_leaf17.hits" --leaf-size 17 --repeat 1
run err_raycast_noscene   raycast --scene scenes/does-not-exist.obj --rays "$OUT/rays/bunny.random2k.rays" --out "$OUT/hits/err_noscene.hits" --repeat 1
run err_raycast_badmethod raycast --scene $BUNNY --rays "$OUT/rays/bunny.random2k.rays" --out "$OUT/hits/err_badmethod.hits" --method nope --repeat 1
run err_render_not_exr    render --scene $BUNNY --out "$OUT/render/not-an-exr.png" --width 8 --height 8 --spp 1 --quiet
run err_synth_kind        bvh --scene synth:nope:1k --json

# ---------------------------------------------------------------------------------------------
section "render"
R=(--width 64 --height 48 --spp 8 --seed 1 --quiet --checkpoint-secs 0)
for m in "${METHODS[@]}"; do
    run "render_bunny_${m}"            render --scene $BUNNY --out "$OUT/render/bunny_${m}.exr" --method "$m" "${R[@]}"
    run "render_bunny_${m}_general"    render --scene $BUNNY --out "$OUT/render/bunny_${m}_general.exr" --method "$m" --kernel general "${R[@]}"
    run "render_cornell_${m}"          render --scene $CORNELL --out "$OUT/render/cornell_${m}.exr" --method "$m" --env 0 --camera $CORNELL_CAM "${R[@]}"
    run "render_bsdfs_${m}"            render --scene $BSDFS --out "$OUT/render/bsdfs_${m}.exr" --method "$m" --env 0 --camera $BSDFS_CAM "${R[@]}"
done
run render_cornell_mt_general      render --scene $CORNELL --out "$OUT/render/cornell_mt_general.exr" --kernel general --env 0 --camera $CORNELL_CAM "${R[@]}"
run render_bsdfs_unit_general      render --scene $BSDFS --out "$OUT/render/bsdfs_unit_general.exr" --method unit --kernel general --env 0 --camera $BSDFS_CAM "${R[@]}"
run render_bunny_auto              render --scene $BUNNY --out "$OUT/render/bunny_auto.exr" --method auto "${R[@]}"
run render_bunny_mt_seed7_leaf1    render --scene $BUNNY --out "$OUT/render/bunny_mt_seed7_leaf1.exr" --leaf-size 1 --width 64 --height 48 --spp 4 --seed 7 --quiet --checkpoint-secs 0
run render_bunny_quadunit_sah      render --scene $BUNNY --out "$OUT/render/bunny_quadunit_sah.exr" --method quad-unit --leaf-size 8 --leaf-policy sah --sah-group 4 "${R[@]}"
run render_bunny_mt_env_exposure   render --scene $BUNNY --out "$OUT/render/bunny_mt_env_exposure.exr" --env 0.2,0.5,1 --exposure 1.5 --max-depth 4 --rr-depth 1 "${R[@]}"
run render_cornell_mt_submit1ms    render --scene $CORNELL --out "$OUT/render/cornell_mt_submit1ms.exr" --submit-ms 1 --env 0 --camera $CORNELL_CAM "${R[@]}"
run render_cornell_wt_defaultcam   render --scene $CORNELL --out "$OUT/render/cornell_wt_defaultcam.exr" --method watertight --width 48 --height 48 --spp 4 --seed 2 --quiet --checkpoint-secs 0
run render_terrain_mt              render --scene synth:terrain:20k --out "$OUT/render/terrain_mt.exr" --width 48 --height 32 --spp 4 --seed 1 --quiet --checkpoint-secs 0
run render_bsdfs_mt_depth2         render --scene $BSDFS --out "$OUT/render/bsdfs_mt_depth2.exr" --max-depth 2 --env 0.5 --camera $BSDFS_CAM "${R[@]}"

# ---------------------------------------------------------------------------------------------
section "bvh / steps / analyze / spirv"
for k in "${SKEYS[@]}"; do
    s=${SCENE[$k]}
    runj "bvh_${k}_fill"      bvh --scene "$s" --json
    runj "bvh_${k}_sah"       bvh --scene "$s" --leaf-policy sah --leaf-size 4 --leaf-size 16 --json
    runj "bvh_${k}_g4"        bvh --scene "$s" --sah-group 4 --leaf-size 4 --leaf-size 8 --json
    runj "bvh_${k}_threads1"  bvh --scene "$s" --threads 1 --leaf-size 4 --json
    runj "bvh_${k}_threads3"  bvh --scene "$s" --threads 3 --leaf-size 4 --json
    for set in "${SETS[@]}"; do
        runj "steps_${k}_${set}"     steps --scene "$s" --rays "$OUT/rays/$k.$set.rays" --json
        runj "steps_${k}_${set}_gpu" steps --scene "$s" --rays "$OUT/rays/$k.$set.rays" --json --gpu
    done
    runj "steps_${k}_random_l1_sah_gpu" steps --scene "$s" --rays "$OUT/rays/$k.random.rays" --leaf-size 1 --leaf-policy sah --widths 2 --widths 16 --json --gpu --methods mt,quad-unit,f64
    runj "analyze_${k}" analyze --scene "$s" --json
done
run  bvh_bunny_text bvh --scene $BUNNY --leaf-size 4
runj bvh_dragon bvh --scene scenes/dragon.obj --leaf-size 4 --json
runj bvh_cornell bvh --scene $CORNELL --json
run  steps_bunny_random_text steps --scene $BUNNY --rays "$OUT/rays/bunny.random.rays" --gpu
for s in cornell bsdfs dragon buddha; do
    runj "analyze_${s}" analyze --scene "scenes/$s.obj" --json
done
runj analyze_bunny_leaky   analyze --scene $BUNNY --max-leaks-per-million 100000 --json
runj analyze_dragon_leaky  analyze --scene scenes/dragon.obj --max-leaks-per-million 100000 --max-t-ulps 30 --json
runj analyze_bunny_strict  analyze --scene $BUNNY --max-t-ulps 1 --json
run  analyze_bunny_text    analyze --scene $BUNNY
runj spirv spirv --json
run  spirv_text spirv
run  spirv_write spirv --write "$OUT/spirv"

# ---------------------------------------------------------------------------------------------
section "scale / build-bench"
run scale_plan         scale --scenes synth:terrain:20k,synth:spheres:5k,synth:soup:3k --plan-only --out "$OUT/scale/plan"
run scale_plan_address scale --scenes synth:terrain:20k --plan-only --scene-access address --leaf-size 8 --out "$OUT/scale/plan-address"
run scale_cast         scale --scenes synth:terrain:20k,synth:spheres:5k --rays 2000 --repeat 1 --validate 2000 --out "$OUT/scale/cast"
run scale_cast_diffuse scale --scenes synth:spheres:5k --methods mt,watertight --ray-kind diffuse --rays 2000 --repeat 1 --validate 500 --scene-access address --out "$OUT/scale/cast-diffuse"
run build_bench        build-bench --scenes scenes/bunny.obj,synth:terrain:20k,synth:spheres:5k,synth:soup:3k --threads 1,2 --repeat 1 --out "$OUT/build/default"
run build_bench_sah    build-bench --scenes scenes/bunny.obj,synth:spheres:5k --leaf-size 8 --leaf-policy sah --sah-group 4 --threads 2 --repeat 1 --out "$OUT/build/sah-g4"

# ---------------------------------------------------------------------------------------------
section "bench"
B=(--width 64 --height 48 --random-rays 5000 --repeat 1)
run bench_default   bench "${B[@]}" --json-out "$OUT/bench/default.json" --md-out "$OUT/bench/default.md"
run bench_sah_g4    bench "${B[@]}" --leaf-size 8 --leaf-policy sah --sah-group 4 --diffuse-per-hit 2 --seed 3 --json-out "$OUT/bench/sah-g4.json" --md-out "$OUT/bench/sah-g4.md"
# (bench_sah_g4 fails on the baseline: 4999/5000 random rays agree for unit, below bench's 99.99 %;
# kept as a result) and the same settings with another seed that pass:
run bench_sah_g4_seed7 bench "${B[@]}" --leaf-size 8 --leaf-policy sah --sah-group 4 --diffuse-per-hit 2 --json-out "$OUT/bench/sah-g4-seed7.json" --md-out "$OUT/bench/sah-g4-seed7.md"
run bench_multi     bench --scenes scenes/bunny.obj,scenes/cornell.obj,synth:spheres:5k --width 32 --height 24 --random-rays 2000 --diffuse-per-hit 2 --repeat 1 --scene-access address --json-out "$OUT/bench/multi.json" --md-out "$OUT/bench/multi.md"
mkdir -p "$OUT/bench/raysdir"
for set in "${SETS[@]}"; do cp "$OUT/rays/bunny.$set.rays" "$OUT/bench/raysdir/bunny.$set.rays"; done
run bench_raysdir   bench --rays-dir "$OUT/bench/raysdir" --methods mt,quad-unit,f64 --repeat 1 --json-out "$OUT/bench/raysdir.json" --md-out "$OUT/bench/raysdir.md"
run bench_rayquery  bench --methods mt --width 32 --height 24 --diffuse-per-hit 1 --random-rays 1000 --repeat 1 --ray-query on --json-out "$OUT/bench/rayquery.json" --md-out "$OUT/bench/rayquery.md"

# ---------------------------------------------------------------------------------------------
section "bench-render"
run bench_render bench-render --scenes scenes/bunny.obj,scenes/cornell.obj --width 32 --height 24 --spp 2 --repeat 1 --kernels specialised,general --json-out "$OUT/bench-render/bench-render.json" --md-out "$OUT/bench-render/bench-render.md"
run bench_render_bsdfs bench-render --scenes scenes/bsdfs.obj --methods mt,watertight --width 24 --height 16 --spp 2 --max-depth 4 --leaf-size 8 --repeat 1 --json-out "$OUT/bench-render/bsdfs.json" --md-out "$OUT/bench-render/bsdfs.md"

# ---------------------------------------------------------------------------------------------
section "study / accuracy / profile"
run study_smoke     study --preset smoke --out "$OUT/study/smoke"
run study_smoke_all study --preset smoke --methods mt,unit,quad-mt,quad-unit,watertight,baldwin-weber,f64 --leaf-sizes 2,8 --sah-group 4 --out "$OUT/study/smoke-all"
run accuracy_smoke  accuracy --preset smoke --out "$OUT/accuracy/smoke"
run accuracy_smoke_all accuracy --preset smoke --methods mt,unit,quad-mt,quad-unit,watertight,baldwin-weber,f64 --leaf-sizes 1,4 --out "$OUT/accuracy/smoke-all"
run profile_bunny   profile --scene $BUNNY --width 64 --height 48 --diffuse-per-hit 1 --random-rays 2000 --repeat 1 --no-threads --workgroup-sizes 32,64 --out "$OUT/profile/bunny"
run profile_terrain profile --scene synth:terrain:20k --methods mt,quad-unit --leaf-size 8 --width 48 --height 32 --diffuse-per-hit 1 --random-rays 1000 --repeat 1 --no-threads --sweep-set primary --workgroup-sizes 64 --out "$OUT/profile/terrain"

# ---------------------------------------------------------------------------------------------
date -u +%Y-%m-%dT%H:%M:%SZ > "$OUT/meta/finished"
T=$(echo "$(date +%s.%N) - $T0" | bc -l)
printf '%.0f\n' "$T" > "$OUT/meta/wall_seconds"
# Anything the commands wrote into the source tree would be a bug in the capture; record it.
section "done: $NCMD commands, $NFAIL with non-zero exit, $(printf '%.0f' "$T") s wall -> $OUT"
exit 0
