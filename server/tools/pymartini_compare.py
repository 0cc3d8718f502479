"""Meshes the crops written by `rqt_figure table DIR` with pymartini (mapbox martini's RTIN)
at each tolerance, for `rqt_figure compare DIR`, which measures both sides' maximum error with
the same brute force (relief-server's `TriMesh::max_error`).

    pip install pymartini numpy
    python server/tools/pymartini_compare.py DIR

Writes `{dem}_{n}.martini` beside each `{dem}_{n}.f32` (layouts in server/examples/rqt_figure.rs)
and prints pymartini's mean time per crop (error table, then each mesh).
"""

import pathlib
import sys
import time

import numpy as np
from pymartini import Martini

TOLS = [1.0, 2.0, 5.0, 10.0, 20.0]  # as TOLS in rqt_figure.rs


def main(dir_: pathlib.Path) -> None:
    print("| crops | count | error table ms | " + " | ".join(f"mesh us at {t}" for t in TOLS) + " |")
    for path in sorted(dir_.glob("*.f32")):
        raw = path.read_bytes()
        n, count = np.frombuffer(raw[:8], dtype="<u4")
        rec = 8 + 4 * int(n) * int(n)
        martini = Martini(int(n))
        build, mesh = 0.0, [0.0] * len(TOLS)
        with open(path.with_suffix(".martini"), "wb") as out:
            for k in range(int(count)):
                z = np.frombuffer(raw, dtype="<f4", count=int(n) * int(n), offset=8 + k * rec + 8)
                z = np.array(z, dtype=np.float32)  # a writable copy: pymartini wants one
                t0 = time.perf_counter()
                tile = martini.create_tile(z)
                build += time.perf_counter() - t0
                for j, tol in enumerate(TOLS):
                    t0 = time.perf_counter()
                    verts, tris = tile.get_mesh(tol)
                    mesh[j] += time.perf_counter() - t0
                    out.write(np.array([len(verts), len(tris)], dtype="<u4").tobytes())
                    out.write(np.ascontiguousarray(verts, dtype="<u2").tobytes())
                    out.write(np.ascontiguousarray(tris, dtype="<u4").tobytes())
        c = int(count)
        cells = " | ".join(f"{1e6 * m / c:.0f}" for m in mesh)
        print(f"| {path.stem} | {c} | {1e3 * build / c:.2f} | {cells} |")


if __name__ == "__main__":
    main(pathlib.Path(sys.argv[1]))
