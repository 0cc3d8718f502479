#!/usr/bin/env python3
"""Relief's quantized-mesh encoder against the Python `quantized-mesh-encoder` (PyPI) on the
same meshes.

Needs numpy and quantized-mesh-encoder, and the `qm_encode` example built:

    pip install --break-system-packages quantized-mesh-encoder   # brings numpy
    CARGO_TARGET_DIR=target cargo build --release -p relief-server --example qm_encode
    python3 server/tools/qm_peer.py target/release/examples/qm_encode

Meshes (all built here, deterministic): a 65x65 grid of a sine terrain over a level-7 tile, a
Delaunay triangulation of random points (corners and points on every edge included) over a
level-10 tile, a 257x257 grid (66049 vertices: 32-bit indices) of a cone-and-ripples mountain
over a level-12 tile near 138.7 E, and a 33x33 grid below the ellipsoid (-430..-100 m). The
Python encoder does not renumber vertices, and its high-water-mark code needs them in the order
the triangles first use them, so every mesh is put in that order first (Relief's encoder then
keeps it, so both tiles number the vertices alike).

Each encoder writes a tile without extensions. Each tile is decoded twice, by the small decoder
below (written from the spec, independent of Relief's) and by Relief's (`qm_encode --decode`);
the two decodings must agree exactly, and both encoders' triangles must come back as given.
Two markdown tables are printed: bytes raw and gzipped (level 6) for each encoder, the largest
error of the decoded positions against the true ones (horizontal and vertical, metres) for each,
and the largest difference between the two decodings; then the headers: bounding sphere radius,
how far the farthest decoded vertex lies outside the sphere (<= 0: all inside), and the norm of
the horizon occlusion point (Cesium expects it in the ellipsoid-scaled frame, just above 1).
"""

import gzip
import io
import json
import math
import random
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from quantized_mesh_encoder import encode as peer_encode

WGS84_A = 6378137.0
WGS84_B = 6356752.314245179
WGS84_E2 = 1.0 - (WGS84_B * WGS84_B) / (WGS84_A * WGS84_A)


def ecef(lon, lat, h):
    """WGS84 geodetic (degrees, metres) to ECEF, arrays."""
    lon, lat = np.radians(lon), np.radians(lat)
    n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * np.sin(lat) ** 2)
    return np.stack(
        [
            (n + h) * np.cos(lat) * np.cos(lon),
            (n + h) * np.cos(lat) * np.sin(lon),
            (n * (1.0 - WGS84_E2) + h) * np.sin(lat),
        ],
        axis=-1,
    )


# --- meshes -------------------------------------------------------------------------------


def grid(bounds, cols, rows, height):
    w, s, e, n = bounds
    lon = w + (e - w) * np.arange(cols) / (cols - 1)
    lat = s + (n - s) * np.arange(rows) / (rows - 1)
    lon2, lat2 = np.meshgrid(lon, lat)
    verts = np.stack([lon2.ravel(), lat2.ravel(), height(lon2.ravel(), lat2.ravel())], axis=1)
    tris = []
    for r in range(rows - 1):
        for c in range(cols - 1):
            a = r * cols + c
            tris.append((a, a + 1, a + cols + 1))
            tris.append((a, a + cols + 1, a + cols))
    return verts, np.array(tris, dtype=np.int64)


def delaunay(pts):
    """Bowyer-Watson on points in the unit square; counter-clockwise triangles."""
    p = [tuple(q) for q in pts] + [(-50.0, -50.0), (50.0, -50.0), (0.5, 50.0)]
    n = len(pts)

    def circle(t):
        (ax, ay), (bx, by), (cx, cy) = p[t[0]], p[t[1]], p[t[2]]
        d = 2.0 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
        ux = ((ax * ax + ay * ay) * (by - cy) + (bx * bx + by * by) * (cy - ay) + (cx * cx + cy * cy) * (ay - by)) / d
        uy = ((ax * ax + ay * ay) * (cx - bx) + (bx * bx + by * by) * (ax - cx) + (cx * cx + cy * cy) * (bx - ax)) / d
        return ux, uy, (ax - ux) ** 2 + (ay - uy) ** 2

    tris = {(n, n + 1, n + 2): circle((n, n + 1, n + 2))}
    for i in range(n):
        x, y = p[i]
        bad = [t for t, (ux, uy, r2) in tris.items() if (x - ux) ** 2 + (y - uy) ** 2 < r2]
        edges = {}
        for t in bad:
            del tris[t]
            for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
                key = tuple(sorted(e))
                edges[key] = None if key in edges else e
        for e in edges.values():
            if e is not None:
                t = (e[0], e[1], i)
                tris[t] = circle(t)
    out = []
    for t in tris:
        if max(t) >= n:
            continue
        (ax, ay), (bx, by), (cx, cy) = p[t[0]], p[t[1]], p[t[2]]
        area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if abs(area) < 1e-12:
            continue
        out.append(t if area > 0 else (t[0], t[2], t[1]))
    return np.array(out, dtype=np.int64)


def random_tin(bounds, n_inner, n_edge, height, seed):
    rng = random.Random(seed)
    uv = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    for _ in range(n_edge):
        t = rng.random()
        uv += [(t, 0.0), (rng.random(), 1.0), (0.0, rng.random()), (1.0, t)]
    uv += [(rng.random(), rng.random()) for _ in range(n_inner)]
    tris = delaunay(uv)
    w, s, e, n = bounds
    uv = np.array(uv)
    lon = w + (e - w) * uv[:, 0]
    lat = s + (n - s) * uv[:, 1]
    return np.stack([lon, lat, height(lon, lat)], axis=1), tris


def first_use_order(verts, tris):
    """Vertices renumbered in the order the triangles first use them, unused ones dropped."""
    order, new = [], {}
    for i in tris.ravel():
        if i not in new:
            new[i] = len(order)
            order.append(i)
    return verts[order], np.vectorize(new.get)(tris).astype(np.int64)


def meshes():
    def sine(lon, lat):
        return 2000.0 + 1500.0 * np.sin(lon * 7.0) * np.cos(lat * 5.0) + 80.0 * np.sin(lon * 90.0)

    def mountain(lon, lat):
        r = np.hypot((lon - 138.73) * math.cos(math.radians(35.36)), lat - 35.36) * 111.0
        return 3776.0 * np.exp(-((r / 9.0) ** 2)) + 60.0 * np.sin(lon * 2000.0) * np.cos(lat * 1700.0) + 400.0

    def basin(lon, lat):
        return -430.0 + 330.0 * ((lon - 35.15625) / 1.40625) ** 2 + 20.0 * np.sin(lat * 40.0)

    yield "grid 65x65, sine, L7", (8.4375, 46.40625, 9.84375, 47.8125), *grid(
        (8.4375, 46.40625, 9.84375, 47.8125), 65, 65, sine
    )
    b = (9.140625, 46.93359375, 9.31640625, 47.109375)
    yield "random TIN, L10", b, *random_tin(b, 1500, 40, sine, 7)
    b = (138.603515625, 35.244140625, 138.6474609375, 35.2880859375)
    yield "grid 257x257, mountain, L12", b, *grid(b, 257, 257, mountain)
    b = (35.15625, 30.9375, 36.5625, 32.34375)
    yield "grid 33x33, below 0, L7", b, *grid(b, 33, 33, basin)


# --- decoding -------------------------------------------------------------------------------


def qm_decode(buf, bounds):
    """A quantized-mesh-1.0 decoder written from the spec (decoding as Cesium does)."""
    w, s, e, n = bounds
    head = struct.unpack_from("<3d2f4d3d", buf, 0)
    pos = 88
    (count,) = struct.unpack_from("<I", buf, pos)
    pos += 4

    def zigzag_run(pos):
        zz = np.frombuffer(buf, "<u2", count, pos).astype(np.int64)
        return np.cumsum((zz >> 1) ^ -(zz & 1)) & 0xFFFF, pos + 2 * count

    u, pos = zigzag_run(pos)
    v, pos = zigzag_run(pos)
    h, pos = zigzag_run(pos)
    wide = count > 65536
    size, dtype, mask = (4, "<u4", 0xFFFFFFFF) if wide else (2, "<u2", 0xFFFF)
    pos += (size - pos % size) % size
    (tc,) = struct.unpack_from("<I", buf, pos)
    pos += 4
    codes = np.frombuffer(buf, dtype, 3 * tc, pos).tolist()
    pos += 3 * tc * size
    highest, idx = 0, []
    for c in codes:
        idx.append((highest - c) & mask)
        if c == 0:
            highest += 1
    edges = []
    for _ in range(4):
        (k,) = struct.unpack_from("<I", buf, pos)
        pos += 4
        edges.append(np.frombuffer(buf, dtype, k, pos).tolist())
        pos += k * size
    lo, hi = head[3], head[4]
    verts = np.stack(
        [w + u / 32767.0 * (e - w), s + v / 32767.0 * (n - s), lo + h / 32767.0 * (hi - lo)], axis=1
    )
    return {
        "header": head,
        "vertices": verts,
        "triangles": np.array(idx, dtype=np.int64).reshape(-1, 3),
        "edges": edges,
    }


def relief_decode(cli, path, bounds):
    out = subprocess.run([cli, "--decode", path, *map(repr, bounds)], check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def check_same(mine, relief, what):
    assert np.array_equal(mine["triangles"], np.array(relief["triangles"]).reshape(-1, 3)), what
    assert mine["edges"] == [relief[k] for k in ("west", "south", "east", "north")], what
    assert np.abs(mine["vertices"] - np.array(relief["vertices"])).max() <= 1e-9, what


def errors(decoded, truth):
    """Largest horizontal (metres, on the ground) and vertical error of decoded positions."""
    horiz = np.linalg.norm(ecef(decoded[:, 0], decoded[:, 1], truth[:, 2]) - ecef(*truth.T), axis=1)
    return horiz.max(), np.abs(decoded[:, 2] - truth[:, 2]).max()


def sphere_excess(tile):
    head = tile["header"]
    pts = ecef(*tile["vertices"].T)
    return np.linalg.norm(pts - np.array(head[5:8]), axis=1).max() - head[8]


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    cli = sys.argv[1]
    rows, heads = [], []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name, bounds, verts, tris in meshes():
            verts, tris = first_use_order(verts, tris)
            mesh = tmp / "mesh.json"
            mesh.write_text(json.dumps({"bounds": list(bounds), "vertices": verts.tolist(), "triangles": tris.tolist()}))
            ours = tmp / "relief.terrain"
            subprocess.run([cli, str(mesh), str(ours)], check=True)
            relief_bytes = ours.read_bytes()
            f = io.BytesIO()
            peer_encode(f, verts.astype(np.float64), tris.astype(np.uint32), bounds=bounds)
            peer_bytes = f.getvalue()
            theirs = tmp / "peer.terrain"
            theirs.write_bytes(peer_bytes)

            tiles = {}
            for who, path, data in (("relief", ours, relief_bytes), ("peer", theirs, peer_bytes)):
                mine = qm_decode(data, bounds)
                check_same(mine, relief_decode(cli, str(path), bounds), f"{name}: {who}'s tile decodes alike")
                assert np.array_equal(mine["triangles"], tris), f"{name}: {who}'s triangles"
                tiles[who] = mine
            r_err = errors(tiles["relief"]["vertices"], verts)
            p_err = errors(tiles["peer"]["vertices"], verts)
            d_err = errors(tiles["relief"]["vertices"], tiles["peer"]["vertices"])
            gz = lambda b: len(gzip.compress(b, compresslevel=6, mtime=0))
            rows.append(
                f"| {name} | {len(verts)} | {len(tris)} | {len(relief_bytes)} | {gz(relief_bytes)} "
                f"| {len(peer_bytes)} | {gz(peer_bytes)} | {r_err[0]:.3f} / {r_err[1]:.3f} "
                f"| {p_err[0]:.3f} / {p_err[1]:.3f} | {d_err[0]:.3f} / {d_err[1]:.3f} |"
            )
            hop = lambda t: np.linalg.norm(t["header"][9:12])
            heads.append(
                f"| {name} | {tiles['relief']['header'][8]:.1f} | {tiles['peer']['header'][8]:.1f} "
                f"| {sphere_excess(tiles['relief']):.3f} | {sphere_excess(tiles['peer']):.3f} "
                f"| {hop(tiles['relief']):.6f} | {hop(tiles['peer']):.6g} |"
            )
    print("| mesh | vertices | triangles | Relief bytes | Relief gz | peer bytes | peer gz "
          "| Relief max err horiz / vert (m) | peer max err horiz / vert (m) | Relief vs peer (m) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    print("\n".join(rows))
    print()
    print("| mesh | Relief sphere r (m) | peer sphere r (m) | Relief outside sphere (m) "
          "| peer outside sphere (m) | Relief horizon pt norm | peer horizon pt norm |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    print("\n".join(heads))


if __name__ == "__main__":
    main()
