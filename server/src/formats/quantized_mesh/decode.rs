//! [`decode`]: quantized-mesh bytes to a [`QmTile`], every field checked. Allocations are
//! bounded by the input's length (a count is checked against the bytes left before anything is
//! allocated for it), and no input panics.

use super::normals::oct_decode;
use super::{
    EXT_METADATA, EXT_OCT_NORMALS, HEADER_LEN, MAX_VERTICES_16, QUANT_MAX, QmError, dequantize,
};

/// The 88-byte header.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QmHeader {
    /// The tile's centre, ECEF metres.
    pub center: [f64; 3],
    /// The height quantized as 0.
    pub min_height: f32,
    /// The height quantized as 32767.
    pub max_height: f32,
    /// The bounding sphere's centre, ECEF metres.
    pub sphere_center: [f64; 3],
    /// The bounding sphere's radius, metres.
    pub sphere_radius: f64,
    /// The horizon occlusion point, in the ellipsoid-scaled frame.
    pub horizon_occlusion_point: [f64; 3],
}

/// A decoded tile: the header, the quantized vertices, the triangles and edge lists as vertex
/// indices, and the extensions.
#[derive(Debug, Clone, PartialEq)]
pub struct QmTile {
    /// The header.
    pub header: QmHeader,
    /// Quantized longitudes, 0 (west) ..= 32767 (east).
    pub u: Vec<u16>,
    /// Quantized latitudes, 0 (south) ..= 32767 (north).
    pub v: Vec<u16>,
    /// Quantized heights, 0 (minimum) ..= 32767 (maximum).
    pub height: Vec<u16>,
    /// Whether the indices were 32-bit (more than 65536 vertices).
    pub wide_indices: bool,
    /// Triangles, counter-clockwise.
    pub triangles: Vec<[u32; 3]>,
    /// Vertices on the western edge.
    pub west: Vec<u32>,
    /// Vertices on the southern edge.
    pub south: Vec<u32>,
    /// Vertices on the eastern edge.
    pub east: Vec<u32>,
    /// Vertices on the northern edge.
    pub north: Vec<u32>,
    /// The `octvertexnormals` extension: two bytes per vertex.
    pub normals: Option<Vec<[u8; 2]>>,
    /// The `metadata` extension's JSON.
    pub metadata: Option<String>,
    /// Other extensions, skipped: `(id, length in bytes)`.
    pub other_extensions: Vec<(u8, u32)>,
}

impl QmTile {
    /// `[lon, lat, height]` of every vertex, for a tile of the given bounds (degrees).
    pub fn positions(&self, west: f64, south: f64, east: f64, north: f64) -> Vec<[f64; 3]> {
        let (lo, hi) = (
            f64::from(self.header.min_height),
            f64::from(self.header.max_height),
        );
        self.u
            .iter()
            .zip(&self.v)
            .zip(&self.height)
            .map(|((&u, &v), &h)| {
                [
                    dequantize(u, west, east),
                    dequantize(v, south, north),
                    dequantize(h, lo, hi),
                ]
            })
            .collect()
    }

    /// The unit normals of the `octvertexnormals` extension, if present.
    pub fn unit_normals(&self) -> Option<Vec<[f64; 3]>> {
        self.normals
            .as_ref()
            .map(|n| n.iter().map(|&e| oct_decode(e)).collect())
    }
}

/// The signed delta of a zig-zag code (the inverse of [`super::zigzag_encode`]).
pub fn zigzag_decode(code: u16) -> i32 {
    i32::from(code >> 1) ^ -i32::from(code & 1)
}

/// Indices of high-water-mark codes, with the arithmetic wrapping at 2^16 (`wide == false`) or
/// 2^32 as the spec's decoder storing into typed arrays wraps.
pub fn hwm_decode(codes: &[u32], wide: bool) -> Vec<u32> {
    let mask: u64 = if wide { 0xFFFF_FFFF } else { 0xFFFF };
    let mut highest: u64 = 0;
    codes
        .iter()
        .map(|&code| {
            let index = highest.wrapping_sub(u64::from(code)) & mask;
            if code == 0 {
                highest += 1;
            }
            // Masked to 32 bits.
            index as u32
        })
        .collect()
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn left(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn take(&mut self, need: u64, what: &'static str) -> Result<&'a [u8], QmError> {
        let left = self.left();
        match usize::try_from(need) {
            Ok(n) if n <= left => {
                let out = &self.bytes[self.pos..self.pos + n];
                self.pos += n;
                Ok(out)
            }
            _ => Err(QmError::Truncated {
                what,
                at: self.pos,
                need,
                left,
            }),
        }
    }

    fn array<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], QmError> {
        let mut out = [0u8; N];
        out.copy_from_slice(self.take(N as u64, what)?);
        Ok(out)
    }

    fn u32(&mut self, what: &'static str) -> Result<u32, QmError> {
        self.array(what).map(u32::from_le_bytes)
    }

    fn f64(&mut self, what: &'static str) -> Result<f64, QmError> {
        self.array(what).map(f64::from_le_bytes)
    }

    fn vec3(&mut self, what: &'static str) -> Result<[f64; 3], QmError> {
        Ok([self.f64(what)?, self.f64(what)?, self.f64(what)?])
    }

    /// `count` indices of `width` bytes.
    fn indices(&mut self, count: u32, wide: bool, what: &'static str) -> Result<Vec<u32>, QmError> {
        let width: u64 = if wide { 4 } else { 2 };
        let bytes = self.take(u64::from(count) * width, what)?;
        Ok(if wide {
            bytes
                .chunks_exact(4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect()
        } else {
            bytes
                .chunks_exact(2)
                .map(|b| u32::from(u16::from_le_bytes([b[0], b[1]])))
                .collect()
        })
    }
}

fn header(r: &mut Reader) -> Result<QmHeader, QmError> {
    if r.left() < HEADER_LEN {
        return Err(QmError::Truncated {
            what: "header",
            at: 0,
            need: HEADER_LEN as u64,
            left: r.left(),
        });
    }
    Ok(QmHeader {
        center: r.vec3("center")?,
        min_height: r.array("minimum height").map(f32::from_le_bytes)?,
        max_height: r.array("maximum height").map(f32::from_le_bytes)?,
        sphere_center: r.vec3("bounding sphere")?,
        sphere_radius: r.f64("bounding sphere")?,
        horizon_occlusion_point: r.vec3("horizon occlusion point")?,
    })
}

/// One delta-coded, zig-zagged array of `n` values in 0..=32767.
fn quantized(r: &mut Reader, n: usize, what: &'static str) -> Result<Vec<u16>, QmError> {
    let at = r.pos;
    let bytes = r.take(2 * n as u64, what)?;
    let mut value = 0i32;
    bytes
        .chunks_exact(2)
        .enumerate()
        .map(|(i, b)| {
            value += zigzag_decode(u16::from_le_bytes([b[0], b[1]]));
            u16::try_from(value)
                .ok()
                .filter(|&q| q <= QUANT_MAX)
                .ok_or_else(|| QmError::Invalid {
                    at: at + 2 * i,
                    why: format!("{what} of vertex {i} decodes to {value}, outside 0..=32767"),
                })
        })
        .collect()
}

fn check_indices(list: &[u32], n: usize, at: usize, what: &str) -> Result<(), QmError> {
    match list.iter().position(|&i| i as usize >= n) {
        None => Ok(()),
        Some(k) => Err(QmError::Invalid {
            at,
            why: format!(
                "{what} entry {k} is vertex {}, but the tile has {n} vertices",
                list[k]
            ),
        }),
    }
}

/// Decodes a quantized-mesh-1.0 tile (not gzipped). Quantized values must lie in 0..=32767,
/// indices below the vertex count, the `octvertexnormals` extension must hold two bytes per
/// vertex and the `metadata` extension a length-prefixed UTF-8 string filling it; each of the
/// two may appear once. Other extensions are skipped and listed.
pub fn decode(bytes: &[u8]) -> Result<QmTile, QmError> {
    let mut r = Reader { bytes, pos: 0 };
    let header = header(&mut r)?;

    let n = r.u32("vertex count")? as usize;
    if (r.left() as u64) < 6 * n as u64 {
        return Err(QmError::Truncated {
            what: "vertex data",
            at: r.pos,
            need: 6 * n as u64,
            left: r.left(),
        });
    }
    let u = quantized(&mut r, n, "u")?;
    let v = quantized(&mut r, n, "v")?;
    let height = quantized(&mut r, n, "height")?;

    let wide = n > MAX_VERTICES_16;
    let align = if wide { 4 } else { 2 };
    let pad = (align - r.pos % align) % align;
    r.take(pad as u64, "index padding")?;
    let triangle_count = r.u32("triangle count")?;
    let at = r.pos;
    let count = triangle_count.checked_mul(3).ok_or(QmError::Truncated {
        what: "triangle indices",
        at,
        need: u64::from(triangle_count) * 3 * align as u64,
        left: r.left(),
    })?;
    let flat = hwm_decode(&r.indices(count, wide, "triangle indices")?, wide);
    check_indices(&flat, n, at, "triangle index")?;
    let triangles = flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();

    let mut edge = |what: &'static str| -> Result<Vec<u32>, QmError> {
        let count = r.u32(what)?;
        let at = r.pos;
        let list = r.indices(count, wide, what)?;
        check_indices(&list, n, at, what)?;
        Ok(list)
    };
    let west = edge("west edge")?;
    let south = edge("south edge")?;
    let east = edge("east edge")?;
    let north = edge("north edge")?;

    let mut tile = QmTile {
        header,
        u,
        v,
        height,
        wide_indices: wide,
        triangles,
        west,
        south,
        east,
        north,
        normals: None,
        metadata: None,
        other_extensions: Vec::new(),
    };
    while r.left() > 0 {
        let at = r.pos;
        let [id] = r.array::<1>("extension id")?;
        let len = r.u32("extension length")?;
        let data = r.take(u64::from(len), "extension data")?;
        let duplicate = || QmError::Invalid {
            at,
            why: format!("extension {id} appears twice"),
        };
        match id {
            EXT_OCT_NORMALS => {
                if tile.normals.is_some() {
                    return Err(duplicate());
                }
                if data.len() != 2 * n {
                    return Err(QmError::Invalid {
                        at,
                        why: format!(
                            "octvertexnormals holds {} bytes, not 2 for each of {n} vertices",
                            data.len()
                        ),
                    });
                }
                tile.normals = Some(data.chunks_exact(2).map(|b| [b[0], b[1]]).collect());
            }
            EXT_METADATA => {
                if tile.metadata.is_some() {
                    return Err(duplicate());
                }
                let mut ext = Reader {
                    bytes: data,
                    pos: 0,
                };
                let json_len = ext.u32("metadata length")?;
                let json = ext.take(u64::from(json_len), "metadata JSON")?;
                if ext.left() != 0 {
                    return Err(QmError::Invalid {
                        at,
                        why: format!("metadata extension has {} bytes after its JSON", ext.left()),
                    });
                }
                let json = std::str::from_utf8(json).map_err(|e| QmError::Invalid {
                    at,
                    why: format!("metadata JSON is not UTF-8: {e}"),
                })?;
                tile.metadata = Some(json.to_owned());
            }
            _ => tile.other_extensions.push((id, len)),
        }
    }
    Ok(tile)
}
