//! The DEM arguments of every command that reads a DEM (`build`, `serve`, `bench`): one set,
//! so that a DEM that builds also serves.

use super::{DEFAULT_MAX_SAMPLES, Dem, DemError, LoadOptions, PngOptions, load};

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
    /// Ground metres between columns (required for PNG; overrides the GeoTIFF's tags).
    #[arg(long)]
    pub spacing_x: Option<f64>,
    /// Ground metres between rows (required for PNG; overrides the GeoTIFF's tags).
    #[arg(long)]
    pub spacing_y: Option<f64>,
    /// Place input that carries no georeference (synthetic, PNG) on the Earth: the longitude
    /// and latitude in degrees of its north-west sample, as `LON,LAT` (e.g. `--origin
    /// 138.5,35.5`). The standard formats (/cesium, /tiles) need a georeference; GeoTIFFs
    /// carry their own.
    #[arg(long, value_name = "LON,LAT", value_parser = parse_origin, allow_hyphen_values = true)]
    pub origin: Option<(f64, f64)>,
    /// Refuse DEMs with more samples than this.
    #[arg(long, default_value_t = DEFAULT_MAX_SAMPLES)]
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
            progress: !self.quiet,
        }
    }

    /// Loads `spec` with these arguments.
    pub fn load(&self, spec: &str) -> Result<Dem, DemError> {
        load(spec, &self.options())
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
