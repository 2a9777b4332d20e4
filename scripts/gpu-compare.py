#!/usr/bin/env python3
"""Two values of one GPU option on one device, per scene: interleaved
renders (`whitted render --backend gpu --OPTION VALUE --stats`), medians
of device time and whole-process wall time, and the wavefront's device
time per stage where it runs. Prints a Markdown table
(docs/profiling.md: "Megakernel against wavefront", "The grid's cell
lists").

    scripts/gpu-compare.py [--option kernel --values mega,wavefront]
                           [--runs 3] [--only balls,...] [--extra "--accel grid"]
                           [--exe target/release/whitted]

Scenes: the SPD's seven at their default sizes (512x512, --preset spd),
scenes/showcase.toml at 800x600, and 20 000 random spheres at 1024x768,
depth 5 (the figure issue 11 started from). Every pair of images must be
identical (none of these options changes a pixel), else the script fails.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile


def render(exe, scene, option, value, args, out):
    png = os.path.join(out, f"{value}.png")
    stats = os.path.join(out, f"{value}.json")
    cmd = [exe, "-q", "render", scene, "--backend", "gpu", f"--{option}", value,
           "-o", png, "--stats", stats] + args
    subprocess.run(cmd, check=True)
    with open(stats) as f:
        s = json.load(f)["seconds"]
    with open(png, "rb") as f:
        image = f.read()
    return s, image


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--exe", default="target/release/whitted")
    ap.add_argument("--only", default="", help="comma-separated scene names")
    ap.add_argument("--option", default="kernel", help="the render option compared")
    ap.add_argument("--values", default="mega,wavefront", help="its two values")
    ap.add_argument("--extra", default="", help="more render options for every run")
    a = ap.parse_args()
    v0, v1 = a.values.split(",")
    extra = a.extra.split()
    tmp = tempfile.mkdtemp(prefix="kernels-")
    cases = []
    for name in ["balls", "gears", "mount", "rings", "teapot", "tetra", "tree"]:
        path = os.path.join(tmp, f"{name}.nff")
        subprocess.run([a.exe, "-q", "generate", name, "-o", path], check=True)
        cases.append((name, path, ["--preset", "spd"] + extra))
    cases.append(("showcase", "scenes/showcase.toml", extra))
    spheres = os.path.join(tmp, "spheres-20k.nff")
    subprocess.run([a.exe, "-q", "generate", "--count", "20000", "--seed", "1",
                    "-o", spheres], check=True)
    cases.append(("spheres-20k", spheres,
                  ["--width", "1024", "--height", "768", "--max-depth", "5"] + extra))
    if a.only:
        keep = a.only.split(",")
        cases = [c for c in cases if c[0] in keep]
    print(f"| scene | device s {v0} | device s {v1} | {v1}/{v0} | "
          f"process s {v0} | process s {v1} | wavefront stages (device s) |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for name, path, args in cases:
        got = {v0: [], v1: []}
        for _ in range(a.runs):
            images = {}
            for v in [v0, v1]:
                s, images[v] = render(a.exe, path, a.option, v, args, tmp)
                got[v].append(s)
            if images[v0] != images[v1]:
                sys.exit(f"{name}: the images differ")
        med = {v: {f: statistics.median(s[f] for s in runs) for f in ["gpu", "total"]}
               for v, runs in got.items()}
        split = ""
        for v in [v0, v1]:
            if got[v][0].get("gpu_stages"):
                stages = {st: statistics.median(s["gpu_stages"][st] for s in got[v])
                          for st in got[v][0]["gpu_stages"]}
                order = ["generate", "extend", "shade", "shadow+combine", "resolve"]
                split = ", ".join(f"{st} {stages[st]:.3f}" for st in order if st in stages)
        m, w = med[v0], med[v1]
        print(f"| {name} | {m['gpu']:.3f} | {w['gpu']:.3f} | {w['gpu'] / m['gpu']:.2f} | "
              f"{m['total']:.3f} | {w['total']:.3f} | {split} |", flush=True)


if __name__ == "__main__":
    main()
