#!/usr/bin/env bash
# Builds a profile-guided release binary of whitted (rustc's PGO: an
# instrumented build, training renders, then a build that uses their
# profile) at target/pgo/<host>/release/whitted. The same images bit for
# bit as `cargo build --release` (checked at the end: PGO moves code, not
# arithmetic); 2-11 % less CPU render time on the SPD scenes and random
# spheres (BENCHMARKS.md, "A profile-guided build").
#
# The training scenes are not the benchmark's: the SPD generators at
# smaller sizes, 5 000 random spheres of another seed, a sphereflake,
# the example scenes, rendered by the CPU mirror under every structure.
#
# Needs llvm-profdata from rustc's own LLVM: `rustup component add
# llvm-tools`. Takes about 10 minutes on two cores: two release builds
# here, half a minute of renders, and the plain release build the check
# compares with (when it is not up to date). Usage: scripts/build-pgo.sh
set -euo pipefail
cd "$(dirname "$0")/.."
host=$(rustc -vV | sed -n 's/^host: //p')
profdata="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-profdata"
if [ ! -x "$profdata" ]; then
  echo "build-pgo.sh: $profdata is missing: run \`rustup component add llvm-tools\`" >&2
  exit 2
fi
root=$PWD/target/pgo
profiles=$root/profiles
scenes=$(mktemp -d)
trap 'rm -rf "$scenes"' EXIT
rm -rf "$profiles"
mkdir -p "$profiles"

# One release build with an extra rustc flag. Under RUSTFLAGS cargo ignores
# the config's flags (.cargo/config.toml: target-cpu), so the flag joins
# RUSTFLAGS then; otherwise it joins the config's list for the host.
# --target keeps the flag off build scripts.
build() {
  local flag=$1
  if [ -n "${RUSTFLAGS:-}" ]; then
    RUSTFLAGS="$RUSTFLAGS $flag" cargo build --release --target "$host" --target-dir "$root"
  else
    cargo build --release --target "$host" --target-dir "$root" \
      --config "target.$host.rustflags=[\"$flag\"]"
  fi
}

echo "build-pgo.sh: 1/3 instrumented build" >&2
build "-Cprofile-generate=$profiles"
bin=$root/$host/release/whitted

echo "build-pgo.sh: 2/3 training renders" >&2
(
  cd "$scenes"
  "$bin" generate balls --size 3 -o balls.nff -q
  "$bin" generate gears --size 3 -o gears.nff -q
  "$bin" generate mount --size 5 -o mount.nff -q
  "$bin" generate rings --size 5 -o rings.nff -q
  "$bin" generate teapot --size 4 -o teapot.nff -q
  "$bin" generate tetra --size 5 -o tetra.nff -q
  "$bin" generate tree --size 9 -o tree.nff -q
  "$bin" generate --count 5000 --seed 7 -o spheres.nff -q
  "$bin" generate --sphereflake 4 -o flake.nff -q
  for s in *.nff; do
    "$bin" render "$s" --preset spd --backend cpu -o out.png -q
    "$bin" render "$s" --backend cpu --width 400 --height 300 --max-depth 5 -o out.png -q
  done
  for a in grid bvh octree hybrid; do
    "$bin" render rings.nff --backend cpu --accel "$a" --width 256 --height 256 -o out.png -q
    "$bin" render spheres.nff --backend cpu --accel "$a" --width 256 --height 192 -o out.png -q
  done
)
for f in scenes/*.toml scenes/*.nff; do
  "$bin" render "$f" --backend cpu -o "$scenes/out.png" -q
done
"$profdata" merge -o "$root/whitted.profdata" "$profiles"

echo "build-pgo.sh: 3/3 build with the profile" >&2
build "-Cprofile-use=$root/whitted.profdata"

# The profile-guided binary must render what a plain release build of the
# same source renders, bit for bit (the same float arithmetic): one scene
# under the BVH, one under the grid.
cargo build --release -q
for check in "rings.nff --preset spd" "spheres.nff --width 256 --height 192 --max-depth 5"; do
  read -r -a args <<<"$check"
  "$bin" render "$scenes/${args[0]}" "${args[@]:1}" --backend cpu -o "$scenes/pgo.png" -q
  target/release/whitted render "$scenes/${args[0]}" "${args[@]:1}" --backend cpu -o "$scenes/plain.png" -q
  if ! cmp -s "$scenes/pgo.png" "$scenes/plain.png"; then
    echo "build-pgo.sh: the profile-guided binary renders ${args[0]} differently from the plain release build" >&2
    exit 1
  fi
done
echo "build-pgo.sh: $bin (the same image as target/release/whitted)"
