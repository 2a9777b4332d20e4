#!/usr/bin/env python3
"""The megakernel against the wavefront kernel on one device, per scene:
interleaved renders (`whitted render --backend gpu --kernel K --stats`),
medians of device time, render wall time and whole-process wall time, and
the wavefront's device time per stage. Prints a Markdown table
(docs/profiling.md, "Megakernel against wavefront").

    scripts/kernel-compare.py [--runs 3] [--exe target/release/whitted]

Scenes: the SPD's seven at their default sizes (512x512, --preset spd),
scenes/showcase.toml at 800x600, and 20 000 random spheres at 1024x768,
depth 5 (the figure issue 11 started from). Every pair of images must be
identical (the kernels never change a pixel), else the script fails.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile


def render(exe, scene, kernel, args, out):
    png = os.path.join(out, f"{kernel}.png")
    stats = os.path.join(out, f"{kernel}.json")
    cmd = [exe, "-q", "render", scene, "--backend", "gpu", "--kernel", kernel,
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
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="kernels-")
    cases = []
    for name in ["balls", "gears", "mount", "rings", "teapot", "tetra", "tree"]:
        path = os.path.join(tmp, f"{name}.nff")
        subprocess.run([a.exe, "-q", "generate", name, "-o", path], check=True)
        cases.append((name, path, ["--preset", "spd"]))
    cases.append(("showcase", "scenes/showcase.toml", []))
    spheres = os.path.join(tmp, "spheres-20k.nff")
    subprocess.run([a.exe, "-q", "generate", "--count", "20000", "--seed", "1",
                    "-o", spheres], check=True)
    cases.append(("spheres-20k", spheres,
                  ["--width", "1024", "--height", "768", "--max-depth", "5"]))
    if a.only:
        keep = a.only.split(",")
        cases = [c for c in cases if c[0] in keep]
    print("| scene | device s mega | device s wavefront | wavefront/mega | "
          "process s mega | process s wavefront | wavefront stages (device s) |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for name, path, args in cases:
        got = {"mega": [], "wavefront": []}
        for _ in range(a.runs):
            images = {}
            for k in ["mega", "wavefront"]:
                s, images[k] = render(a.exe, path, k, args, tmp)
                got[k].append(s)
            if images["mega"] != images["wavefront"]:
                sys.exit(f"{name}: the kernels' images differ")
        med = {k: {f: statistics.median(s[f] for s in v) for f in ["gpu", "total"]}
               for k, v in got.items()}
        stages = {st: statistics.median(s["gpu_stages"][st] for s in got["wavefront"])
                  for st in got["wavefront"][0]["gpu_stages"]}
        order = ["generate", "extend", "shade", "shadow+combine", "resolve"]
        split = ", ".join(f"{st} {stages[st]:.3f}" for st in order if st in stages)
        m, w = med["mega"], med["wavefront"]
        print(f"| {name} | {m['gpu']:.3f} | {w['gpu']:.3f} | {w['gpu'] / m['gpu']:.2f} | "
              f"{m['total']:.3f} | {w['total']:.3f} | {split} |", flush=True)


if __name__ == "__main__":
    main()
