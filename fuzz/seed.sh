#!/usr/bin/env bash
# Writes the fuzz targets' seed inputs into fuzz/seeds/TARGET/ (not
# committed; the minimised corpus in fuzz/corpus/ is): the scenes in
# scenes/, the seven SPD scenes at size 1 (and 2 where small) written by
# `whitted generate`, and a few hand-written .obj files covering the
# syntax tobj reads. docs/reliability.md says how the targets were run.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --quiet --bin whitted
bin=target/debug/whitted
out=fuzz/seeds
rm -rf "$out"
mkdir -p "$out"/{toml,nff,obj,pack}
cp scenes/*.toml "$out/toml/"
cp scenes/*.nff "$out/nff/"
cp scenes/*.obj "$out/obj/"
for s in balls gears mount rings teapot tetra tree; do
  "$bin" generate "$s" --size 1 -o "$out/nff/$s-1.nff" >/dev/null
done
# Size 2 where the file stays small (gears and teapot are 60-300 KB).
for s in balls mount rings tetra tree; do
  "$bin" generate "$s" --size 2 -o "$out/nff/$s-2.nff" >/dev/null
done
o="$out/obj"
printf 'v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n' >"$o/quad.obj"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1/1 2/2/1 3/3/1\n' >"$o/full.obj"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 0\nf -4//1 -3//1 -2//1\nf -4 -2 -1\n' >"$o/relative.obj"
printf 'mtllib a.mtl\no one\ng g1\nusemtl red\ns 1\nv 0 0 0 1\nv 2 0 0 2\nv 0 2 0 0.5\nf 1 2 3\nl 1 2\np 3\no two\nv 5 5 5\nv 6 5 5\nv 5 6 5\nf 4 5 6\n' >"$o/groups.obj"
printf '# a pentagon fan, a line continuation and a sliver\nv 0 0 0\nv 1 0 0\nv 1.5 1 0\nv 0.5 2 0\nv -0.5 1 0\nv 2 0 0\nf 1 2 3 4 5\nf 1 2 \\\n 6\n' >"$o/fan.obj"
ls "$out"/* | head -40
du -sh "$out"/*
