//! The DEM arguments of every command that reads a DEM (`build`, `serve`, `bench`): one set,
//! so that a DEM that builds also serves.

use super::{Dem, DemError, LoadOptions, PngOptions, load_all};
use crate::formats::terrain_rgb::Encoding;
use crate::geo::mercator::TileId;

/// How to read a DEM.
#[derive(Clone, Debug, clap::Args)]
pub struct DemArgs {
    /// PNG only: metres per 16-bit value.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub png_scale: f64,
    /// PNG only: metres added to every value (e.g. `--png-offset -17`).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub png_offset: f64,
    /// PNG only: the 16-bit value that means "no data" (use -1 for none).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub png_nodata: i32,
    /// Ground metres between columns (required for 16-bit PNG; overrides the file's, and the
    /// one computed for a mosaic).
    #[arg(long)]
    pub spacing_x: Option<f64>,
    /// Ground metres between rows (required for 16-bit PNG; overrides the file's, and the one
    /// computed for a mosaic).
    #[arg(long)]
    pub spacing_y: Option<f64>,
    /// Place input that carries no georeference (synthetic, PNG) on the Earth: the longitude
    /// and latitude in degrees of its north-west sample, as `LON,LAT` (e.g. `--origin
    /// 138.5,35.5`). The standard formats (/cesium, /tiles) need a georeference; GeoTIFFs,
    /// .hgt files and terrain tiles carry their own.
    #[arg(long, value_name = "LON,LAT", value_parser = parse_origin, allow_hyphen_values = true)]
    pub origin: Option<(f64, f64)>,
    /// Read PNGs as terrain tiles whose colours are heights: `terrain-rgb` (Mapbox; MapLibre
    /// calls it `mapbox`): -10000 + (R*65536 + G*256 + B) * 0.1 m, or `terrarium` (Mapzen/AWS):
    /// R*256 + G + B/256 - 32768 m. Required for 8-bit RGB(A) PNGs, which are otherwise
    /// refused; alpha 0 means no data. A tile is placed in Web Mercator (EPSG:3857) by its
    /// zoom, column and row, taken from its path `.../Z/X/Y.png` or a `Z-X-Y.png` name (XYZ
    /// scheme, row 0 at the north), or from --tile.
    #[arg(long, value_name = "ENCODING")]
    pub encoding: Option<Encoding>,
    /// With --encoding: the tile a single PNG is, as `Z/X/Y` (XYZ scheme, row 0 at the north,
    /// e.g. `--tile 12/3629/1617`), where its path does not say; overrides the path.
    #[arg(long, value_name = "Z/X/Y")]
    pub tile: Option<TileId>,
    /// Refuse DEMs with more samples than this [default: what a build fits in this machine's
    /// memory, or the cgroup's limit, at 12 bytes a sample; `tin` tiles need about 24].
    #[arg(long, default_value_t = super::default_max_samples(), hide_default_value = true)]
    pub max_samples: u64,
    /// Hide progress bars.
    #[arg(long)]
    pub quiet: bool,
}

impl DemArgs {
    /// The load options these arguments give.
    pub fn options(&self) -> LoadOptions {
        LoadOptions {
            max_samples: self.max_samples,
            spacing_x: self.spacing_x,
            spacing_y: self.spacing_y,
            png: PngOptions {
                scale: self.png_scale,
                offset: self.png_offset,
                nodata_value: u16::try_from(self.png_nodata).ok(),
            },
            origin: self.origin,
            encoding: self.encoding,
            tile: self.tile,
            progress: !self.quiet,
        }
    }

    /// Loads `specs` with these arguments: one DEM, or the mosaic of several
    /// ([`super::load_all`]).
    pub fn load<S: AsRef<str>>(&self, specs: &[S]) -> Result<Dem, DemError> {
        load_all(specs, &self.options())
    }
}

impl Default for DemArgs {
    fn default() -> Self {
        let o = LoadOptions::default();
        DemArgs {
            png_scale: o.png.scale,
            png_offset: o.png.offset,
            png_nodata: o.png.nodata_value.map_or(-1, i32::from),
            spacing_x: None,
            spacing_y: None,
            max_samples: o.max_samples,
            origin: None,
            encoding: None,
            tile: None,
            quiet: false,
        }
    }
}

/// Parses `LON,LAT` in degrees.
fn parse_origin(s: &str) -> Result<(f64, f64), String> {
    let bad = || format!("expected LON,LAT in degrees, as in 138.5,35.5; got {s:?}");
    let (lon, lat) = s.split_once(',').ok_or_else(bad)?;
    let lon: f64 = lon.trim().parse().map_err(|_| bad())?;
    let lat: f64 = lat.trim().parse().map_err(|_| bad())?;
    if !(-180.0..=180.0).contains(&lon) || !(-85.0..=85.0).contains(&lat) {
        return Err(format!(
            "origin {lon},{lat}: the longitude must be in -180..180 and the latitude in -85..85"
        ));
    }
    Ok((lon, lat))
}
