//! Readers on the real DEMs in `../shared/dem` (present in CI) and the committed crop, plus
//! corrupt and absurd input.

use super::*;

fn shared(rel: &str) -> Option<String> {
    let p = format!("{}/../../shared/dem/{rel}", env!("CARGO_MANIFEST_DIR"));
    if Path::new(&p).exists() {
        Some(p)
    } else {
        eprintln!("skipping: {p} is not here (it is in CI)");
        None
    }
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs()
}

fn range(d: &Dem) -> (f32, f32) {
    d.heights
        .iter()
        .enumerate()
        .filter(|(i, _)| !d.is_void(*i))
        .fold((f32::MAX, f32::MIN), |(a, b), (_, &h)| (a.min(h), b.max(h)))
}

#[test]
fn fuji_geotiff_int16_with_voids() {
    let Some(p) = shared("fuji_srtm3/osgearth_mt_fuji_90m.tif") else {
        return;
    };
    let d = load(&p, &LoadOptions::default()).unwrap();
    assert_eq!((d.width, d.height), (1201, 1201));
    assert_eq!(d.voids.count(), 2437);
    assert!(close(d.spacing_x, 75.61, 0.01), "{}", d.spacing_x);
    assert!(close(d.spacing_y, 92.46, 0.01), "{}", d.spacing_y);
    assert_eq!(range(&d), (-16.0, 3742.0));
    assert_eq!(d.crs.as_deref(), Some("EPSG:4326"));
    // Filled voids stay within the terrain's range: no spikes.
    let (lo, hi) = range(&d);
    for (i, h) in d.heights.iter().enumerate() {
        if d.is_void(i) {
            assert!(*h >= lo - 1.0 && *h <= hi + 1.0, "fill {h}");
        }
    }
}

#[test]
fn projected_and_other_geographic_geotiffs() {
    if let Some(p) = shared("bigtujunga_30m/ttb_bigtujunga.tif") {
        let d = load(&p, &LoadOptions::default()).unwrap();
        assert_eq!((d.width, d.height), (1197, 643));
        assert!(close(d.spacing_x, 30.0, 0.01) && close(d.spacing_y, 30.0, 0.01));
        assert_eq!(range(&d), (315.0, 2295.0));
        assert_eq!(d.voids.count(), 0);
    }
    if let Some(p) = shared("fortworth_plains_pysheds/pysheds_dem.tif") {
        let d = load(&p, &LoadOptions::default()).unwrap();
        assert_eq!((d.width, d.height), (367, 359));
        assert!(close(d.spacing_x, 78.16, 0.01), "{}", d.spacing_x);
        assert!(close(d.spacing_y, 92.42, 0.01), "{}", d.spacing_y);
        assert_eq!(range(&d), (147.0, 298.0));
    }
}

#[test]
fn png_with_scale_offset_and_spacing() {
    let Some(p) = shared("fuji_srtm3/fuji_srtm3.png") else {
        return;
    };
    let opts = LoadOptions {
        spacing_x: Some(75.61),
        spacing_y: Some(92.46),
        png: PngOptions {
            scale: 1.0,
            offset: -17.0,
            nodata_value: Some(0),
        },
        ..LoadOptions::default()
    };
    let d = load(&p, &opts).unwrap();
    assert_eq!((d.width, d.height), (1201, 1201));
    assert_eq!(d.voids.count(), 2437);
    assert_eq!(range(&d), (-16.0, 3742.0));
    // Same samples as the GeoTIFF original.
    if let Some(t) = shared("fuji_srtm3/osgearth_mt_fuji_90m.tif") {
        let g = load(&t, &LoadOptions::default()).unwrap();
        assert_eq!(g.heights, d.heights);
    }
    // Spacing is required for PNG.
    let e = load(&p, &LoadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("--spacing-x"), "{e}");
}

#[test]
fn committed_crop_and_embedded_default() {
    let d = embedded_default().unwrap();
    assert_eq!((d.width, d.height), (257, 193));
    assert_eq!(d.voids.count(), 50);
    assert_eq!(range(&d).1, 3742.0);
    assert!(close(d.spacing_x, 75.6, 0.01) && close(d.spacing_y, 92.46, 0.01));
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/fuji_crop.tif");
    assert_eq!(
        load(path, &LoadOptions::default()).unwrap().heights,
        d.heights
    );
}

fn write_tmp(dir: &tempfile::TempDir, name: &str, bytes: &[u8]) -> String {
    let p = dir.path().join(name);
    std::fs::write(&p, bytes).unwrap();
    p.display().to_string()
}

fn tiff_f32(w: u32, h: u32, data: &[f32], nodata: Option<&str>) -> Vec<u8> {
    use tiff::encoder::{TiffEncoder, colortype};
    let mut buf = std::io::Cursor::new(Vec::new());
    let mut enc = TiffEncoder::new(&mut buf).unwrap();
    let mut img = enc.new_image::<colortype::Gray32Float>(w, h).unwrap();
    img.encoder()
        .write_tag(
            tiff::tags::Tag::ModelPixelScaleTag,
            &[10.0f64, 10.0, 0.0][..],
        )
        .unwrap();
    if let Some(nd) = nodata {
        img.encoder()
            .write_tag(tiff::tags::Tag::GdalNodata, nd)
            .unwrap();
    }
    img.write_data(data).unwrap();
    buf.into_inner()
}

#[test]
fn float32_geotiff_nodata_nan_and_absurd_values() {
    let dir = tempfile::tempdir().unwrap();
    let mut data: Vec<f32> = (0..64).map(|i| 100.0 + i as f32).collect();
    data[9] = -9999.0;
    let p = write_tmp(&dir, "ok.tif", &tiff_f32(8, 8, &data, Some("-9999")));
    let d = load(&p, &LoadOptions::default()).unwrap();
    assert_eq!(d.voids.count(), 1);
    assert_eq!((d.spacing_x, d.spacing_y), (10.0, 10.0));

    data[9] = f32::NAN;
    let p = write_tmp(&dir, "nan.tif", &tiff_f32(8, 8, &data, None));
    let e = load(&p, &LoadOptions::default()).unwrap_err();
    assert!(
        matches!(
            e,
            DemError::NaN {
                count: 1,
                col: 1,
                row: 1,
                ..
            }
        ),
        "{e}"
    );
    let p = write_tmp(&dir, "nan-nodata.tif", &tiff_f32(8, 8, &data, Some("nan")));
    assert_eq!(load(&p, &LoadOptions::default()).unwrap().voids.count(), 1);

    data[9] = 1e7;
    let p = write_tmp(&dir, "absurd.tif", &tiff_f32(8, 8, &data, None));
    assert!(matches!(
        load(&p, &LoadOptions::default()),
        Err(DemError::Absurd { .. })
    ));
    data[9] = f32::INFINITY;
    let p = write_tmp(&dir, "inf.tif", &tiff_f32(8, 8, &data, None));
    assert!(matches!(
        load(&p, &LoadOptions::default()),
        Err(DemError::Absurd { .. })
    ));

    let all = vec![-9999.0f32; 64];
    let p = write_tmp(&dir, "void.tif", &tiff_f32(8, 8, &all, Some("-9999")));
    assert!(matches!(
        load(&p, &LoadOptions::default()),
        Err(DemError::AllVoid(_))
    ));
}

#[test]
fn bad_files_get_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let data: Vec<f32> = (0..64).map(|i| i as f32).collect();
    let good = tiff_f32(8, 8, &data, None);
    let p = write_tmp(&dir, "trunc.tif", &good[..good.len() / 2]);
    let e = load(&p, &LoadOptions::default()).unwrap_err();
    assert!(matches!(e, DemError::Corrupt { .. }), "{e}");
    let p = write_tmp(&dir, "garbage.tif", b"this is not a tiff at all");
    assert!(matches!(
        load(&p, &LoadOptions::default()),
        Err(DemError::Corrupt { .. })
    ));
    let p = write_tmp(&dir, "garbage.png", b"\x89PNG\r\n\x1a\nnope");
    assert!(matches!(
        load(&p, &LoadOptions::default()),
        Err(DemError::Corrupt { .. })
    ));
    let e = load("/no/such/file.tif", &LoadOptions::default()).unwrap_err();
    assert!(matches!(e, DemError::Io { .. }), "{e}");

    let one = tiff_f32(1, 1, &[5.0], None);
    let p = write_tmp(&dir, "one.tif", &one);
    assert!(matches!(
        load(&p, &LoadOptions::default()),
        Err(DemError::TooSmall { .. })
    ));
    let small = LoadOptions {
        max_samples: 10,
        ..LoadOptions::default()
    };
    let p = write_tmp(&dir, "big.tif", &good);
    let e = load(&p, &small).unwrap_err();
    assert!(e.to_string().contains("--max-samples"), "{e}");
    assert!(matches!(
        load("synthetic:0", &LoadOptions::default()),
        Err(DemError::TooSmall { .. })
    ));
    assert!(matches!(
        load("synthetic:x", &LoadOptions::default()),
        Err(DemError::BadSpec { .. })
    ));
    assert!(matches!(
        load("synthetic:20000", &LoadOptions::default()),
        Err(DemError::BadSpec { .. })
    ));
}

#[test]
fn voids_in_a_ramp_are_filled_smoothly() {
    let (w, h) = (40u32, 30u32);
    let ramp: Vec<f32> = (0..w * h)
        .map(|i| (i % w) as f32 * 2.0 + (i / w) as f32)
        .collect();
    let mut voids = VoidMask::new(ramp.len());
    let mut heights = ramp.clone();
    for y in 10..20 {
        for x in 12..25 {
            let i = (y * w + x) as usize;
            voids.set(i);
            heights[i] = 1e9;
        }
    }
    fill::fill_voids(w, h, &mut heights, &voids, false);
    for i in 0..ramp.len() {
        if voids.get(i) {
            // Within the range of the surrounding valid ramp, and close to the ramp itself.
            assert!(
                heights[i] >= 24.0 - 1e-3 && heights[i] <= 48.0 + 20.0,
                "{}",
                heights[i]
            );
            assert!(
                (heights[i] - ramp[i]).abs() < 6.0,
                "{} vs {}",
                heights[i],
                ramp[i]
            );
        }
    }
}

#[test]
fn synthetic_is_deterministic_and_looks_like_terrain() {
    let a = load("synthetic:600:3", &LoadOptions::default()).unwrap();
    let b = load("synthetic:600:3", &LoadOptions::default()).unwrap();
    let c = load("synthetic:600:4", &LoadOptions::default()).unwrap();
    assert_eq!(a.heights, b.heights);
    assert_ne!(a.heights, c.heights);
    assert_eq!(
        load("synthetic:2", &LoadOptions::default())
            .unwrap()
            .heights
            .len(),
        4
    );
    let (lo, hi) = range(&a);
    assert!(hi - lo > 300.0, "relief {lo}..{hi}");
    // Both flat and steep parts: slopes between neighbours span a wide range.
    let slopes: Vec<f32> = (0..599 * 600)
        .filter(|i| i % 600 != 599)
        .map(|i| (a.heights[i + 1] - a.heights[i]).abs() / 10.0)
        .collect();
    let flat = slopes.iter().filter(|&&s| s < 0.02).count() as f32 / slopes.len() as f32;
    let steep = slopes.iter().filter(|&&s| s > 0.3).count() as f32 / slopes.len() as f32;
    assert!(flat > 0.05 && steep > 0.005, "flat {flat}, steep {steep}");
}
