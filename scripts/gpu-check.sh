#!/usr/bin/env bash
# The real-GPU check, for a machine with a GPU that cannot build the project
# (no network, no toolchain): run the GPU test binaries, `validate`, `bench`
# and `profile` there and keep every result. docs/profiling.md ("A real GPU:
# NVIDIA H200") holds what it found the first time.
#
# Prepare where the project builds (the test binaries are the test
# profile's, so that their compiled-in paths, CARGO_MANIFEST_DIR and
# CARGO_BIN_EXE_whitted, point into this checkout):
#   cargo build --release && cargo test --all-targets --no-run
#   scripts/gpu-check.sh --pack DIR    # stripped binaries in DIR/bins.tar.xz
# Then, on the GPU machine, in a copy of this checkout with DIR beside it:
#   scripts/gpu-check.sh DIR OUT       # log, tests, CSVs, heat map: 7 files
# (the charts need a TrueType font: fonts-dejavu-core, or WHITTED_FONT,
# which the script points at matplotlib's copy where it finds no other).
# The tests take the
# longest: on an H200 the gpu and probe binaries had not finished after
# 150 s each (docs/profiling.md), hence a 900 s limit per binary.
# If the checkout there is not where it was built, the run links the build
# path to it. Nothing here installs a driver: the Vulkan loader and the
# GPU's ICD must be there (VK_DRIVER_FILES may name the ICD's manifest).
set -u
cd "$(dirname "$0")/.."
if [ "${1:-}" = --pack ]; then
  dir=${2:?usage: gpu-check.sh --pack DIR}
  mkdir -p "$dir/raw"
  cp target/release/whitted "$dir/raw/whitted"
  cp target/debug/whitted "$dir/raw/whitted-dbg"
  for t in probe gpu validate_scenes analytic stability; do
    cp "$(ls -t target/debug/deps/$t-* | grep -v '\.d$' | head -1)" "$dir/raw/t-$t"
  done
  strip "$dir"/raw/*
  pwd > "$dir/raw/built-at"
  tar cf - -C "$dir/raw" . | xz -9 -T0 > "$dir/bins.tar.xz"
  rm -rf "$dir/raw"
  ls -la "$dir/bins.tar.xz"
  exit 0
fi
dir=${1:?usage: gpu-check.sh DIR OUT}
out=${2:?usage: gpu-check.sh DIR OUT}
mkdir -p "$out" "$dir/bin"
tar xJf "$dir/bins.tar.xz" -C "$dir/bin"
B=$(cd "$dir/bin" && pwd)
T0=$(date +%s)
el() { echo "[+$(( $(date +%s) - T0 ))s] $*"; }
log=$out/log.txt
exec > >(tee -a "$log") 2>&1
built=$(cat "$B/built-at")
if [ -n "$built" ] && [ "$built" != "$PWD" ] && [ ! -e "$built" ]; then
  mkdir -p "$(dirname "$built")" && ln -s "$PWD" "$built" && el "linked $built to $PWD"
fi
mkdir -p target/debug target/tmp && cp "$B/whitted-dbg" target/debug/whitted
W=$B/whitted
# No system font (the H200's image has none): matplotlib's DejaVu Sans.
if [ -z "${WHITTED_FONT:-}" ] && ! ls /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf >/dev/null 2>&1; then
  f=$(python3 -c 'import matplotlib, os; print(os.path.join(os.path.dirname(matplotlib.__file__), "mpl-data/fonts/ttf/DejaVuSans.ttf"))' 2>/dev/null)
  [ -f "$f" ] && export WHITTED_FONT=$f && el "WHITTED_FONT=$f"
fi
export WHITTED_PIPELINE_CACHE=/tmp/gpu-check-pipelines WHITTED_REQUIRE_GPU=1
el devices; timeout 30 "$W" devices
# The first render of each kernel variant compiles its pipeline: timed
# cold (an empty cache) and warm, so the driver's compile time is known.
"$W" generate --count 20000 --seed 1 -o /tmp/s20k.nff
for accel in grid bvh; do
  for c in cold warm; do
    [ $c = cold ] && rm -rf "$WHITTED_PIPELINE_CACHE"
    s=$(date +%s%N)
    timeout 300 "$W" render /tmp/s20k.nff --backend gpu --accel $accel -o /tmp/x.png -q
    el "pipeline $c, $accel: render wall $(( ($(date +%s%N) - s) / 1000000 )) ms"
  done
done
el "validate the bundled scenes"
for s in scenes/*.toml; do
  for accel in grid bvh; do
    timeout 120 "$W" validate "$s" --width 320 --height 240 --accel $accel 2>&1 | tail -1
  done
done
el "bench"
timeout 300 "$W" bench --suite spheres,spd --backends cpu,gpu --accel grid,bvh --runs 3 \
  --csv "$out/bench.csv" 2>&1 | tail -40
el "profile"
timeout 300 "$W" profile /tmp/s20k.nff --kernels mega,wavefront --repeat 3 \
  --csv "$out/profile.csv" --plot "$out/profile.svg" 2>&1 | tail -70
el "scaling"
timeout 300 "$W" bench --scaling --backends gpu --runs 1 --csv "$out/scaling.csv" 2>&1 | tail -14
for t in analytic stability validate_scenes gpu probe; do
  el "tests: $t"
  timeout 900 "$B/t-$t" --test-threads 4 > /tmp/gpu-check-test.txt 2>&1
  echo "rc=$?"; grep -E "FAILED|panicked|test result" /tmp/gpu-check-test.txt | head -20
  cat /tmp/gpu-check-test.txt >> "$out/tests.txt"
done
el end
