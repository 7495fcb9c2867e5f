#!/usr/bin/env bash
# selftest.sh CAPTURE_DIR: checks that compare.sh detects real differences and ignores volatile
# ones, by mutating a copy of CAPTURE_DIR. Prints PASS/FAIL per case; exits non-zero on a FAIL.
set -u
SRC=$(readlink -f "$1")
HERE=$(cd "$(dirname "$(readlink -f "$0")")" && pwd)
W=$(mktemp -d /tmp/golden-selftest.XXXXXX)
trap 'rm -rf "$W"' EXIT
FAILS=0

fresh() { rm -rf "$W/m"; cp -a "$SRC" "$W/m"; chmod -R u+w "$W/m"; }
expect() { # expect NAME WANT_RC GREP_PATTERN
    local name=$1 want=$2 pat=$3 rc
    "$HERE/compare.sh" "$SRC" "$W/m" > "$W/out" 2>&1
    rc=$?
    if [ "$rc" = "$want" ] && { [ -z "$pat" ] || grep -q -- "$pat" "$W/out"; }; then
        echo "PASS  $name (rc $rc)"
    else
        echo "FAIL  $name: rc $rc (want $want), pattern '$pat'"; sed 's/^/      /' "$W/out" | head -20
        FAILS=$((FAILS + 1))
    fi
}
first() { (cd "$W/m" && ls $1 2>/dev/null | head -1); }
jqset() { # jqset FILE FILTER
    jq "$2" "$W/m/$1" > "$W/t" && cp "$W/t" "$W/m/$1"
}

fresh; expect "unchanged copy" 0 "RESULT: SAME"

fresh; f=$(first 'hits/raycast_bunny_random_mt_l4_closest.hits')
printf '\x01' | dd of="$W/m/$f" bs=1 seek=4000 conv=notrunc status=none
expect "one byte of a .hits file" 1 "DIFF  \[hits\] $f: 1 of 20000 records differ, first at record 250"

fresh; f=render/bunny_mt.exr; printf '\x00' | dd of="$W/m/$f" bs=1 seek=3000 conv=notrunc status=none
expect "one byte of an .exr" 1 "DIFF  \[exr\] $f"

fresh; f=render/cornell_unit.png; truncate -s -1 "$W/m/$f"
expect "a truncated .png" 1 "DIFF  \[png\] $f"

fresh; f=rays/terrain.diffuse.rays; printf '\x7f' | dd of="$W/m/$f" bs=1 seek=33 conv=notrunc status=none
expect "one byte of a .rays file" 1 "DIFF  \[rays\] $f"

fresh; rm "$W/m/hits/raycast_spheres_primary_f64_l16_any.hits"
expect "a missing hit file" 1 "only in A"

fresh; jqset json/raycast_bunny_random_unit_l4_closest.json '.hits += 1'
expect "JSON hit count" 1 "raycast_bunny_random_unit_l4_closest.json: 1 leaf values differ"

fresh; jqset json/raycast_bunny_random_unit_l4_closest.json '.validation.agreement = 0.99995'
expect "JSON validation agreement" 1 "validation.agreement"

fresh; jqset json/raycast_bunny_random_unit_l4_closest.json '.kernel_ms *= 3 | .mrays_per_s /= 3 | .kernel_ms_min = 0'
expect "JSON timing fields only (ignored)" 0 "RESULT: SAME"

fresh; jqset json/bvh_bunny_fill.json '.[0].stats.epo *= (1 + 1e-15) | .[0].stats.build_ms = 1 | .[0].stats.epo_ms = 2'
expect "JSON epo last-bits noise + build times (ignored)" 0 "RESULT: SAME"

fresh; jqset json/bvh_bunny_fill.json '.[0].stats.epo *= (1 + 1e-9)'
expect "JSON epo changed at 1e-9" 1 "stats.epo"

fresh; jqset json/bvh_bunny_fill.json '.[0].stats.sah_cost += 1e-12'
expect "JSON sah_cost last digits" 1 "stats.sah_cost"

fresh; jqset render/bunny_unit.json '.gpu_ms = 1 | .samples_per_second = 2 | .mrays_per_second = 3 | .wall_ms = 4 | .submits = 99 | .build_ms = 5'
expect "render JSON timings (ignored)" 0 "RESULT: SAME"

fresh; jqset render/bunny_unit.json '.closest_rays += 1'
expect "render JSON ray count" 1 "closest_rays"

fresh; jqset study/smoke/study.json '.rows[3].sets[1].traversal.nodes.max += 1'
expect "study JSON traversal count" 1 "traversal.nodes.max"

fresh; f=study/smoke/study.csv
awk -F, 'BEGIN{OFS=","} NR==2 {$7 = $7 + 1} {print}' "$W/m/$f" > "$W/t" && cp "$W/t" "$W/m/$f"
expect "CSV sah_cost column" 1 "DIFF  \[csv\] $f"

fresh; f=study/smoke/study.csv
awk -F, 'BEGIN{OFS=","} NR==2 {$10 = 99; $14 = 1.5} {print}' "$W/m/$f" > "$W/t" && cp "$W/t" "$W/m/$f"
expect "CSV render_s / msamples_per_s columns (ignored)" 0 "RESULT: SAME"

fresh; f=build/default/build.csv
awk -F, 'BEGIN{OFS=","} NR==3 {$11 = $11 + 1} {print}' "$W/m/$f" > "$W/t" && cp "$W/t" "$W/m/$f"
expect "CSV build nodes column" 1 "DIFF  \[csv\] $f"

fresh; f=bench/default.md
sed -i '0,/| 100.0000 |/s/| 100.0000 |/| 99.9900 |/' "$W/m/$f"
expect "MD agreement cell" 1 "DIFF  \[md\] $f"

fresh; f=bench/default.md
sed -i -E '0,/^\| bunny \| 3072 \| primary \| mt \|/s/^(\| bunny \| 3072 \| primary \| mt \| 4 \| [0-9.]+ \| )[0-9.]+/\19999.9/' "$W/m/$f"
expect "MD kernel ms cell (ignored)" 0 "RESULT: SAME"

fresh; f=spirv/raycast.mt.closest.spvasm; [ -f "$W/m/$f" ] || f=$(first 'spirv/*.spvasm')
echo "; extra" >> "$W/m/$f"
expect "SPIR-V disassembly" 1 "DIFF  \[other\] $f"

fresh; awk -F'\t' 'BEGIN{OFS="\t"} $1=="err_raycast_leaf0" {$2=0} {print}' "$W/m/commands.txt" > "$W/t" && cp "$W/t" "$W/m/commands.txt"
expect "an exit code" 1 "DIFF  \[command\] err_raycast_leaf0: exit code 1 -> 0"

fresh; f=log/raycastv_bunny_primary_mt_text.stdout
sed -i 's/(4897 hit)/(4898 hit)/' "$W/m/$f"
expect "stdout text (informational only)" 0 "INFO  \[text\] $f"

fresh; rm -rf "$W/m"/{hits,json,render,rays,study,accuracy,bench,build,scale,profile,bench-render,spirv,log}; mkdir "$W/m/log"
expect "a capture with no files" 2 "RESULT: NOTHING COMPARED"

echo
[ $FAILS -eq 0 ] && echo "selftest: all cases PASS" || echo "selftest: $FAILS FAILED"
exit $FAILS
