//! Cesium terrain: the store as quantized-mesh-1.0 tiles in Cesium's geographic tiling scheme,
//! described by a `layer.json`.
//!
//! - **Tiles.** Each tile is resampled from the store at 65 x 65 points from edge to edge
//!   ([`super::sampler`]; points outside the store get 0 m, the ellipsoid, as Cesium's own
//!   ellipsoid terrain does), then meshed with the store's tile mesh: `grid` keeps every point
//!   (two triangles a cell); `rqt` and `tin` simplify to half of Cesium's geometric error for
//!   the level ([`cesium_level_error`]), the error Cesium's refinement assumes a tile has, so
//!   the simplification spends at most half of it. Cesium stitches neighbours with skirts built
//!   from the edge lists, so no mesh needs shared borders here.
//! - **Availability.** Level 0 (both root tiles) is always available, so that Cesium has a
//!   globe to refine; below it, the tiles that overlap the store's longitude/latitude box, down
//!   to the level whose 65-point tiles are as fine as the store's samples ([`CesiumLayer`]).
//!   Other tiles are not available: the server answers 404, and Cesium upsamples parents.

use super::quantized_mesh::availability_metadata;
use super::sampler::{Points, Resampler};
use crate::geo::tiling::{Scheme, TileRange, TileXyz, cesium_level_error};
use crate::geo::{GeoError, GeoTransform, LonLatBounds};
use crate::lod::tile::mesh::{HeightGrid, TriMesh, rqt::rqt, tin::tin};
use relief_proto::tile::body::MeshKind;

/// Points a side of every tile, Cesium's heightmap size.
pub const TILE_POINTS: usize = 65;
/// Levels of availability a tile's `metadata` extension lists below it.
pub const METADATA_LEVELS: u8 = 10;

/// Which tiles exist for a terrain, and its `layer.json`.
#[derive(Clone, Debug, PartialEq)]
pub struct CesiumLayer {
    /// The store's longitude/latitude box.
    pub bounds: LonLatBounds,
    /// The deepest level served.
    pub max_level: u8,
    /// Per level from 0, the tiles available.
    pub ranges: Vec<TileRange>,
}

impl CesiumLayer {
    /// The layer of a `width` x `height` store placed by `geo`.
    pub fn new(geo: &GeoTransform, width: u32, height: u32) -> Result<CesiumLayer, GeoError> {
        let bounds = geo.bounds(width, height)?;
        // The store's sample step in degrees of longitude, at its widest.
        let step = (bounds.east - bounds.west) / f64::from(width.max(2) - 1);
        let max_level = Scheme::Geographic.level_for(step, TILE_POINTS as u32);
        let mut ranges = vec![TileRange {
            start_x: 0,
            start_y: 0,
            end_x: 1,
            end_y: 0,
        }];
        for z in 1..=max_level {
            match Scheme::Geographic.range(&bounds, z) {
                Some(r) => ranges.push(r),
                None => break,
            }
        }
        Ok(CesiumLayer {
            bounds,
            max_level: (ranges.len() - 1) as u8,
            ranges,
        })
    }

    /// Whether tile `t` is served.
    pub fn available(&self, t: TileXyz) -> bool {
        self.ranges
            .get(t.z as usize)
            .is_some_and(|r| r.contains(t.x, t.y))
    }

    /// The `layer.json` for tiles at `tiles_url` (relative, with `{z}`, `{x}`, `{y}` and
    /// `{version}`), with the store's `mesh` named in the description.
    pub fn layer_json(&self, mesh: MeshKind, terrain_id: u64) -> serde_json::Value {
        let available: Vec<[TileRange; 1]> = self.ranges.iter().map(|r| [*r]).collect();
        serde_json::json!({
            "tilejson": "2.1.0",
            "name": "relief",
            "description": format!(
                "Relief terrain {terrain_id:016x}, {} tile meshes", mesh.name()),
            "version": "1.0.0",
            "format": "quantized-mesh-1.0",
            "scheme": "tms",
            "projection": "EPSG:4326",
            "tiles": ["{z}/{x}/{y}.terrain?v={version}"],
            "minzoom": 0,
            "maxzoom": self.max_level,
            "bounds": self.bounds.to_array(),
            "extensions": ["octvertexnormals", "metadata"],
            // CesiumJS takes the `metadata` extension only from a layer that says how many
            // levels each tile's metadata covers: without this it fails on the first tile
            // that carries it ("reading 'addAvailableTileRange'", CesiumJS 1.145). With it,
            // CesiumJS learns availability from the tiles at levels 0, 10, 20 ... and ignores
            // `available`, which stays for other clients.
            "metadataAvailability": METADATA_LEVELS,
            "available": available,
            "attribution": "",
        })
    }

    /// The `metadata` extension's JSON for tile `t`: the available tiles under it for the
    /// next [`METADATA_LEVELS`] levels.
    pub fn metadata(&self, t: TileXyz) -> String {
        let mut levels = Vec::new();
        for dz in 1..=METADATA_LEVELS {
            let z = t.z as usize + dz as usize;
            let Some(r) = self.ranges.get(z) else { break };
            // Tile t's descendants at level z.
            let k = 1u32 << dz;
            let own = TileRange {
                start_x: t.x * k,
                start_y: t.y * k,
                end_x: t.x * k + k - 1,
                end_y: t.y * k + k - 1,
            };
            let cut = TileRange {
                start_x: own.start_x.max(r.start_x),
                start_y: own.start_y.max(r.start_y),
                end_x: own.end_x.min(r.end_x),
                end_y: own.end_y.min(r.end_y),
            };
            let any = cut.start_x <= cut.end_x && cut.start_y <= cut.end_y;
            levels.push(if any { vec![cut] } else { Vec::new() });
        }
        availability_metadata(&levels)
    }
}

/// A tile's mesh: vertices as (longitude, latitude, height) in degrees and metres, triangles
/// counter-clockwise seen from above, and the tile's box.
#[derive(Clone, Debug, PartialEq)]
pub struct GeoMesh {
    /// The tile's box.
    pub bounds: LonLatBounds,
    /// Vertices.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles.
    pub triangles: Vec<[u32; 3]>,
}

/// The simplification tolerance of `rqt` and `tin` tiles at level `z`, metres.
pub fn tolerance(z: u8) -> f32 {
    (cesium_level_error(z) / 2.0) as f32
}

/// The heights of tile `t` at its 65 x 65 points, row by row from the north (0 m outside the
/// store).
pub fn tile_heights(r: &Resampler<'_>, t: TileXyz) -> Vec<f32> {
    r.tile(Scheme::Geographic, t, TILE_POINTS, Points::Edges)
        .into_iter()
        .map(|h| h.unwrap_or(0.0))
        .collect()
}

/// The `kind` mesh of a tile's 65 x 65 heights at level `z`.
pub fn mesh_heights(grid: &HeightGrid<'_>, kind: MeshKind, z: u8) -> TriMesh {
    match kind {
        MeshKind::Grid => grid_mesh(grid.width as u32),
        // 65 is 2^6 + 1, the side a restricted quadtree needs.
        MeshKind::Rqt => rqt(grid, tolerance(z)).expect("65 x 65 is an rqt side"),
        MeshKind::Tin => tin(grid, tolerance(z), &[]),
    }
}

/// Tile `t` resampled from the store and meshed by `kind`.
pub fn tile_mesh(r: &Resampler<'_>, kind: MeshKind, t: TileXyz) -> GeoMesh {
    let n = TILE_POINTS;
    let z = tile_heights(r, t);
    let grid = HeightGrid::new(n, n, &z).expect("a 65 x 65 grid");
    let mesh = mesh_heights(&grid, kind, t.z);
    let step = 1.0 / (n - 1) as f64;
    let vertices = mesh
        .vertices
        .iter()
        .map(|&[c, row]| {
            let [lon, lat] = Scheme::Geographic.point(t, c as f64 * step, row as f64 * step);
            [lon, lat, f64::from(grid.at(c, row))]
        })
        .collect();
    GeoMesh {
        bounds: Scheme::Geographic.bounds(t),
        vertices,
        triangles: mesh.triangles,
    }
}

/// Every point of an `n` x `n` grid, two triangles a cell, counter-clockwise seen from above
/// (rows grow south, so that is clockwise in `(col, row)`).
fn grid_mesh(n: u32) -> TriMesh {
    let vertices = (0..n)
        .flat_map(|row| (0..n).map(move |c| [c, row]))
        .collect();
    let mut triangles = Vec::with_capacity(2 * (n as usize - 1).pow(2));
    for row in 0..n - 1 {
        for c in 0..n - 1 {
            let (nw, ne) = (row * n + c, row * n + c + 1);
            let (sw, se) = (nw + n, ne + n);
            triangles.push([nw, sw, se]);
            triangles.push([nw, se, ne]);
        }
    }
    TriMesh {
        vertices,
        triangles,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::Georef;

    fn fuji() -> GeoTransform {
        GeoTransform::new(&Georef {
            epsg: 4326,
            first: [138.0, 36.0],
            step: [1.0 / 1200.0, 1.0 / 1200.0],
        })
        .unwrap()
    }

    #[test]
    fn the_layer_covers_the_store_down_to_its_resolution() {
        let l = CesiumLayer::new(&fuji(), 1201, 1201).unwrap();
        assert_eq!(l.max_level, 12);
        assert!(l.available(TileXyz { z: 0, x: 0, y: 0 }));
        assert!(l.available(TileXyz { z: 0, x: 1, y: 0 }));
        assert!(!l.available(TileXyz { z: 13, x: 0, y: 0 }));
        let r8 = l.ranges[8];
        assert_eq!(
            (r8.start_x, r8.end_x, r8.start_y, r8.end_y),
            (452, 453, 177, 179)
        );
        assert!(!l.available(TileXyz {
            z: 8,
            x: 451,
            y: 178
        }));
        let j = l.layer_json(MeshKind::Grid, 7);
        assert_eq!(j["available"].as_array().unwrap().len(), 13);
        assert_eq!(j["available"][8][0]["startX"], 452);
        assert_eq!(j["scheme"], "tms");
        assert_eq!(j["metadataAvailability"], METADATA_LEVELS);
        // Metadata lists the next levels' tiles under a tile, cut to the layer.
        let m: serde_json::Value = serde_json::from_str(&l.metadata(TileXyz {
            z: 8,
            x: 452,
            y: 178,
        }))
        .unwrap();
        let a = m["available"].as_array().unwrap();
        assert_eq!(a.len(), 4);
        assert_eq!(a[0][0]["startX"], 904);
        assert_eq!(a[0][0]["endY"], 357);
    }

    #[test]
    fn grid_meshes_cover_the_tile_counter_clockwise() {
        let m = grid_mesh(5);
        assert_eq!(m.triangles.len(), 32);
        assert!(m.covers(5, 5));
    }
}
