#!/usr/bin/env python3
"""Renders scenes with two whitted binaries in alternating order and
prints, per scene, each binary's grid (cells / references) and the
medians of its `--stats` grid build, pack and render seconds and of its
peak RSS, and whether both made the same image and ray counts.

  scripts/before-after.py BEFORE AFTER [RUNS] SCENE[:WxH] ...

e.g. scripts/before-after.py /tmp/whitted-old target/release/whitted 5 \\
       spheres-1m.nff:512x384 ../shared/scenes/spd/balls.nff
"""
import hashlib
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    bins = {"before": sys.argv[1], "after": sys.argv[2]}
    runs = int(sys.argv[3]) if sys.argv[3].isdigit() else 5
    scenes = sys.argv[4:] if sys.argv[3].isdigit() else sys.argv[3:]
    tmp = Path(tempfile.mkdtemp())
    print("| scene | grid before | grid after | grid build (s) | pack (s) | render (s) | peak RSS (MB) | same image & rays |")
    print("|---|---|---|---|---|---|---|---|")
    for spec in scenes:
        path, _, size = spec.partition(":")
        args = []
        if size:
            w, h = size.split("x")
            args = ["--width", w, "--height", h]
        res = {}
        for r in range(runs):
            for tag in ("before", "after") if r % 2 == 0 else ("after", "before"):
                out, st = tmp / f"{tag}.png", tmp / f"{tag}.json"
                p = subprocess.run(
                    ["/usr/bin/time", "-f", "%M", bins[tag], "render", "-q", "--backend", "cpu",
                     path, "-o", str(out), "--stats", str(st)] + args,
                    capture_output=True, text=True)
                if p.returncode != 0:
                    sys.exit(f"{tag} {spec}: {p.stderr}")
                j = json.loads(st.read_text())
                d = res.setdefault(tag, {"grid": [], "build": [], "render": [], "rss": []})
                d["grid"].append(j["grid"]["build_seconds"])
                d["build"].append(j["seconds"]["build"])
                d["render"].append(j["seconds"]["render"])
                d["rss"].append(int(p.stderr.split()[-1]) / 1024)
                d["cells"], d["refs"], d["rays"] = j["grid"]["cells"], j["grid"]["refs"], j["rays"]
                d["md5"] = hashlib.md5(out.read_bytes()).hexdigest()
        b, a = res["before"], res["after"]
        m = statistics.median
        same = b["md5"] == a["md5"] and b["rays"] == a["rays"]
        grid = lambda d: f"{'x'.join(map(str, d['cells']))} / {d['refs']}"
        print(f"| {Path(path).name} | {grid(b)} | {grid(a)} "
              f"| {m(b['grid']):.3f} → {m(a['grid']):.3f} | {m(b['build']):.3f} → {m(a['build']):.3f} "
              f"| {m(b['render']):.3f} → {m(a['render']):.3f} | {m(b['rss']):.0f} → {m(a['rss']):.0f} "
              f"| {'yes' if same else 'NO'} |", flush=True)


main()
