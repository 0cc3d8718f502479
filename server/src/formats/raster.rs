//! Elevation as PNG images for MapLibre's `raster-dem` sources: the store resampled onto Web
//! Mercator XYZ tiles of 256 or 512 pixels, each pixel's height at its centre, encoded as
//! terrain-RGB or Terrarium ([`super::terrain_rgb`]), with a TileJSON describing them.
//!
//! Pixels outside the store get 0 m, exactly encodable in both encodings. Tiles that do not
//! overlap the store's box, or lie deeper than [`RasterLayer::max_level`], are not served.

use super::sampler::{Points, Resampler};
use super::terrain_rgb::{Encoding, encode_png};
use crate::geo::tiling::{Scheme, TileXyz};
use crate::geo::{GeoError, GeoTransform, LonLatBounds};

/// Tile sizes served, pixels a side.
pub const TILE_SIZES: [u32; 2] = [256, 512];

/// Which Web Mercator tiles exist for a terrain at one tile size.
#[derive(Clone, Debug, PartialEq)]
pub struct RasterLayer {
    /// The store's longitude/latitude box.
    pub bounds: LonLatBounds,
    /// Pixels a side.
    pub tile_size: u32,
    /// The deepest level: the first whose pixels are as fine as the store's samples.
    pub max_level: u8,
}

impl RasterLayer {
    /// The layer of a `width` x `height` store placed by `geo`, in tiles of `tile_size`.
    pub fn new(
        geo: &GeoTransform,
        width: u32,
        height: u32,
        tile_size: u32,
    ) -> Result<RasterLayer, GeoError> {
        let bounds = geo.bounds(width, height)?;
        let step = (bounds.east - bounds.west) / f64::from(width.max(2) - 1);
        Ok(RasterLayer {
            bounds,
            tile_size,
            // Pixels are cells: `tile_size` of them span a tile, as `tile_size + 1` edges.
            max_level: Scheme::Mercator.level_for(step, tile_size + 1),
        })
    }

    /// Whether tile `t` is served.
    pub fn available(&self, t: TileXyz) -> bool {
        t.z <= self.max_level
            && Scheme::Mercator
                .range(&self.bounds, t.z)
                .is_some_and(|r| r.contains(t.x, t.y))
    }

    /// The TileJSON 3.0 of `encoding` tiles at `tiles_url` (absolute, with `{z}`, `{x}`, `{y}`):
    /// all a MapLibre `raster-dem` source needs, the encoding included.
    pub fn tilejson(&self, encoding: Encoding, tiles_url: &str) -> serde_json::Value {
        serde_json::json!({
            "tilejson": "3.0.0",
            "name": format!("relief {}", encoding.name()),
            "tiles": [tiles_url],
            "scheme": "xyz",
            "minzoom": 0,
            "maxzoom": self.max_level,
            "bounds": self.bounds.to_array(),
            "tileSize": self.tile_size,
            "encoding": encoding.maplibre_name(),
            "attribution": "",
        })
    }
}

/// Tile `t` of `size` pixels resampled from the store and encoded as a PNG.
pub fn tile_png(r: &Resampler<'_>, encoding: Encoding, t: TileXyz, size: u32) -> Vec<u8> {
    let z: Vec<f32> = r
        .tile(Scheme::Mercator, t, size as usize, Points::Centres)
        .into_iter()
        .map(|h| h.unwrap_or(0.0))
        .collect();
    encode_png(size, size, &z, encoding)
}
