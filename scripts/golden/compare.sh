#!/usr/bin/env bash
# compare.sh DIR_A DIR_B [--strict-text] [--show N]
#
# Compares two capture directories made by capture.sh. Prints only what differs (one line per
# file, with a short description and up to N (default 3) detail lines), then a count of compared
# files per kind and a summary line.
#
#   commands.txt           every command's exit code and command line (must match)
#   *.hits *.rays *.exr    sha256 (bit for bit); .hits/.rays report how many records differ
#   *.png                  sha256, except PNGs whose pixels plot timings (excluded, counted)
#   *.json                 jq: volatile keys removed recursively (VOLATILE_JSON below), capture
#                          paths replaced by <OUT>, keys sorted; differing leaf paths reported
#   *.csv                  volatile columns dropped by header name (normalize.py CSV_VOLATILE)
#   *.md                   volatile table columns dropped by header name, timing numbers/dates
#                          masked in prose, the timing-derived "claims" section dropped
#   rows.jsonl             each row without its timing figures and its source's date, commit
#                          and host load (normalize.py norm_rows)
#   other files (spirv/*.spvasm, ...)  exact, after <OUT> substitution
#   log/*.stdout|stderr    text with timing numbers masked: INFORMATIONAL (does not fail the
#                          comparison) unless --strict-text
#
# Exit status: 0 iff nothing but informational text differs; 1 if anything else differs;
# 2 on usage errors or if nothing at all was compared.
set -u
export LC_ALL=C

HERE=$(cd "$(dirname "$(readlink -f "$0")")" && pwd)
NORM="$HERE/normalize.py"
STRICT_TEXT=0
SHOW=3
ARGS=()
while [ $# -gt 0 ]; do
    case "$1" in
        --strict-text) STRICT_TEXT=1 ;;
        --show) SHOW=$2; shift ;;
        -h|--help) sed -n '2,25p' "$0"; exit 0 ;;
        *) ARGS+=("$1") ;;
    esac
    shift
done
if [ ${#ARGS[@]} -ne 2 ]; then
    echo "usage: $0 DIR_A DIR_B [--strict-text] [--show N]" >&2
    exit 2
fi
A=$(readlink -f "${ARGS[0]}")
B=$(readlink -f "${ARGS[1]}")
for d in "$A" "$B"; do
    if [ ! -f "$d/commands.txt" ]; then
        echo "compare.sh: $d has no commands.txt: not a capture directory" >&2
        exit 2
    fi
done
command -v jq >/dev/null || { echo "compare.sh: jq is required (apt-get install -y jq)" >&2; exit 2; }
command -v python3 >/dev/null || { echo "compare.sh: python3 is required" >&2; exit 2; }

TMP=$(mktemp -d /tmp/golden-compare.XXXXXX)
trap 'rm -rf "$TMP"' EXIT

# Keys removed anywhere in a JSON document (whole subtree): GPU/CPU timings, rates derived from
# them, memory use, dates, commit ids, host load, shader-clock ticks (and the heat-map scale
# derived from them), and the render's submit count (its pass size is sized to --submit-ms of
# wall-clock time; the image does not depend on it).
VOLATILE_JSON='^(kernel_ms|kernel_ms_min|kernel_ms_max|mrays_per_s|mrays_per_s_min|mrays_per_s_max|embree_mrays_per_s|mrays_per_second|samples_per_second|msamples_per_s|ms|seconds|gpu_ms|wall_ms|build_ms|epo_ms|blas_build_ms|tlas_build_ms|mtris_per_s|bvh_mtris_per_s|load_s|bvh_s|upload_s|peak_rss_bytes|budget_bytes|date|commit|host_load_before|host_load_after|load_1m|build_seconds|convert_seconds|ticks|heat_scale|submits|mrays_median|mrays_min|mrays_max|median_s|min_s|max_s)$'
# PNGs that plot timings (study plots, accuracy frontier plots) or shader-clock ticks (profile
# heat maps): their pixels differ from run to run.
EXCLUDED_PNG='^(study/.*/study-[^/]*\.png|accuracy/.*/frontier_[^/]*\.png|profile/.*/heatmap-[^/]*\.png)$'

outs_of() { # the capture's recorded and actual paths, ':'-separated, for <OUT> substitution
    local d=$1 rec=""
    [ -f "$d/meta/outdir" ] && rec=$(cat "$d/meta/outdir")
    printf '%s:%s' "$rec" "$d"
}
OUTS_A=$(outs_of "$A")
OUTS_B=$(outs_of "$B")
json_outs() { printf '%s' "$1" | tr ':' '\n' | awk 'length>0' | jq -R . | jq -s 'sort_by(-length)'; }
JOUTS_A=$(json_outs "$OUTS_A")
JOUTS_B=$(json_outs "$OUTS_B")

NDIFF=0
NINFO=0
declare -A COUNT=()
declare -A COUNTDIFF=()
inc() { COUNT[$1]=$(( ${COUNT[$1]:-0} + 1 )); }
report() { # report KIND PATH DESCRIPTION [detail lines on stdin]
    local kind=$1 path=$2 desc=$3
    NDIFF=$((NDIFF + 1))
    COUNTDIFF[$kind]=$(( ${COUNTDIFF[$kind]:-0} + 1 ))
    echo "DIFF  [$kind] $path: $desc"
}
info() {
    NINFO=$((NINFO + 1))
    echo "INFO  [$1] $2: $3"
}
details() { head -n "$SHOW" | cut -c1-240 | sed 's/^/        /'; }

# ---------------------------------------------------------------------------------------------
# capture provenance
for side in A B; do
    d=$A; [ $side = B ] && d=$B
    echo "$side: $d (binary $(cat "$d/meta/bin" 2>/dev/null || echo '?'), sha256 $(cut -c1-12 "$d/meta/bin.sha256" 2>/dev/null || echo '?'), $(wc -l < "$d/commands.txt") commands, $(cat "$d/meta/wall_seconds" 2>/dev/null || echo '?') s)"
done
for d in "$A" "$B"; do
    if [ ! -f "$d/meta/finished" ]; then
        report capture "$d" "capture did not finish (no meta/finished): it cannot prove equality"
    fi
done
if [ -f "$A/meta/inputs.sha256" ] && [ -f "$B/meta/inputs.sha256" ] && \
   ! cmp -s "$A/meta/inputs.sha256" "$B/meta/inputs.sha256"; then
    echo "WARN  input scenes differ between the captures (meta/inputs.sha256):"
    diff "$A/meta/inputs.sha256" "$B/meta/inputs.sha256" | grep '^[<>]' | details
fi

# ---------------------------------------------------------------------------------------------
# commands and exit codes
declare -A RC_A=() CL_A=() RC_B=() CL_B=()
while IFS=$'\t' read -r n rc cl; do RC_A[$n]=$rc; CL_A[$n]=$cl; done < "$A/commands.txt"
while IFS=$'\t' read -r n rc cl; do RC_B[$n]=$rc; CL_B[$n]=$cl; done < "$B/commands.txt"
for n in $(printf '%s\n' "${!RC_A[@]}" "${!RC_B[@]}" | sort -u); do
    inc command
    if [ -z "${RC_A[$n]+x}" ]; then report command "$n" "only in B (rc ${RC_B[$n]}): ${CL_B[$n]}"; continue; fi
    if [ -z "${RC_B[$n]+x}" ]; then report command "$n" "only in A (rc ${RC_A[$n]}): ${CL_A[$n]}"; continue; fi
    if [ "${RC_A[$n]}" != "${RC_B[$n]}" ]; then
        report command "$n" "exit code ${RC_A[$n]} -> ${RC_B[$n]}"
        for side in A B; do
            d=$A; [ $side = B ] && d=$B
            [ -s "$d/log/$n.stderr" ] && tail -n 1 "$d/log/$n.stderr" | sed "s/^/$side: /" | details
        done
    fi
    if [ "${CL_A[$n]}" != "${CL_B[$n]}" ]; then
        report command "$n" "command line differs"
        printf 'A: %s\nB: %s\n' "${CL_A[$n]}" "${CL_B[$n]}" | details
    fi
done

# ---------------------------------------------------------------------------------------------
# file inventory
list_files() { (cd "$1" && find . -type f ! -path './meta/*' ! -name commands.txt ! -name timings.txt | sed 's#^\./##' | sort); }
list_files "$A" > "$TMP/files.a"
list_files "$B" > "$TMP/files.b"
comm -23 "$TMP/files.a" "$TMP/files.b" > "$TMP/only.a"
comm -13 "$TMP/files.a" "$TMP/files.b" > "$TMP/only.b"
comm -12 "$TMP/files.a" "$TMP/files.b" > "$TMP/both"
while read -r f; do report missing "$f" "only in A"; done < "$TMP/only.a"
while read -r f; do report missing "$f" "only in B"; done < "$TMP/only.b"

: > "$TMP/l.sha"; : > "$TMP/l.json"; : > "$TMP/l.csv"; : > "$TMP/l.md"; : > "$TMP/l.rows"; : > "$TMP/l.text"; : > "$TMP/l.exact"; : > "$TMP/l.excluded"
while read -r f; do
    case "$f" in
        log/*.stdout|log/*.stderr) echo "$f" >> "$TMP/l.text" ;;
        *.hits|*.rays|*.exr) echo "$f" >> "$TMP/l.sha" ;;
        *.png) if [[ $f =~ $EXCLUDED_PNG ]]; then echo "$f" >> "$TMP/l.excluded"; else echo "$f" >> "$TMP/l.sha"; fi ;;
        *.json) echo "$f" >> "$TMP/l.json" ;;
        *.csv) echo "$f" >> "$TMP/l.csv" ;;
        *.md) echo "$f" >> "$TMP/l.md" ;;
        rows.jsonl|*/rows.jsonl) echo "$f" >> "$TMP/l.rows" ;;
        *) echo "$f" >> "$TMP/l.exact" ;;
    esac
done < "$TMP/both"

# ---------------------------------------------------------------------------------------------
# binary outputs: sha256
record_diff() { # record_diff FILE_A FILE_B RECORD_BYTES -> "N of M records differ, first at i"
    python3 - "$1" "$2" "$3" <<'EOF'
import sys
a = open(sys.argv[1], 'rb').read(); b = open(sys.argv[2], 'rb').read(); r = int(sys.argv[3])
if len(a) != len(b):
    print(f"sizes differ: {len(a)} vs {len(b)} bytes ({len(a)/r:g} vs {len(b)/r:g} records)")
    sys.exit()
n = len(a) // r
bad = [i for i in range(n) if a[i*r:(i+1)*r] != b[i*r:(i+1)*r]]
print(f"{len(bad)} of {n} records differ, first at record {bad[0] if bad else '-'}")
EOF
}
if [ -s "$TMP/l.sha" ]; then
    (cd "$A" && xargs -d '\n' sha256sum < "$TMP/l.sha") > "$TMP/sha.a"
    (cd "$B" && xargs -d '\n' sha256sum < "$TMP/l.sha") > "$TMP/sha.b"
    paste -d' ' <(cut -c1-64 "$TMP/sha.a") <(cut -c1-64 "$TMP/sha.b") "$TMP/l.sha" > "$TMP/sha.ab"
    # sha256sum keeps input order; check that the file columns line up
    if ! diff -q <(cut -c67- "$TMP/sha.a") "$TMP/l.sha" >/dev/null || ! diff -q <(cut -c67- "$TMP/sha.b") "$TMP/l.sha" >/dev/null; then
        echo "compare.sh: internal error: sha256 lists out of order" >&2; exit 2
    fi
    while read -r ha hb f; do
        ext=${f##*.}
        inc "$ext"
        if [ "$ha" != "$hb" ]; then
            case "$ext" in
                hits) report hits "$f" "$(record_diff "$A/$f" "$B/$f" 16)" ;;
                rays) report rays "$f" "$(record_diff "$A/$f" "$B/$f" 32)" ;;
                *) report "$ext" "$f" "sha256 ${ha:0:12} -> ${hb:0:12} ($(stat -c %s "$A/$f") -> $(stat -c %s "$B/$f") bytes)" ;;
            esac
        fi
    done < "$TMP/sha.ab"
fi
while read -r f; do [ -n "$f" ] && inc "png-excluded"; done < "$TMP/l.excluded"

# ---------------------------------------------------------------------------------------------
# JSON: jq, volatile keys stripped
# `epo` (end-point overlap, a sum over all nodes) is summed in a thread-dependent order by the
# baseline, so its last bits vary from run to run: it is compared at 12 significant digits.
JQ_NORM='def outsub: reduce $outs[] as $o (.; split($o) | join("<OUT>"));
def sig12: if type != "number" or . == 0 then . else
  ((if . < 0 then -. else . end) | log10 | floor) as $e
  | "\((. / pow(10; $e - 11)) | round)e\($e - 11)" end;
def norm: walk(if type == "object" then
      with_entries(select(.key | test($re) | not) | if .key == "epo" then .value |= sig12 else . end)
      | to_entries | sort_by(.key) | from_entries
    elif type == "string" then outsub else . end);'
JQ_FLAT='tostream | select(length == 2) | "\(.[0] | map(tostring) | join(".")) = \(.[1] | tojson)"'
json_norm_one() { # json_norm_one FILE OUTS_JSON -> one line on stdout (or the raw text, marked)
    if [ ! -s "$1" ]; then echo "<empty>"; return 0; fi
    local out
    if out=$(jq -c --arg re "$VOLATILE_JSON" --argjson outs "$2" "$JQ_NORM norm" "$1" 2>/dev/null); then
        printf '%s\n' "$(printf '%s' "$out" | tr '\n' ' ')"
    else
        printf '<not valid JSON> %s\n' "$(tr '\n\t' '  ' < "$1")"
    fi
}
json_batch() { # json_batch DIR OUTS_JSON LIST DEST: "relpath<TAB>normalised JSON" per file
    local d=$1 outs=$2 list=$3 dest=$4 f
    (cd "$d" && xargs -d '\n' jq -r --arg re "$VOLATILE_JSON" --argjson outs "$outs" \
        "$JQ_NORM \"\\(input_filename)\\t\\(norm | tojson)\"" < "$list" 2>/dev/null) > "$dest.tmp"
    # jq stops at the first file that is not JSON, and prints nothing for an empty file, and a
    # file could hold several documents: redo every such file one by one
    declare -A seen=()
    cut -f1 "$dest.tmp" | sort | uniq -c | awk '$1 == 1 {print $2}' > "$dest.once"
    while read -r f; do seen[$f]=1; done < "$dest.once"
    awk -F'\t' 'NR==FNR {ok[$1]=1; next} ($1 in ok)' "$dest.once" "$dest.tmp" > "$dest"
    while read -r f; do
        [ -n "$f" ] || continue
        [ -n "${seen[$f]+x}" ] || printf '%s\t%s\n' "$f" "$(json_norm_one "$d/$f" "$outs")" >> "$dest"
    done < "$list"
}
if [ -s "$TMP/l.json" ]; then
    json_batch "$A" "$JOUTS_A" "$TMP/l.json" "$TMP/json.a"
    json_batch "$B" "$JOUTS_B" "$TMP/l.json" "$TMP/json.b"
    declare -A JA=() JB=()
    while IFS=$'\t' read -r f doc; do JA[$f]=$doc; done < "$TMP/json.a"
    while IFS=$'\t' read -r f doc; do JB[$f]=$doc; done < "$TMP/json.b"
fi
while read -r f; do
    [ -n "$f" ] || continue
    inc json
    if [ -z "${JA[$f]+x}" ] || [ -z "${JB[$f]+x}" ]; then
        report json "$f" "internal error: not normalised"; continue
    fi
    if [ "${JA[$f]}" != "${JB[$f]}" ]; then
        printf '%s\n' "${JA[$f]}" > "$TMP/ja"; printf '%s\n' "${JB[$f]}" > "$TMP/jb"
        if jq -e . "$TMP/ja" >/dev/null 2>&1 && jq -e . "$TMP/jb" >/dev/null 2>&1; then
            jq -r "$JQ_FLAT" "$TMP/ja" > "$TMP/fa"; jq -r "$JQ_FLAT" "$TMP/jb" > "$TMP/fb"
            nd=$(diff "$TMP/fa" "$TMP/fb" | grep '^[<>]' | cut -c3- | sed 's/ = .*//' | sort -u | wc -l)
            report json "$f" "$nd leaf values differ (volatile keys stripped)"
            diff "$TMP/fa" "$TMP/fb" | grep '^[<>]' | sed 's/^</A:/; s/^>/B:/' | details
        else
            report json "$f" "differs (not both valid JSON)"
            diff "$TMP/ja" "$TMP/jb" | grep '^[<>]' | details
        fi
    fi
done < "$TMP/l.json"

# ---------------------------------------------------------------------------------------------
# CSV / Markdown / text: normalize.py, one process per side and kind
norm_batch() { # norm_batch MODE LIST
    local mode=$1 list=$2 side d outs args
    for side in a b; do
        if [ $side = a ]; then d=$A; outs=$OUTS_A; else d=$B; outs=$OUTS_B; fi
        args=()
        while read -r f; do
            [ -n "$f" ] || continue
            mkdir -p "$TMP/n$side/$(dirname "$f")"
            args+=("$d/$f" "$TMP/n$side/$f")
        done < "$list"
        [ ${#args[@]} -gt 0 ] && python3 "$NORM" "$mode" "$outs" "${args[@]}"
    done
}
compare_normalized() { # compare_normalized KIND LIST INFORMATIONAL
    local kind=$1 list=$2 informational=$3 f nd
    while read -r f; do
        [ -n "$f" ] || continue
        inc "$kind"
        if ! cmp -s "$TMP/na/$f" "$TMP/nb/$f"; then
            nd=$(diff "$TMP/na/$f" "$TMP/nb/$f" | grep -c '^[<>]')
            if [ "$informational" = 1 ]; then
                info "$kind" "$f" "$nd lines differ after masking timings"
            else
                report "$kind" "$f" "$nd lines differ after normalisation"
            fi
            diff "$TMP/na/$f" "$TMP/nb/$f" | grep '^[<>]' | sed 's/^</A:/; s/^>/B:/' | details
        fi
    done < "$list"
}
norm_batch csv "$TMP/l.csv";  compare_normalized csv "$TMP/l.csv" 0
norm_batch md "$TMP/l.md";    compare_normalized md "$TMP/l.md" 0
norm_batch rows "$TMP/l.rows"; compare_normalized rows "$TMP/l.rows" 0
norm_batch text "$TMP/l.text"
if [ $STRICT_TEXT = 1 ]; then compare_normalized text "$TMP/l.text" 0; else compare_normalized text "$TMP/l.text" 1; fi

# other files (SPIR-V disassembly, ...): exact after <OUT> substitution
while read -r f; do
    [ -n "$f" ] || continue
    inc other
    if ! cmp -s "$A/$f" "$B/$f"; then
        sa=$(sed "s#$A#<OUT>#g" "$A/$f" | sha256sum); sb=$(sed "s#$B#<OUT>#g" "$B/$f" | sha256sum)
        if [ "$sa" != "$sb" ]; then
            report other "$f" "differs"
            diff <(sed "s#$A#<OUT>#g" "$A/$f") <(sed "s#$B#<OUT>#g" "$B/$f") | grep '^[<>]' | details
        fi
    fi
done < "$TMP/l.exact"

# ---------------------------------------------------------------------------------------------
TOTAL=0
line=""
for k in command hits rays exr png json csv md rows other text png-excluded; do
    c=${COUNT[$k]:-0}
    [ "$k" != png-excluded ] && [ "$k" != command ] && TOTAL=$((TOTAL + c))
    d=${COUNTDIFF[$k]:-0}
    case $k in
        command) line+="exit codes: $c commands";;
        text) line+=", text (stdout/stderr, $([ $STRICT_TEXT = 1 ] && echo strict || echo informational)): $c";;
        png-excluded) line+=", png excluded (timing plots/heat maps): $c";;
        *) line+=", $k: $c";;
    esac
    [ "$d" -gt 0 ] && line+=" ($d differ)"
done
echo "compared: $line"
echo "files only in one capture: $(wc -l < "$TMP/only.a") in A, $(wc -l < "$TMP/only.b") in B"
if [ "$TOTAL" -eq 0 ] || [ "${COUNT[command]:-0}" -eq 0 ]; then
    echo "RESULT: NOTHING COMPARED (empty or broken capture?)"
    exit 2
fi
if [ $NDIFF -eq 0 ]; then
    echo "RESULT: SAME: no differences ($NINFO informational text diffs)"
    exit 0
fi
echo "RESULT: DIFFERENT: $NDIFF differences ($NINFO informational text diffs)"
exit 1
