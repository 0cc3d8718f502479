//! The shared real DEMs (`../shared/dem` beside the repository, as for the DEM tests, or
//! `$RELIEF_DEMS`) for the mesh figures, and square crops of them.

use relief_server::dem::{self, Dem, LoadOptions, PngOptions};
use std::path::{Path, PathBuf};

/// The DEMs, by folder name.
pub const NAMES: [&str; 4] = [
    "fuji_srtm3",
    "bigtujunga_30m",
    "fortworth_plains_pysheds",
    "jacksboro_ridges_mpl",
];

/// The folder of the shared DEMs.
pub fn root() -> PathBuf {
    std::env::var_os("RELIEF_DEMS").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/dem"),
        PathBuf::from,
    )
}

/// Loads DEM `name`: its GeoTIFF where there is one, else its 16-bit PNG with the sidecar's
/// scale, offset and spacing.
pub fn load(name: &str) -> anyhow::Result<Dem> {
    let dir = root().join(name);
    for entry in std::fs::read_dir(&dir)? {
        let p = entry?.path();
        if p.extension().is_some_and(|e| e == "tif") {
            return Ok(dem::load(&p.to_string_lossy(), &LoadOptions::default())?);
        }
    }
    load_png(&dir.join(format!("{name}.png")))
}

/// Loads a 16-bit PNG DEM with the scale, offset and spacing of its JSON sidecar (the same
/// name with `.json`).
pub fn load_png(png: &Path) -> anyhow::Result<Dem> {
    let car: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(png.with_extension("json"))?)?;
    let num = |k: &str| {
        car[k]
            .as_f64()
            .ok_or_else(|| anyhow::anyhow!("{}: the sidecar lacks {k}", png.display()))
    };
    let opts = LoadOptions {
        spacing_x: car["spacing_m_xy"][0].as_f64(),
        spacing_y: car["spacing_m_xy"][1].as_f64(),
        png: PngOptions {
            scale: num("scale")?,
            offset: num("offset")?,
            nodata_value: Some(0),
        },
        ..LoadOptions::default()
    };
    Ok(dem::load(&png.to_string_lossy(), &opts)?)
}

/// The non-overlapping `n x n` crops of `d` (neighbours share their edge samples), each as
/// (first column, first row, heights row-major).
pub fn crops(d: &Dem, n: u32) -> Vec<(u32, u32, Vec<f32>)> {
    let step = n - 1;
    let mut out = Vec::new();
    for y in 0..(d.height - 1) / step {
        for x in 0..(d.width - 1) / step {
            let (c0, r0) = (x * step, y * step);
            let z = (0..n * n)
                .map(|i| d.heights[((r0 + i / n) * d.width + c0 + i % n) as usize])
                .collect();
            out.push((c0, r0, z));
        }
    }
    out
}
