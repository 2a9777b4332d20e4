#!/usr/bin/env bash
# Issue 7's oversized and degenerate inputs, each run through `whitted
# render` and timed: prints one Markdown row per case (class, case, exit
# code, what happened, median wall time of RUNS runs) for
# docs/reliability.md. Every case must answer (render or exit 2) without
# a panic, an abort or a file left behind; the script says FAIL otherwise.
#
#   scripts/hostile-sizes.sh [WHITTED] [RUNS]
#
# WHITTED defaults to target/release/whitted (build it with
# `cargo build --release`); RUNS to 3. Renders use --backend cpu.
set -euo pipefail

W=${1:-target/release/whitted}
RUNS=${2:-3}
W=$(realpath "$W")
ROOT=$(cd "$(dirname "$0")/.." && pwd)
DIR=$(mktemp -d)
trap 'rm -rf "$DIR"' EXIT
cd "$DIR"

view() { # resolution
    printf 'b 0.1 0.1 0.2\nv\nfrom 0 -6 2\nat 0 0 0\nup 0 0 1\nangle 40\nhither 0.01\nresolution %s\nl 4 -3 5\n' "$1"
}
opaque='f 1 0.5 0.3 0.8 0.2 30 0 1'
glass='f 0.9 0.9 0.9 0 0.2 30 0.8 1.5'
repeat() { # n line
    awk -v n="$1" -v l="$2" 'BEGIN { for (i = 0; i < n; i++) print l }'
}

{ view "512 512"; echo "$opaque"; repeat 10000 's 0 0 0 1'; } >same-10k.nff
{ view "512 512"; echo "$opaque"; repeat 30000 's 0 0 0 1'; } >same-30k.nff
{ view "512 512"; echo "$opaque"; repeat 100000 's 0 0 0 1'; } >same-100k.nff
{ view "512 512"; echo "$opaque"; repeat 3000000 's 0 0 0 1'; } >same-3M.nff
{ view "64 64"; echo "$glass"; repeat 10000 's 0 0 0 1'; } >glass-10k.nff
{ view "512 512"; echo "$opaque"; echo 's 0 0 0 1e-120'; } >tiny-1e-120.nff
{ view "512 512"; echo "$opaque"; echo 's 0 0 0 5e-324'; } >tiny-5e-324.nff
{ view "512 512"; echo "$opaque"; awk 'BEGIN { for (i = 0; i < 1000; i++) printf "s %g 0 0 1e-120\n", i * 1e-3 }'; } >tiny-line-1k.nff
{ view "512 512"; echo "$opaque"; repeat 100000 's 0.5 0.5 0.5 1e-300'; } >point-100k.nff
{ view "512 512"; echo "$opaque"; repeat 100000 's 0.5 0.5 0.5 1e-5'; } >point-100k-small.nff
{ view "512 512"; echo "$opaque"; awk 'BEGIN { for (i = 0; i < 100000; i++) printf "s 0.5 0.5 0.5 %g\n", 1e-5 * (1 + i * 1e-6) }'; } >point-100k-nested.nff
"$W" generate --count 1000000 -o spheres-1m.nff
SHOW=$ROOT/scenes/showcase.toml

echo "| class | case | exit | outcome | seconds (median of $RUNS) |"
echo "|-------|------|------|---------|---------|"
fail=0
case_() { # class label scene args...
    local class=$1 label=$2 scene=$3
    shift 3
    local times=() code out err
    for _ in $(seq "$RUNS"); do
        rm -f out.png st.json
        local t0 t1
        t0=$(date +%s.%N)
        set +e
        "$W" render -q --backend cpu "$scene" -o out.png --stats st.json "$@" 2>err.txt
        code=$?
        set -e
        t1=$(date +%s.%N)
        times+=("$(echo "$t1 - $t0" | bc)")
    done
    err=$(head -c 300 err.txt | tr '\n' ' ')
    if [ "$code" = 0 ]; then
        out=$(python3 -c "import json; j=json.load(open('st.json')); g=j['grid']; \
print('rendered %dx%d; grid %s, %d refs%s' % (j['width'], j['height'], 'x'.join(map(str, g['cells'])), g['refs'], \
      ', %d copies dropped' % g['duplicates'] if g.get('duplicates') else ''))")
    elif [ "$code" = 2 ]; then
        out="refused: ${err#error: }"
        if [ -e out.png ] || [ -e st.json ] || ls .whitted-* >/dev/null 2>&1; then
            out="FAIL (file left behind) $out"
            fail=1
        fi
    else
        out="FAIL: $err"
        fail=1
    fi
    if grep -q panicked err.txt; then
        out="FAIL (panic) $out"
        fail=1
    fi
    local med
    med=$(printf '%s\n' "${times[@]}" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
    printf '| %s | %s | %s | %s | %.2f |\n' "$class" "$label" "$code" "$out" "$med"
}

case_ "overlapping primitives" "10 k copies of one sphere, 512²" same-10k.nff
case_ "overlapping primitives" "30 k copies" same-30k.nff
case_ "overlapping primitives" "100 k copies" same-100k.nff
case_ "overlapping primitives" "3 M copies (30 MB file)" same-3M.nff
case_ "overlapping primitives" "10 k transparent copies (kept), 64²" glass-10k.nff
case_ "degenerate extents" "radius 1e-120" tiny-1e-120.nff
case_ "degenerate extents" "radius 5e-324" tiny-5e-324.nff
case_ "degenerate extents" "1000 spheres of radius 1e-120 on a line" tiny-line-1k.nff
case_ "degenerate extents" "100 k spheres of radius 1e-300 at one point" point-100k.nff
case_ "degenerate extents" "100 k spheres of radius 1e-5 at one point" point-100k-small.nff
case_ "degenerate extents" "100 k spheres at one centre, 10 k distinct radii" point-100k-nested.nff
case_ "explicit grid" "--grid 1023x1023x1023" "$SHOW" --grid 1023x1023x1023
case_ "explicit grid" "--grid 1023x1023x16" "$SHOW" --grid 1023x1023x16
case_ "image size" "--width 65536 --height 65536" "$SHOW" --width 65536 --height 65536
case_ "image size" "… --sampling corners --spp 4096" "$SHOW" --width 65536 --height 65536 --sampling corners --spp 4096
case_ "image size" "--width 65536 --height 16" "$SHOW" --width 65536 --height 16
case_ "samples" "--spp 4096, 32×24" "$SHOW" --spp 4096 --width 32 --height 24
case_ "depth" "--max-depth 16 --min-weight 0, 160×120" "$SHOW" --max-depth 16 --min-weight 0 --width 160 --height 120
case_ "large scene (reference)" "1 M random spheres, 512×384" spheres-1m.nff --width 512 --height 384
exit $fail
