//! Tests of the quantized-mesh encoder and decoder, and the meshes and checks they share:
//! - [`round_trip`]: the integer codes against hand-written vectors, encode-decode round trips;
//! - [`geometry`]: bounding sphere, centre, horizon occlusion point, normals;
//! - [`extensions`]: extension bytes, availability JSON, Accept parsing;
//! - [`bad_input`]: refused meshes and bytes, decoding that never panics.

mod bad_input;
mod extensions;
mod geometry;
mod round_trip;

use super::decode::{hwm_decode, zigzag_decode};
use super::ellipsoid::{
    WGS84_A, WGS84_B, bounding_sphere, dot, geodetic_normal, norm, occluder_radii, sub, to_ecef,
};
use super::normals::{oct_decode, oct_encode, vertex_normals};
use super::*;
use proptest::prelude::*;

/// A small deterministic generator (xorshift64*), so failures reproduce.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// A `cols` x `rows` grid over the bounds, row-major from the south-west, two counter-clockwise
/// triangles a cell.
fn grid([w, s, e, n]: [f64; 4], cols: u32, rows: u32, height: impl Fn(f64, f64) -> f64) -> QmMesh {
    let mut vertices = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            let lon = w + (e - w) * f64::from(c) / f64::from(cols - 1);
            let lat = s + (n - s) * f64::from(r) / f64::from(rows - 1);
            vertices.push([lon, lat, height(lon, lat)]);
        }
    }
    let mut triangles = Vec::new();
    for r in 0..rows - 1 {
        for c in 0..cols - 1 {
            let a = r * cols + c;
            let (b, cc, d) = (a + 1, a + cols + 1, a + cols);
            triangles.push([a, b, cc]);
            triangles.push([a, cc, d]);
        }
    }
    QmMesh {
        west: w,
        south: s,
        east: e,
        north: n,
        vertices,
        triangles,
    }
}

const ALPS: [f64; 4] = [8.4375, 46.40625, 9.84375, 47.8125];

fn sine_terrain(lon: f64, lat: f64) -> f64 {
    2000.0 + 1500.0 * (lon * 7.0).sin() * (lat * 5.0).cos()
}

/// The grid with interior vertices jittered inside their cells and the vertex order shuffled:
/// an irregular triangulation whose vertices are not in first-use order.
fn irregular(seed: u64) -> QmMesh {
    let mut rng = Rng(seed);
    let mut mesh = grid(ALPS, 17, 13, |_, _| 0.0);
    let (dx, dy) = ((ALPS[2] - ALPS[0]) / 16.0, (ALPS[3] - ALPS[1]) / 12.0);
    for v in &mut mesh.vertices {
        if v[0] > ALPS[0] && v[0] < ALPS[2] && v[1] > ALPS[1] && v[1] < ALPS[3] {
            v[0] += rng.range(-0.3, 0.3) * dx;
            v[1] += rng.range(-0.3, 0.3) * dy;
        }
        v[2] = sine_terrain(v[0], v[1]) + rng.range(-50.0, 50.0);
    }
    // Fisher-Yates over the vertices, triangles renumbered to match.
    let n = mesh.vertices.len();
    let mut perm: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        perm.swap(i, (rng.next() % (i as u64 + 1)) as usize);
    }
    let mut new_of_old = vec![0u32; n];
    for (new, &old) in perm.iter().enumerate() {
        new_of_old[old] = new as u32;
    }
    mesh.vertices = perm.iter().map(|&old| mesh.vertices[old]).collect();
    for t in &mut mesh.triangles {
        *t = t.map(|i| new_of_old[i as usize]);
    }
    // One vertex no triangle uses.
    mesh.vertices.push([9.0, 47.0, 1234.5]);
    mesh
}

fn bounds(mesh: &QmMesh) -> (f64, f64, f64, f64) {
    (mesh.west, mesh.south, mesh.east, mesh.north)
}

/// Encodes, decodes, and checks the decoded tile against the mesh: positions within half a
/// quantization step, triangles exactly the mesh's renumbered by [`vertex_order`], each edge list
/// exactly the vertices within half a step of the edge, sorted along it.
fn round_trip(mesh: &QmMesh, ext: &QmExtensions) -> (Vec<u8>, QmTile) {
    let bytes = encode(mesh, ext).unwrap();
    let tile = decode(&bytes).unwrap();
    let n = mesh.vertices.len();
    let order = vertex_order(mesh).unwrap();
    let mut sorted = order.clone();
    sorted.sort_unstable();
    assert_eq!(sorted, (0..n as u32).collect::<Vec<_>>(), "a permutation");
    assert_eq!(tile.u.len(), n);
    assert_eq!(tile.wide_indices, n > 65536);

    let (w, s, e, no) = bounds(mesh);
    let h = &tile.header;
    let (lo, hi) = (f64::from(h.min_height), f64::from(h.max_height));
    let (min_v, max_v) = mesh
        .vertices
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v[2]), b.max(v[2]))
        });
    assert!(
        lo <= min_v && hi >= max_v,
        "header heights {lo}..{hi} hold {min_v}..{max_v}"
    );
    let step = [(e - w) / 32767.0, (no - s) / 32767.0, (hi - lo) / 32767.0];
    let pos = tile.positions(w, s, e, no);
    for (new, &old) in order.iter().enumerate() {
        for k in 0..3 {
            let err = (pos[new][k] - mesh.vertices[old as usize][k]).abs();
            assert!(
                err <= 0.5 * step[k] * (1.0 + 1e-9) + 1e-9,
                "vertex {old} axis {k}: off by {err}, half a step is {}",
                0.5 * step[k]
            );
        }
    }

    let mut new_of_old = vec![0u32; n];
    for (new, &old) in order.iter().enumerate() {
        new_of_old[old as usize] = new as u32;
    }
    let expected: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| new_of_old[i as usize]))
        .collect();
    assert_eq!(tile.triangles, expected);

    let near = |x: f64, edge: f64, step: f64| (x - edge).abs() < 0.5 * step;
    let edge_list = |on: &dyn Fn(&[f64; 3]) -> bool, along: &[u16]| {
        let mut list: Vec<u32> = (0..n)
            .filter(|&i| on(&mesh.vertices[order[i] as usize]))
            .map(|i| i as u32)
            .collect();
        list.sort_by_key(|&i| (along[i as usize], i));
        list
    };
    assert_eq!(tile.west, edge_list(&|v| near(v[0], w, step[0]), &tile.v));
    assert_eq!(tile.south, edge_list(&|v| near(v[1], s, step[1]), &tile.u));
    assert_eq!(tile.east, edge_list(&|v| near(v[0], e, step[0]), &tile.v));
    assert_eq!(tile.north, edge_list(&|v| near(v[1], no, step[1]), &tile.u));
    for pair in tile.west.windows(2) {
        assert!(tile.v[pair[0] as usize] <= tile.v[pair[1] as usize]);
    }
    (bytes, tile)
}
