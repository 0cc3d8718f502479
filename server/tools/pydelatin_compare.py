#!/usr/bin/env python3
"""Relief's `tin` against pydelatin (hmm's greedy insertion) on the same crops at the same
maximum vertical error.

Needs `pip install pydelatin numpy` and the `tin_cli` example built:

    CARGO_TARGET_DIR=target cargo build --release -p relief-server --example tin_cli
    python3 server/tools/pydelatin_compare.py target/release/examples/tin_cli DEM.png...

For each DEM, each crop size (65 and 257 samples a side, crops spread over the DEM) and each
tolerance, both builders mesh the crop; both meshes' errors are measured by the same brute-force
oracle (`tin_cli check`, Relief's `TriMesh::max_error`), and a markdown table is printed:
triangles and milliseconds (best of five) for each, summed over the crops, and the largest
error either reached.
"""

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from pydelatin import Delatin

TOLERANCES = [1.0, 2.0, 5.0, 10.0, 20.0]
SIZES = [65, 257]
CROPS_PER_SIZE = 4


def run(cli, *args):
    out = subprocess.run([cli, *map(str, args)], check=True, capture_output=True, text=True)
    return json.loads(out.stdout) if out.stdout.strip() else None


def dem_size(png):
    side = json.loads(Path(png).with_suffix(".json").read_text())
    return side["width"], side["height"]


def pydelatin_mesh(z, tol, path):
    """pydelatin's mesh of `z` at `tol`, written for `tin_cli check`; (triangles, best ms)."""
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        d = Delatin(z, max_error=tol)
        best = min(best, (time.perf_counter() - t0) * 1e3)
    h = z.shape[0]
    v = d.vertices
    # pydelatin's y grows north (y = h - 1 - row).
    cols = np.rint(v[:, 0]).astype(int)
    rows = h - 1 - np.rint(v[:, 1]).astype(int)
    with open(path, "w") as f:
        f.write(f"{len(v)} {len(d.triangles)}\n")
        f.writelines(f"{c} {r}\n" for c, r in zip(cols, rows))
        f.writelines(f"{a} {b} {c}\n" for a, b, c in d.triangles)
    return len(d.triangles), best


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    cli, dems = sys.argv[1], sys.argv[2:]
    print("| DEM | crops | tol m | Relief tris | pydelatin tris | Relief/pydelatin "
          "| Relief max err | pydelatin max err | Relief ms | pydelatin ms |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    grand = {"rt": 0, "pt": 0, "rms": 0.0, "pms": 0.0, "fewer": 0, "more": 0}
    with tempfile.TemporaryDirectory() as tmp:
        for png in dems:
            w, h = dem_size(png)
            name = Path(png).stem
            for n in SIZES:
                # Crops along the diagonal, away from the borders.
                k = CROPS_PER_SIZE
                spots = [((w - n) * (i + 1) // (k + 1), (h - n) * (i + 1) // (k + 1))
                         for i in range(k)]
                raws = []
                for i, (c, r) in enumerate(spots):
                    raw = f"{tmp}/{name}_{n}_{i}.f32"
                    run(cli, "crop", png, c, r, n, n, raw)
                    raws.append(raw)
                for tol in TOLERANCES:
                    tot = {"rt": 0, "pt": 0, "re": 0.0, "pe": 0.0, "rms": 0.0, "pms": 0.0}
                    for raw in raws:
                        z = np.fromfile(raw, dtype="<f4").reshape(n, n)
                        r = run(cli, "tin", raw, n, n, tol)
                        mesh = raw + ".mesh"
                        tris, ms = pydelatin_mesh(z, tol, mesh)
                        p = run(cli, "check", raw, n, n, mesh)
                        assert r["covers"] and p["covers"], (raw, tol)
                        assert p["triangles"] == tris
                        tot["rt"] += r["triangles"]
                        tot["pt"] += tris
                        tot["re"] = max(tot["re"], r["max_error"])
                        tot["pe"] = max(tot["pe"], p["max_error"])
                        tot["rms"] += r["ms"]
                        tot["pms"] += ms
                    for key in ("rt", "pt", "rms", "pms"):
                        grand[key] += tot[key]
                    grand["fewer"] += tot["rt"] < tot["pt"]
                    grand["more"] += tot["rt"] > tot["pt"]
                    print(f"| {name} | {len(raws)} x {n}^2 | {tol:g} | {tot['rt']} | {tot['pt']} "
                          f"| {tot['rt'] / tot['pt']:.3f} | {tot['re']:.3f} | {tot['pe']:.3f} "
                          f"| {tot['rms']:.1f} | {tot['pms']:.1f} |", flush=True)
    print(f"| all | | | {grand['rt']} | {grand['pt']} | {grand['rt'] / grand['pt']:.4f} | | "
          f"| {grand['rms']:.0f} | {grand['pms']:.0f} |")
    print(f"\nRelief fewer triangles in {grand['fewer']} rows, more in {grand['more']}.")


if __name__ == "__main__":
    main()
