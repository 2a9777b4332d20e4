#!/usr/bin/env bash
# Times whitted (CPU mirror) and POV-Ray 3.7 on the same scene, same
# resolution and depth, same machine, alternating runs; prints the medians
# of the wall times and their ratio.
#
#   scripts/povray-compare.sh [SCENE.nff|SCENE.toml] [WIDTH HEIGHT] [RUNS]
#
# Default scene: 20 000 random spheres (whitted generate --count 20000).
# POV-Ray runs as whitted::povray::render runs it: one thread per core
# (+WT), no anti-aliasing (-A), full quality (+Q9), no display, on the scene
# `whitted export` writes (max_trace_level = max depth + 1). How closely
# the two images agree, scene by scene: docs/povray.md.
set -euo pipefail
cd "$(dirname "$0")/.."
command -v povray >/dev/null || { echo "povray is not installed (apt-get install povray)" >&2; exit 2; }
cargo build --release -q
bin=target/release/whitted
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
scene=${1:-}
if [ -z "$scene" ]; then
  scene=$work/spheres.nff
  $bin generate --count 20000 -o "$scene"
fi
w=${2:-1024}; h=${3:-768}; runs=${4:-3}
$bin export "$scene" -o "$work/scene.pov" --width "$w" --height "$h" --max-depth 5
wt=(); pt=()
for _ in $(seq "$runs"); do
  t0=$(date +%s.%N); $bin render "$scene" -q --backend cpu --width "$w" --height "$h" --max-depth 5 -o "$work/w.png"; t1=$(date +%s.%N)
  povray +I"$work/scene.pov" +O"$work/p.png" +W"$w" +H"$h" +WT"$(nproc)" -A +Q9 -UA -D -GA >/dev/null 2>&1; t2=$(date +%s.%N)
  wt+=("$(echo "$t1 - $t0" | bc)"); pt+=("$(echo "$t2 - $t1" | bc)")
done
median() { printf '%s\n' "$@" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
mw=$(median "${wt[@]}"); mp=$(median "${pt[@]}")
echo "scene: $scene  ${w}x${h}  depth 5  runs: $runs  ($(nproc) cores)"
echo "whitted (cpu) wall: ${wt[*]}  median $mw s"
echo "povray 3.7    wall: ${pt[*]}  median $mp s"
echo "ratio (povray / whitted): $(echo "scale=2; $mp / $mw" | bc)"
