//! The readers on the real DEMs in `../shared/dem` (each checked against its JSON sidecar; the
//! tests print a notice and pass where the folder is absent, it is present in CI), the fill on
//! their voids, and the committed crop.

use super::{load_sidecar, shared};
use crate::dem::{Dem, LoadOptions, PngOptions, embedded_default, load};
use crate::geo::GeoTransform;

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs()
}

/// The shared DEM `name`'s PNG decoded with its sidecar, to compare the GeoTIFF against.
fn png_twin(name: &str, car: &serde_json::Value) -> Option<Dem> {
    let path = shared(&format!("{name}/{name}.png"));
    let opts = LoadOptions {
        spacing_x: Some(1.0),
        spacing_y: Some(1.0),
        png: PngOptions {
            scale: car["scale"].as_f64()?,
            offset: car["offset"].as_f64()?,
            nodata_value: Some(0),
        },
        ..LoadOptions::default()
    };
    Some(load(&path, &opts).unwrap())
}

#[test]
#[ignore = "needs ../shared/dem"]
fn shared_dem_geotiffs_match_their_sidecars() {
    for (name, file, crs) in [
        ("fuji_srtm3", "osgearth_mt_fuji_90m.tif", "EPSG:4326"),
        ("bigtujunga_30m", "ttb_bigtujunga.tif", "EPSG:32611"),
        ("fortworth_plains_pysheds", "pysheds_dem.tif", "EPSG:4326"),
    ] {
        let path = shared(&format!("{name}/{file}"));
        let car = load_sidecar(name);
        let d = load(&path, &LoadOptions::default()).unwrap();
        assert_eq!(d.width as u64, car["width"].as_u64().unwrap(), "{name}");
        assert_eq!(d.height as u64, car["height"].as_u64().unwrap(), "{name}");
        let s = &car["spacing_m_xy"];
        assert!(
            close(d.spacing_x, s[0].as_f64().unwrap(), 0.01),
            "{name}: {}",
            d.spacing_x
        );
        assert!(
            close(d.spacing_y, s[1].as_f64().unwrap(), 0.01),
            "{name}: {}",
            d.spacing_y
        );
        let (lo, hi) = d.valid_range();
        assert_eq!(lo as f64, car["min_m"].as_f64().unwrap(), "{name}");
        assert_eq!(hi as f64, car["max_m"].as_f64().unwrap(), "{name}");
        assert_eq!(
            d.voids.count(),
            car["nodata_pixels"].as_u64().unwrap(),
            "{name}"
        );
        assert_eq!(d.crs.as_deref(), Some(crs), "{name}");
        // The georeference puts the samples where the sidecar's pixel-area bounds say: the
        // first sample half a pixel in from the north-west corner.
        let g = d.georef.clone().expect("a georeference");
        let t = GeoTransform::new(&g).unwrap();
        let (key, half) = if g.epsg == 4326 {
            ("bounds_lonlat", car["pixel_deg"].as_f64().unwrap() / 2.0)
        } else {
            ("bounds_xy", s[0].as_f64().unwrap() / 2.0)
        };
        let b: Vec<f64> = car[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let [x0, y0] = g.model(0.0, 0.0);
        assert!(
            (x0 - (b[0] + half)).abs() < 1e-5 * half.max(1.0),
            "{name}: {x0}"
        );
        assert!(
            (y0 - (b[3] - half)).abs() < 1e-5 * half.max(1.0),
            "{name}: {y0}"
        );
        let [x1, y1] = g.model((d.width - 1) as f64, (d.height - 1) as f64);
        assert!(
            (x1 - (b[2] - half)).abs() < 1e-3 * half.max(1.0),
            "{name}: {x1}"
        );
        assert!(
            (y1 - (b[1] + half)).abs() < 1e-3 * half.max(1.0),
            "{name}: {y1}"
        );
        let ll = t.bounds(d.width, d.height).unwrap();
        if name == "bigtujunga_30m" {
            // UTM 11N east of Los Angeles: the San Gabriel Mountains.
            assert!(ll.west > -118.4 && ll.east < -117.9, "{ll:?}");
            assert!(ll.south > 34.2 && ll.north < 34.45, "{ll:?}");
        }
        // Sample for sample the same as the PNG conversion, voids included.
        if let Some(p) = png_twin(name, &car) {
            assert_eq!(p.voids, d.voids, "{name}");
            let same = (0..d.heights.len())
                .filter(|&i| !d.is_void(i))
                .all(|i| d.heights[i] == p.heights[i]);
            assert!(same, "{name}");
        }
    }
}

#[test]
#[ignore = "needs ../shared/dem"]
fn shared_dem_fuji_voids_are_filled_within_their_surroundings() {
    let path = shared("fuji_srtm3/osgearth_mt_fuji_90m.tif");
    let d = load(&path, &LoadOptions::default()).unwrap();
    assert_eq!(d.voids.count(), 2437);
    let (w, h) = (d.width as i64, d.height as i64);
    for i in d.voids.iter() {
        let (x, y) = (i as i64 % w, i as i64 / w);
        // Range of the valid samples within 24 samples.
        let mut r = (f32::MAX, f32::MIN);
        for yy in (y - 24).max(0)..(y + 25).min(h) {
            for xx in (x - 24).max(0)..(x + 25).min(w) {
                let j = (yy * w + xx) as usize;
                if !d.is_void(j) {
                    r = (r.0.min(d.heights[j]), r.1.max(d.heights[j]));
                }
            }
        }
        let v = d.heights[i];
        assert!(
            r.0 > r.1 || (v >= r.0 && v <= r.1),
            "({x}, {y}): {v} outside {r:?}"
        );
    }
}

#[test]
#[ignore = "needs ../shared/dem"]
fn shared_dem_pngs_match_their_sidecars() {
    for name in [
        "fuji_srtm3",
        "bigtujunga_30m",
        "fortworth_plains_pysheds",
        "jacksboro_ridges_mpl",
    ] {
        let path = shared(&format!("{name}/{name}.png"));
        let car = load_sidecar(name);
        let png = PngOptions {
            scale: car["scale"].as_f64().unwrap(),
            offset: car["offset"].as_f64().unwrap(),
            nodata_value: Some(car["nodata_value"].as_u64().unwrap() as u16),
        };
        let s = &car["spacing_m_xy"];
        let (sx, sy) = (s[0].as_f64().unwrap(), s[1].as_f64().unwrap());
        let d = load(
            &path,
            &LoadOptions {
                spacing_x: Some(sx),
                spacing_y: Some(sy),
                png,
                ..LoadOptions::default()
            },
        )
        .unwrap();
        assert_eq!(d.width as u64, car["width"].as_u64().unwrap(), "{name}");
        assert_eq!(d.height as u64, car["height"].as_u64().unwrap(), "{name}");
        assert_eq!(
            d.voids.count(),
            car["nodata_pixels"].as_u64().unwrap(),
            "{name}"
        );
        let (lo, hi) = d.valid_range();
        assert_eq!(lo as f64, car["min_m"].as_f64().unwrap(), "{name}");
        assert_eq!(hi as f64, car["max_m"].as_f64().unwrap(), "{name}");
        assert_eq!((d.spacing_x, d.spacing_y), (sx, sy));
        assert!(d.crs.is_none());
    }
}

#[test]
fn embedded_default_is_the_committed_crop() {
    let d = embedded_default().unwrap();
    assert_eq!((d.width, d.height), (257, 193));
    assert_eq!(d.voids.count(), 50);
    assert_eq!(d.valid_range(), (506.0, 3742.0));
    // 3" at the crop's centre latitude, 35.397 N.
    assert!((d.spacing_x - 75.69).abs() < 0.05, "{}", d.spacing_x);
    assert!((d.spacing_y - 92.46).abs() < 0.05, "{}", d.spacing_y);
    assert_eq!(d.crs.as_deref(), Some("EPSG:4326"));
    // Column 700, row 628 of the original, whose first sample lies at 138 E, 36 N.
    let g = d.georef.clone().expect("the crop's georeference");
    let [lon, lat] = g.model(0.0, 0.0);
    assert!((lon - (138.0 + 700.0 / 1200.0)).abs() < 1e-9, "{lon}");
    assert!((lat - (36.0 - 628.0 / 1200.0)).abs() < 1e-9, "{lat}");
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/fuji_crop.tif");
    let f = load(path, &LoadOptions::default()).unwrap();
    assert_eq!(f.heights, d.heights);
    assert_eq!(f.voids, d.voids);
}

#[test]
#[ignore = "needs ../shared/dem"]
fn shared_dem_committed_crop_is_the_documented_window_of_the_original() {
    let p = shared("fuji_srtm3/osgearth_mt_fuji_90m.tif");
    let full = load(&p, &LoadOptions::default()).unwrap();
    let crop = embedded_default().unwrap();
    // Rows 628..=820, columns 700..=956 (server/data/README.md).
    for y in 0..crop.height {
        for x in 0..crop.width {
            let (i, j) = (
                (y * crop.width + x) as usize,
                ((y + 628) * full.width + x + 700) as usize,
            );
            assert_eq!(crop.is_void(i), full.is_void(j), "void at ({x}, {y})");
            if !crop.is_void(i) {
                assert_eq!(crop.heights[i], full.heights[j], "height at ({x}, {y})");
            }
        }
    }
}

/// The standard formats: the `.hgt` reader on a file made from fuji_srtm3, which is SRTM 3" over
/// 138..139 E, 35..36 N: the same heights, voids, georeference and spacing as the GeoTIFF.
#[test]
#[ignore = "needs ../shared/dem"]
fn shared_dem_fuji_as_hgt_reads_like_the_geotiff() {
    use crate::formats::hgt::{VOID, to_bytes};
    let tif = load(
        &shared("fuji_srtm3/osgearth_mt_fuji_90m.tif"),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!((tif.width, tif.height), (1201, 1201));
    // The GeoTIFF's samples as they were: whole metres, voids -32768.
    let samples: Vec<i16> = (0..tif.heights.len())
        .map(|i| {
            if tif.is_void(i) {
                VOID
            } else {
                let h = tif.heights[i];
                assert_eq!(h, h.round(), "sample {i}");
                h as i16
            }
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("N35E138.hgt");
    std::fs::write(&p, to_bytes(&samples)).unwrap();
    let hgt = load(p.to_str().unwrap(), &LoadOptions::default()).unwrap();
    assert_eq!((hgt.width, hgt.height), (tif.width, tif.height));
    assert_eq!(hgt.voids.count(), 2437);
    assert_eq!(hgt.voids, tif.voids);
    // The same samples, so the same fill.
    assert_eq!(hgt.heights, tif.heights);
    assert_eq!(hgt.crs, tif.crs);
    let (a, b) = (hgt.georef.unwrap(), tif.georef.unwrap());
    assert_eq!(a.epsg, b.epsg);
    assert_eq!(a.first, [138.0, 36.0]);
    for k in 0..2 {
        assert!((a.first[k] - b.first[k]).abs() < 1e-9, "{a:?} {b:?}");
        assert!(close(a.step[k], b.step[k], 1e-12), "{a:?} {b:?}");
    }
    assert!(
        close(hgt.spacing_x, tif.spacing_x, 1e-9),
        "{}",
        hgt.spacing_x
    );
    assert!(
        close(hgt.spacing_y, tif.spacing_y, 1e-9),
        "{}",
        hgt.spacing_y
    );
}

/// The standard formats: real heights (a 256 x 256 window of fuji_srtm3 around the summit) written as
/// terrain-RGB and Terrarium tiles by `terrain_rgb::encode_png` read back by the tile reader
/// within half the encoding's step.
#[test]
#[ignore = "needs ../shared/dem"]
fn shared_dem_fuji_heights_survive_terrain_tiles() {
    use crate::formats::terrain_rgb::{Encoding, encode_png};
    let d = load(
        &shared("fuji_srtm3/osgearth_mt_fuji_90m.tif"),
        &LoadOptions::default(),
    )
    .unwrap();
    let (x0, y0, px) = (700u32, 600u32, 256u32);
    let window: Vec<f32> = (0..px * px)
        .map(|i| d.at(x0 + i % px, y0 + i / px))
        .collect();
    let dir = tempfile::tempdir().unwrap();
    for enc in Encoding::ALL {
        let p = dir.path().join("12-3629-1617.png");
        std::fs::write(&p, encode_png(px, px, &window, enc)).unwrap();
        let opts = LoadOptions {
            encoding: Some(enc),
            ..LoadOptions::default()
        };
        let t = load(p.to_str().unwrap(), &opts).unwrap();
        assert_eq!(t.voids.count(), 0);
        let worst = window
            .iter()
            .zip(&t.heights)
            .map(|(a, b)| (a - b).abs() as f64)
            .fold(0.0, f64::max);
        assert!(worst <= enc.step() / 2.0 + 1e-3, "{enc}: {worst}");
        assert_eq!(t.valid_range(), {
            let lo = window.iter().copied().fold(f32::MAX, f32::min);
            let hi = window.iter().copied().fold(f32::MIN, f32::max);
            (lo, hi)
        });
    }
}
