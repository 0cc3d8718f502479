//! [`encode`]: a [`QmMesh`] to quantized-mesh bytes, and the two integer codes of the format
//! ([`zigzag_encode`], [`hwm_encode`]).

use super::ellipsoid::{bounding_sphere, geodetic_normal, horizon_occlusion_point, to_ecef};
use super::normals::{oct_encode, vertex_normals};
use super::{
    EXT_METADATA, EXT_OCT_NORMALS, MAX_VERTICES_16, QUANT_MAX, QmError, QmExtensions, QmMesh,
    dequantize,
};

/// The zig-zag code of a signed delta: 0, -1, 1, -2, 2, ... become 0, 1, 2, 3, 4, ...
pub fn zigzag_encode(delta: i16) -> u16 {
    ((delta << 1) ^ (delta >> 15)) as u16
}

/// The high-water-mark codes of `indices` (webgl-loader's, as the spec decodes them): each index
/// is written as `highest - index`, and a code of 0 (a vertex not seen before) raises `highest`.
/// The arithmetic wraps at 2^16 (`wide == false`) or 2^32, as a decoder storing into `u16` or
/// `u32` arrays wraps, so a tile of exactly 65536 vertices still decodes.
///
/// `None` unless the indices are in first-use order (each one at most the number of distinct
/// indices before it), which [`encode`] arranges with [`vertex_order`].
pub fn hwm_encode(indices: &[u32], wide: bool) -> Option<Vec<u32>> {
    let mask: u64 = if wide { 0xFFFF_FFFF } else { 0xFFFF };
    let mut highest: u64 = 0;
    let mut seen: u64 = 0;
    let mut out = Vec::with_capacity(indices.len());
    for &index in indices {
        let index = u64::from(index);
        if index > seen {
            return None;
        }
        if index == seen {
            seen += 1;
        }
        let code = highest.wrapping_sub(index) & mask;
        if code == 0 {
            highest += 1;
        }
        out.push(code as u32);
    }
    Some(out)
}

/// The order [`encode`] writes the vertices in: `order[i]` is the index in `mesh.vertices` of the
/// `i`-th vertex of the tile. Vertices come in the order the triangles first use them, then the
/// unused ones in their own order.
pub fn vertex_order(mesh: &QmMesh) -> Result<Vec<u32>, QmError> {
    let n = mesh.vertices.len();
    if n > u32::MAX as usize {
        return Err(QmError::TooMany {
            what: "vertices",
            count: n,
        });
    }
    let mut placed = vec![false; n];
    let mut order = Vec::with_capacity(n);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for &index in tri {
            let slot = placed
                .get_mut(index as usize)
                .ok_or(QmError::IndexOutOfRange {
                    triangle: t,
                    index,
                    vertices: n,
                })?;
            if !*slot {
                *slot = true;
                order.push(index);
            }
        }
    }
    // n fits u32, checked above.
    order.extend((0..n as u32).filter(|&i| !placed[i as usize]));
    Ok(order)
}

fn next_down(f: f32) -> f32 {
    if f == 0.0 {
        -f32::from_bits(1)
    } else if f > 0.0 {
        f32::from_bits(f.to_bits() - 1)
    } else {
        f32::from_bits(f.to_bits() + 1)
    }
}

fn next_up(f: f32) -> f32 {
    -next_down(-f)
}

/// The largest `f32` at most `x` (infinite past the range).
fn f32_at_most(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) > x { next_down(f) } else { f }
}

/// The smallest `f32` at least `x` (infinite past the range).
fn f32_at_least(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) < x { next_up(f) } else { f }
}

fn quantize(x: f64, lo: f64, hi: f64) -> u16 {
    if hi > lo {
        // Clamped to 0..=32767 first, so the cast is exact.
        ((x - lo) / (hi - lo) * f64::from(QUANT_MAX))
            .round()
            .clamp(0.0, f64::from(QUANT_MAX)) as u16
    } else {
        0
    }
}

fn check_bounds(mesh: &QmMesh) -> Result<(), QmError> {
    let (w, s, e, n) = (mesh.west, mesh.south, mesh.east, mesh.north);
    let ok = w.is_finite()
        && s.is_finite()
        && e.is_finite()
        && n.is_finite()
        && -180.0 <= w
        && w < e
        && e <= 180.0
        && -90.0 <= s
        && s < n
        && n <= 90.0;
    if ok {
        Ok(())
    } else {
        Err(QmError::BadBounds {
            west: w,
            south: s,
            east: e,
            north: n,
        })
    }
}

/// Checks every vertex: finite, and within the bounds give or take a millionth of the tile.
fn check_vertices(mesh: &QmMesh) -> Result<(), QmError> {
    let tol_lon = (mesh.east - mesh.west) * 1e-6;
    let tol_lat = (mesh.north - mesh.south) * 1e-6;
    for (index, &[lon, lat, h]) in mesh.vertices.iter().enumerate() {
        if !(lon.is_finite() && lat.is_finite() && h.is_finite()) {
            return Err(QmError::NonFinite {
                what: format!("vertex {index}"),
            });
        }
        if lon < mesh.west - tol_lon
            || lon > mesh.east + tol_lon
            || lat < mesh.south - tol_lat
            || lat > mesh.north + tol_lat
        {
            return Err(QmError::OutsideBounds { index, lon, lat });
        }
    }
    Ok(())
}

fn put_u16s(out: &mut Vec<u8>, values: impl IntoIterator<Item = u16>) {
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// Writes a quantized array: deltas from the previous value (the first from 0), zig-zagged.
fn put_deltas(out: &mut Vec<u8>, values: &[u16]) {
    let mut prev = 0i32;
    put_u16s(
        out,
        values.iter().map(|&v| {
            let delta = i32::from(v) - prev;
            prev = i32::from(v);
            // Values are 0..=32767, so deltas fit i16.
            zigzag_encode(delta as i16)
        }),
    );
}

fn put_indices(out: &mut Vec<u8>, values: &[u32], wide: bool) {
    for &v in values {
        if wide {
            out.extend_from_slice(&v.to_le_bytes());
        } else {
            // Below 65536 when !wide: vertex indices of a tile of at most 65536 vertices, or
            // codes masked to 16 bits.
            out.extend_from_slice(&(v as u16).to_le_bytes());
        }
    }
}

fn put_extension(out: &mut Vec<u8>, id: u8, data: &[u8]) {
    out.push(id);
    // Callers keep data under 2^32 bytes.
    out.extend_from_slice(&(data.len() as u32).to_le_bytes());
    out.extend_from_slice(data);
}

/// Encodes a mesh as a quantized-mesh-1.0 tile, with the extensions asked for.
///
/// Vertices are renumbered as [`vertex_order`] says, and quantized by rounding (at most half a
/// step off: a step is 1/32767 of the tile's width, height, or height range). The header's
/// minimum and maximum heights are the vertices' extremes rounded outwards to `f32`; its centre
/// is the tile's geographic centre at the middle height; its bounding sphere and horizon
/// occlusion point (along the sphere's centre) hold the positions as decoded. Where Cesium's
/// computation has no horizon occlusion point (a tile spanning a hemisphere), the point is
/// written as NaN, which Cesium's visibility test never finds occluded. Normals are computed from
/// the unquantized positions. Edge lists hold the vertices quantized onto each edge, west and
/// east by increasing v, south and north by increasing u.
pub fn encode(mesh: &QmMesh, ext: &QmExtensions) -> Result<Vec<u8>, QmError> {
    check_bounds(mesh)?;
    let (n, nt) = (mesh.vertices.len(), mesh.triangles.len());
    if n == 0 || nt == 0 {
        return Err(QmError::Empty {
            vertices: n,
            triangles: nt,
        });
    }
    if nt > u32::MAX as usize {
        return Err(QmError::TooMany {
            what: "triangles",
            count: nt,
        });
    }
    let order = vertex_order(mesh)?;
    check_vertices(mesh)?;
    let metadata_len = ext.metadata.as_ref().map_or(0, String::len);
    if metadata_len > u32::MAX as usize - 4 {
        return Err(QmError::MetadataTooLong { len: metadata_len });
    }

    let mut new_of_old = vec![0u32; n];
    for (new, &old) in order.iter().enumerate() {
        // n fits u32 (vertex_order checked).
        new_of_old[old as usize] = new as u32;
    }
    let vertices: Vec<[f64; 3]> = order.iter().map(|&i| mesh.vertices[i as usize]).collect();
    let triangles: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| new_of_old[i as usize]))
        .collect();

    let (lo, hi) = vertices
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v[2]), hi.max(v[2]))
        });
    let (min_h, max_h) = (f32_at_most(lo), f32_at_least(hi));
    if !(min_h.is_finite() && max_h.is_finite()) {
        return Err(QmError::NonFinite {
            what: "the height range".into(),
        });
    }
    let (min_h64, max_h64) = (f64::from(min_h), f64::from(max_h));
    let (w, s, e, no) = (mesh.west, mesh.south, mesh.east, mesh.north);
    let us: Vec<u16> = vertices.iter().map(|v| quantize(v[0], w, e)).collect();
    let vs: Vec<u16> = vertices.iter().map(|v| quantize(v[1], s, no)).collect();
    let hs: Vec<u16> = vertices
        .iter()
        .map(|v| quantize(v[2], min_h64, max_h64))
        .collect();

    // The header describes the mesh as it decodes.
    let decoded: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            to_ecef(
                dequantize(us[i], w, e),
                dequantize(vs[i], s, no),
                dequantize(hs[i], min_h64, max_h64),
            )
        })
        .collect();
    let sphere = bounding_sphere(&decoded);
    let hop = horizon_occlusion_point(&decoded, sphere.center, min_h64).unwrap_or([f64::NAN; 3]);
    let center = to_ecef(0.5 * (w + e), 0.5 * (s + no), 0.5 * (min_h64 + max_h64));

    let wide = n > MAX_VERTICES_16;
    let index_bytes = if wide { 4 } else { 2 };
    let mut out = Vec::with_capacity(
        super::HEADER_LEN + 4 + 6 * n + 4 + 4 * 5 + index_bytes * (3 * nt + n) + 2 * n + 16,
    );
    for c in center {
        out.extend_from_slice(&c.to_le_bytes());
    }
    out.extend_from_slice(&min_h.to_le_bytes());
    out.extend_from_slice(&max_h.to_le_bytes());
    for c in sphere.center {
        out.extend_from_slice(&c.to_le_bytes());
    }
    out.extend_from_slice(&sphere.radius.to_le_bytes());
    for c in hop {
        out.extend_from_slice(&c.to_le_bytes());
    }

    out.extend_from_slice(&(n as u32).to_le_bytes());
    put_deltas(&mut out, &us);
    put_deltas(&mut out, &vs);
    put_deltas(&mut out, &hs);

    while out.len() % index_bytes != 0 {
        out.push(0);
    }
    out.extend_from_slice(&(nt as u32).to_le_bytes());
    let flat: Vec<u32> = triangles.iter().flatten().copied().collect();
    let codes = hwm_encode(&flat, wide).ok_or_else(|| QmError::Invalid {
        at: 0,
        why: "internal: the renumbered indices are not in first-use order".into(),
    })?;
    put_indices(&mut out, &codes, wide);

    let edge = |on: &dyn Fn(usize) -> bool, along: &[u16]| {
        let mut list: Vec<u32> = (0..n).filter(|&i| on(i)).map(|i| i as u32).collect();
        list.sort_by_key(|&i| (along[i as usize], i));
        list
    };
    let west = edge(&|i| us[i] == 0, &vs);
    let south = edge(&|i| vs[i] == 0, &us);
    let east = edge(&|i| us[i] == QUANT_MAX, &vs);
    let north = edge(&|i| vs[i] == QUANT_MAX, &us);
    for list in [&west, &south, &east, &north] {
        out.extend_from_slice(&(list.len() as u32).to_le_bytes());
        put_indices(&mut out, list, wide);
    }

    if ext.normals {
        let ecef: Vec<[f64; 3]> = vertices.iter().map(|v| to_ecef(v[0], v[1], v[2])).collect();
        let normals = vertex_normals(&ecef, &triangles, |i| {
            geodetic_normal(vertices[i][0], vertices[i][1])
        });
        let data: Vec<u8> = normals.iter().flat_map(|&v| oct_encode(v)).collect();
        put_extension(&mut out, EXT_OCT_NORMALS, &data);
    }
    if let Some(json) = &ext.metadata {
        let mut data = Vec::with_capacity(4 + json.len());
        data.extend_from_slice(&(json.len() as u32).to_le_bytes());
        data.extend_from_slice(json.as_bytes());
        put_extension(&mut out, EXT_METADATA, &data);
    }
    Ok(out)
}
