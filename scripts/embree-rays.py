#!/usr/bin/env python3
"""Times Intel Embree's single-ray kernel on the rays whitted traces.

Optional (issue 10's comparison; not part of the test suite). Needs the
Python packages embreex and numpy (`pip install embreex numpy`, in a
virtual environment if the system's Python is managed), and the rays from
whitted's own measurement:

    whitted generate tetra -o tetra.nff
    cargo run --release --example rays_per_core -- tetra.nff --rays tetra.rays
    python3 scripts/embree-rays.py tetra.nff tetra.rays

The scene's polygons (NFF `p` and `pp`; every SPD scene of triangles and
polygons: tetra, teapot, mount's mountain, gears) become Embree triangles
(fans); spheres, cones and cylinders are not supported and are refused.
Eye rays are closest-hit queries (rtcIntersect1), shadow feelers
occlusion queries (rtcOccluded1) up to the light; embreex runs them one
by one on one thread. Best of --repeat passes, as rays_per_core prints.
"""

import argparse
import sys
import time


def read_nff(path):
    """The triangles of an NFF file's polygons, as a list of vertex
    triples; exits naming the line of anything else that is geometry."""
    tris = []
    with open(path) as f:
        lines = f.read().splitlines()
    i = 0
    while i < len(lines):
        words = lines[i].split()
        i += 1
        if not words:
            continue
        key = words[0]
        if key in ("p", "pp"):
            n = int(words[1])
            verts = []
            for k in range(n):
                w = lines[i + k].split()
                verts.append(tuple(float(x) for x in w[:3]))
            i += n
            for k in range(1, n - 1):
                tris.append((verts[0], verts[k], verts[k + 1]))
        elif key in ("s", "c", "pl"):
            sys.exit(f"{path}:{i}: '{key}' (not a polygon): only polygon scenes are supported")
    return tris


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene", help="the NFF scene rays_per_core traced")
    ap.add_argument("rays", help="the file rays_per_core --rays wrote")
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    try:
        import numpy as np
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh
    except ImportError as e:
        sys.exit(f"needs embreex and numpy ({e}): pip install embreex numpy")

    tris = np.array(read_nff(a.scene), dtype=np.float32)
    raw = open(a.rays, "rb").read()
    n_eye, n_sh = np.frombuffer(raw[:16], dtype="<u8")
    rays = np.frombuffer(raw[16:], dtype="<f4").reshape(-1, 7)
    if len(rays) != n_eye + n_sh:
        sys.exit(f"{a.rays}: {len(rays)} rays, the header says {n_eye} + {n_sh}")
    eye, sh = rays[:n_eye], rays[n_eye:]
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, tris)

    def best(f):
        t, out = float("inf"), None
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            out = f()
            t = min(t, time.perf_counter() - t0)
        return t, out

    eo, ed = np.ascontiguousarray(eye[:, 0:3]), np.ascontiguousarray(eye[:, 3:6])
    so, sd = np.ascontiguousarray(sh[:, 0:3]), np.ascontiguousarray(sh[:, 3:6])
    sf = np.ascontiguousarray(sh[:, 6])
    te, prim = best(lambda: scene.run(eo, ed))
    ts, occ = best(lambda: scene.run(so, sd, dists=sf, query="OCCLUDED"))
    hits = int((prim >= 0).sum())
    blocked = int((occ >= 0).sum())
    m = lambda n, t: n / t / 1e6
    print(
        f"{a.scene}: {len(tris)} triangles (Embree); eye rays {n_eye} ({hits} hit) in {te:.4f} s: "
        f"{m(n_eye, te):.2f} Mrays/s; feelers {n_sh} ({blocked} blocked) in {ts:.4f} s: "
        f"{m(n_sh, ts):.2f} Mrays/s; together {m(n_eye + n_sh, te + ts):.2f} Mrays/s "
        f"(one thread, best of {a.repeat})"
    )


if __name__ == "__main__":
    main()
