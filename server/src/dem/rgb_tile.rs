//! Terrain-RGB and Terrarium PNG tiles as DEM input (`--encoding terrain-rgb|terrarium`): the
//! heights are the pixels' colours ([`crate::formats::terrain_rgb`]), and the place is the web
//! map tile the file is.
//!
//! - **Which tile**: `--tile Z/X/Y` ([`LoadOptions::tile`]), else the path: `.../Z/X/Y.png`, the
//!   layout tile servers and `wget -r` leave, or a file named `Z-X-Y.png`. XYZ scheme, y = 0 at
//!   the north (a TMS pyramid, y from the south, must be renamed or given by `--tile`).
//! - **Georeference**: Web Mercator (EPSG:3857). Pixels are areas, so the first sample lies
//!   half a pixel in from the tile's north-west corner, and samples are 2 * 20037508.34 / (2^z *
//!   tile pixels) metres apart ([`TileId::pixel_georef`]). Tiles are square, 256 or 512 pixels
//!   as a rule; any square size is read.
//! - **Ground spacing**: Web Mercator metres times the cosine of the latitude of the tile's
//!   centre (Mercator stretches the ground by 1 / cos(latitude), equally in both directions).
//! - **Voids**: a pixel with alpha 0 (RGBA tiles) has no data; the fill covers it.
//!
//! Several tiles of one zoom and size make a mosaic ([`super::mosaic`]): each takes its z/x/y
//! from its own path.

use super::{DemError, LoadOptions, RawGrid, VoidMask, check_size};
use crate::formats::terrain_rgb::{Encoding, FormatError, read_png};
use crate::geo::mercator::TileId;
use std::io::{BufRead, Seek};

/// Reads the tile at `path` from `reader` as `enc`.
pub fn read<R: BufRead + Seek>(
    path: &str,
    reader: R,
    enc: Encoding,
    opts: &LoadOptions,
) -> Result<RawGrid, DemError> {
    let Some(tile) = opts.tile.or_else(|| TileId::from_path(path)) else {
        return Err(DemError::Place {
            input: path.into(),
            detail: format!(
                "a {enc} tile is placed by its zoom, column and row: name it .../Z/X/Y.png or \
                 Z-X-Y.png (XYZ scheme, row 0 at the north, X and Y below 2^Z), or give \
                 --tile Z/X/Y"
            ),
        });
    };
    let (w, h, heights) = read_png(reader, enc, opts.max_samples).map_err(|e| match e {
        FormatError::TooLarge {
            width,
            height,
            limit,
        } => DemError::TooLarge {
            input: path.into(),
            width,
            height,
            samples: width as u64 * height as u64,
            limit,
        },
        FormatError::Png(detail) => DemError::Corrupt {
            path: path.into(),
            kind: "PNG",
            detail,
        },
        other => DemError::Unsupported {
            path: path.into(),
            detail: other.to_string(),
        },
    })?;
    check_size(path, w, h, opts)?;
    if w != h {
        return Err(DemError::Unsupported {
            path: path.into(),
            detail: format!("a {w}x{h} tile; web map tiles are square"),
        });
    }
    let g = tile.pixel_georef(w);
    let spacing = g
        .ground_spacing(h)
        .ok_or_else(|| "no ground spacing for Web Mercator".to_string());
    let mut voids = VoidMask::new(heights.len());
    for (i, v) in heights.iter().enumerate() {
        if v.is_nan() {
            voids.set(i);
        }
    }
    Ok(RawGrid {
        width: w,
        height: h,
        heights,
        voids,
        spacing,
        crs: Some(g.crs()),
        georef: Some(g),
        nan_is_void: true,
        io: Default::default(),
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::{DemError, LoadOptions, load};
    use crate::formats::terrain_rgb::{Encoding, encode_png};
    use crate::geo::GeoTransform;
    use crate::geo::mercator::{EPSG_WEB_MERCATOR, HALF_WORLD, TileId};

    /// Heights of a smooth, varied surface at global pixel (`gx`, `gy`), with fractions of
    /// metres that neither encoding holds exactly.
    pub(crate) fn surface(gx: u32, gy: u32) -> f32 {
        let (x, y) = (gx as f32, gy as f32);
        1234.567 + 300.0 * (x / 7.3).sin() * (y / 5.1).cos() + 50.0 * (x / 31.0 + y / 17.0).sin()
    }

    /// Writes the tile `t` of `px` pixels of [`surface`] in `enc` as `dir/Z/X/Y.png`.
    pub(crate) fn write_tile(
        dir: &std::path::Path,
        t: TileId,
        px: u32,
        enc: Encoding,
        f: impl Fn(u32, u32) -> f32,
    ) -> String {
        let h: Vec<f32> = (0..px * px)
            .map(|i| f(t.x * px + i % px, t.y * px + i / px))
            .collect();
        let folder = dir.join(format!("{}/{}", t.z, t.x));
        std::fs::create_dir_all(&folder).unwrap();
        let p = folder.join(format!("{}.png", t.y));
        std::fs::write(&p, encode_png(px, px, &h, enc)).unwrap();
        p.display().to_string()
    }

    fn with(enc: Encoding) -> LoadOptions {
        LoadOptions {
            encoding: Some(enc),
            ..LoadOptions::default()
        }
    }

    #[test]
    fn tiles_read_back_within_half_a_step_where_their_z_x_y_puts_them() {
        let dir = tempfile::tempdir().unwrap();
        // Mt Fuji's tile at zoom 12.
        let t = TileId::new(12, 3629, 1617).unwrap();
        for (enc, px) in [(Encoding::TerrainRgb, 256), (Encoding::Terrarium, 512)] {
            let p = write_tile(dir.path(), t, px, enc, surface);
            let d = load(&p, &with(enc)).unwrap();
            assert_eq!((d.width, d.height, d.voids.count()), (px, px, 0));
            for (i, &h) in d.heights.iter().enumerate() {
                let want = surface(t.x * px + i as u32 % px, t.y * px + i as u32 / px);
                assert!(
                    ((h - want).abs() as f64) <= enc.step() / 2.0 + 1e-4,
                    "{enc}: {h} {want}"
                );
            }
            assert_eq!(d.crs.as_deref(), Some("EPSG:3857"));
            let g = d.georef.clone().unwrap();
            assert_eq!(g.epsg, EPSG_WEB_MERCATOR);
            let step = 2.0 * HALF_WORLD / (4096.0 * px as f64);
            assert_eq!(g.step, [step, step]);
            // The tile's corners: pixel corners half a sample out from the samples.
            let tr = GeoTransform::new(&g).unwrap();
            let n = 4096.0;
            let lat = |y: f64| {
                (std::f64::consts::PI * (1.0 - 2.0 * y / n))
                    .sinh()
                    .atan()
                    .to_degrees()
            };
            let [w, north] = tr.lonlat(-0.5, -0.5).unwrap();
            let [e, south] = tr.lonlat(px as f64 - 0.5, px as f64 - 0.5).unwrap();
            assert!((w - (3629.0 / n * 360.0 - 180.0)).abs() < 1e-9, "{w}");
            assert!((e - (3630.0 / n * 360.0 - 180.0)).abs() < 1e-9, "{e}");
            assert!((north - lat(1617.0)).abs() < 1e-9, "{north}");
            assert!((south - lat(1618.0)).abs() < 1e-9, "{south}");
            // Ground spacing: Mercator metres times cos(latitude at the centre).
            let k = lat(1617.5).to_radians().cos();
            assert!((d.spacing_x - step * k).abs() < 1e-9 && d.spacing_x == d.spacing_y);
        }
    }

    #[test]
    fn tiles_take_z_x_y_from_a_name_or_a_flag() {
        let dir = tempfile::tempdir().unwrap();
        let t = TileId::new(3, 6, 2).unwrap();
        let enc = Encoding::Terrarium;
        let nested = write_tile(dir.path(), t, 16, enc, surface);
        let flat = dir.path().join("3-6-2.png");
        std::fs::copy(&nested, &flat).unwrap();
        let plain = dir.path().join("tile.png");
        std::fs::copy(&nested, &plain).unwrap();
        let a = load(&nested, &with(enc)).unwrap();
        let b = load(flat.to_str().unwrap(), &with(enc)).unwrap();
        assert_eq!((&a.heights, &a.georef), (&b.heights, &b.georef));
        // No z/x/y: the error says how to give it.
        let plain = plain.to_str().unwrap();
        let e = load(plain, &with(enc)).unwrap_err();
        assert!(matches!(e, DemError::Place { .. }), "{e}");
        let m = e.to_string();
        assert!(m.contains(plain) && m.contains("--tile Z/X/Y"), "{m}");
        let flag = LoadOptions {
            tile: Some(t),
            ..with(enc)
        };
        let c = load(plain, &flag).unwrap();
        assert_eq!((&a.heights, &a.georef), (&c.heights, &c.georef));
        // The flag wins over the path.
        let other = LoadOptions {
            tile: TileId::new(3, 5, 2).ok(),
            ..with(enc)
        };
        let d = load(&nested, &other).unwrap();
        assert!(d.georef.unwrap().first[0] < a.georef.unwrap().first[0]);
    }

    #[test]
    fn tile_options_are_refused_where_they_mean_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let t = TileId::new(3, 6, 2).unwrap();
        let p = write_tile(dir.path(), t, 16, Encoding::TerrainRgb, surface);
        // An RGB PNG without --encoding: the error points to it.
        let e = load(&p, &LoadOptions::default()).unwrap_err();
        assert!(matches!(e, DemError::Unsupported { .. }), "{e}");
        assert!(e.to_string().contains("--encoding terrain-rgb"), "{e}");
        let tile_only = LoadOptions {
            tile: Some(t),
            ..LoadOptions::default()
        };
        let e = load(&p, &tile_only).unwrap_err();
        assert!(e.to_string().contains("--encoding"), "{e}");
        // --encoding for a synthetic terrain, a GeoTIFF or an .hgt.
        let e = load("synthetic:33", &with(Encoding::Terrarium)).unwrap_err();
        assert!(matches!(e, DemError::BadOptions { .. }), "{e}");
        assert!(e.to_string().contains("--encoding"), "{e}");
        let hgt = dir.path().join("N35E138.hgt");
        std::fs::write(&hgt, vec![0u8; 1201 * 1201 * 2]).unwrap();
        let e = load(hgt.to_str().unwrap(), &tile_only).unwrap_err();
        assert!(e.to_string().contains("--tile"), "{e}");
        // A georeferenced tile refuses --origin.
        let o = LoadOptions {
            origin: Some((1.0, 2.0)),
            ..with(Encoding::TerrainRgb)
        };
        assert!(load(&p, &o).unwrap_err().to_string().contains("--origin"));
        // A 16-bit PNG read as a tile.
        let l16 = super::super::png::tests::png16(2, 2, &[1, 2, 3, 4]);
        let q = dir.path().join("3-6-2.png");
        std::fs::write(&q, l16).unwrap();
        let e = load(q.to_str().unwrap(), &with(Encoding::Terrarium)).unwrap_err();
        assert!(matches!(e, DemError::Unsupported { .. }), "{e}");
        // A tile that is not square.
        let rect = encode_png(4, 2, &[0.0; 8], Encoding::Terrarium);
        std::fs::write(&q, rect).unwrap();
        let e = load(q.to_str().unwrap(), &with(Encoding::Terrarium)).unwrap_err();
        assert!(e.to_string().contains("square"), "{e}");
    }
}
