//! Tests of [`load`]'s dispatch and checks, and helpers for the readers' tests: the real DEMs in
//! `../shared/dem` (present in CI) and TIFFs written on the fly. [`real`] holds the tests on the
//! real DEMs and the committed crop.

mod real;

use super::*;
use tiff::encoder::{TiffEncoder, TiffValue, colortype};
use tiff::tags::Tag;

/// The path of `rel` under the shared DEM folder. Panics where it is absent. The tests on the
/// real DEMs are `#[ignore = "needs ../shared/dem"]` (a clone of the repository has no
/// `../shared`, and a newcomer sees them as ignored, not passed); CI runs them with
/// `cargo test -- --ignored shared_dem_`, and there they must not pass without their data.
pub(crate) fn shared(rel: &str) -> String {
    let p = format!("{}/../../shared/dem/{rel}", env!("CARGO_MANIFEST_DIR"));
    assert!(
        std::path::Path::new(&p).exists(),
        "{p} is absent: this test needs ../shared/dem beside the repository"
    );
    p
}

/// The JSON sidecar of shared DEM `name`.
pub(crate) fn load_sidecar(name: &str) -> serde_json::Value {
    let p = format!(
        "{}/../../shared/dem/{name}/{name}.json",
        env!("CARGO_MANIFEST_DIR")
    );
    serde_json::from_str(&std::fs::read_to_string(&p).expect("sidecar")).expect("sidecar JSON")
}

/// GeoTIFF tags for [`tiff_bytes`].
#[derive(Default)]
pub(crate) struct GeoTags<'a> {
    pub scale: Option<[f64; 3]>,
    pub tie: Option<[f64; 6]>,
    pub matrix: Option<[f64; 16]>,
    pub keys: Option<&'a [u16]>,
    pub nodata: Option<&'a str>,
}

/// A projected grid with 10 m pixels.
pub(crate) const METRES_10: GeoTags<'static> = GeoTags {
    scale: Some([10.0, 10.0, 0.0]),
    tie: None,
    matrix: None,
    keys: None,
    nodata: None,
};

/// Encodes a single-image TIFF of colour type `C` with `tags`.
pub(crate) fn tiff_bytes<C: colortype::ColorType>(
    w: u32,
    h: u32,
    data: &[C::Inner],
    tags: &GeoTags,
) -> Vec<u8>
where
    [C::Inner]: TiffValue,
{
    let mut buf = std::io::Cursor::new(Vec::new());
    let mut enc = TiffEncoder::new(&mut buf).unwrap();
    let mut img = enc.new_image::<C>(w, h).unwrap();
    let e = img.encoder();
    if let Some(s) = tags.scale {
        e.write_tag(Tag::ModelPixelScaleTag, &s[..]).unwrap();
    }
    if let Some(t) = tags.tie {
        e.write_tag(Tag::ModelTiepointTag, &t[..]).unwrap();
    }
    if let Some(m) = tags.matrix {
        e.write_tag(Tag::ModelTransformationTag, &m[..]).unwrap();
    }
    if let Some(k) = tags.keys {
        e.write_tag(Tag::GeoKeyDirectoryTag, k).unwrap();
    }
    if let Some(nd) = tags.nodata {
        e.write_tag(Tag::GdalNodata, nd).unwrap();
    }
    img.write_data(data).unwrap();
    buf.into_inner()
}

/// A float32 TIFF with 10 m pixels and an optional GDAL_NODATA.
fn tiff_f32(w: u32, h: u32, data: &[f32], nodata: Option<&str>) -> Vec<u8> {
    let tags = GeoTags {
        nodata,
        ..METRES_10
    };
    tiff_bytes::<colortype::Gray32Float>(w, h, data, &tags)
}

/// Writes `bytes` to `name` in `dir` and returns the path.
pub(crate) fn write_tmp(dir: &tempfile::TempDir, name: &str, bytes: &[u8]) -> String {
    let p = dir.path().join(name);
    std::fs::write(&p, bytes).unwrap();
    p.display().to_string()
}

fn load_err(path: &str) -> DemError {
    load(path, &LoadOptions::default()).expect_err(path)
}

#[test]
fn unreadable_truncated_and_garbage_files_get_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let e = load_err("/no/such/file.tif");
    assert!(matches!(e, DemError::Io { .. }), "{e}");
    assert!(e.to_string().contains("/no/such/file.tif"), "{e}");

    let data: Vec<f32> = (0..4096).map(|i| i as f32).collect();
    let good = tiff_f32(64, 64, &data, None);
    for cut in [good.len() / 2, 12] {
        let e = load_err(&write_tmp(&dir, "trunc.tif", &good[..cut]));
        assert!(matches!(e, DemError::Corrupt { .. }), "{e}");
        assert!(e.to_string().contains("trunc.tif"), "{e}");
    }
    let e = load_err(&write_tmp(
        &dir,
        "garbage.tif",
        b"this is not a tiff at all",
    ));
    assert!(
        matches!(
            e,
            DemError::Corrupt {
                kind: "GeoTIFF",
                ..
            }
        ),
        "{e}"
    );
    let e = load_err(&write_tmp(&dir, "garbage.png", b"\x89PNG\r\n\x1a\nnope"));
    assert!(matches!(e, DemError::Corrupt { kind: "PNG", .. }), "{e}");
    let e = load_err(&write_tmp(&dir, "heights.dat", b"\0\x01\x02\x03 whatever"));
    assert!(matches!(e, DemError::UnknownFormat { .. }), "{e}");
    let e = load_err(&write_tmp(&dir, "empty.tif", b""));
    assert!(matches!(e, DemError::Corrupt { .. }), "{e}");
    // The first bytes win over a wrong extension.
    let d = load(
        &write_tmp(&dir, "misnamed.png", &good),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!((d.width, d.height), (64, 64));
}

#[test]
fn too_small_and_too_large_grids_are_refused() {
    let opts = LoadOptions::default();
    for (w, h) in [(0, 0), (1, 1), (1, 5), (5, 1)] {
        let e = check_size("x", w, h, &opts).unwrap_err();
        assert!(e.to_string().contains("at least 2x2"), "{e}");
    }
    let dir = tempfile::tempdir().unwrap();
    for (w, h) in [(1u32, 1u32), (3, 1)] {
        let t = tiff_f32(w, h, &vec![5.0; (w * h) as usize], None);
        let e = load_err(&write_tmp(&dir, "small.tif", &t));
        assert!(matches!(e, DemError::TooSmall { .. }), "{e}");
    }
    let t = tiff_f32(8, 8, &[1.0; 64], None);
    let p = write_tmp(&dir, "big.tif", &t);
    let small = LoadOptions {
        max_samples: 63,
        ..LoadOptions::default()
    };
    let e = load(&p, &small).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "{p}: 8x8 = 64 samples exceeds the limit of 63; a build holds it in memory, about \
             0.0 GiB here, so the default limit is what fits in this machine's memory; raise it \
             with --max-samples"
        )
    );
    // The default limit is what a build fits in the memory this process may use.
    let limit = default_max_samples();
    let side = limit.isqrt() as u32;
    assert!(check_size("x", side, side, &opts).is_ok());
    assert!(check_size("x", side + 1, side + 1, &opts).is_err());
    if let Some(m) = crate::sysmem::usable_memory() {
        assert_eq!(limit, m / crate::dem::BUILD_BYTES_PER_SAMPLE);
    }
}

#[test]
fn nodata_nan_infinite_and_absurd_samples() {
    let dir = tempfile::tempdir().unwrap();
    let mut data: Vec<f32> = (0..64).map(|i| 100.0 + i as f32).collect();
    data[9] = -9999.0;
    let d = load(
        &write_tmp(&dir, "ok.tif", &tiff_f32(8, 8, &data, Some("-9999"))),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(d.voids.iter().collect::<Vec<_>>(), vec![9]);
    assert!((100.0..=163.0).contains(&d.heights[9]), "{}", d.heights[9]);

    // Undeclared NaN: an error with a count and the first position.
    data[9] = f32::NAN;
    data[20] = f32::NAN;
    let e = load_err(&write_tmp(&dir, "nan.tif", &tiff_f32(8, 8, &data, None)));
    assert!(
        matches!(
            e,
            DemError::NaN {
                count: 2,
                col: 1,
                row: 1,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("2 NaN samples"), "{e}");
    // NaN declared as no-data: voids.
    let p = write_tmp(&dir, "nan-nodata.tif", &tiff_f32(8, 8, &data, Some("nan")));
    let d = load(&p, &LoadOptions::default()).unwrap();
    assert_eq!(d.voids.iter().collect::<Vec<_>>(), vec![9, 20]);
    assert!(d.heights.iter().all(|h| h.is_finite()));
    // A different no-data value does not excuse NaN.
    let e = load_err(&write_tmp(
        &dir,
        "nan-other.tif",
        &tiff_f32(8, 8, &data, Some("-9999")),
    ));
    assert!(matches!(e, DemError::NaN { count: 2, .. }), "{e}");

    data[20] = 50.0;
    for (bad, name) in [
        (1e7, "absurd"),
        (f32::INFINITY, "inf"),
        (f32::NEG_INFINITY, "-inf"),
        (-20_001.0, "deep"),
    ] {
        data[9] = bad;
        let e = load_err(&write_tmp(
            &dir,
            &format!("{name}.tif"),
            &tiff_f32(8, 8, &data, None),
        ));
        assert!(
            matches!(
                e,
                DemError::Absurd {
                    count: 1,
                    col: 1,
                    row: 1,
                    ..
                }
            ),
            "{name}: {e}"
        );
    }
    // An undeclared -32768 (SRTM's no-data value) is reported, not taken as terrain.
    data[9] = -32768.0;
    let p = write_tmp(&dir, "undeclared.tif", &tiff_f32(8, 8, &data, None));
    assert!(load_err(&p).to_string().contains("undeclared no-data"));

    let all = vec![-9999.0f32; 64];
    let e = load_err(&write_tmp(
        &dir,
        "void.tif",
        &tiff_f32(8, 8, &all, Some("-9999")),
    ));
    assert!(matches!(e, DemError::AllVoid(_)), "{e}");
}

#[test]
fn spacing_overrides_and_their_checks() {
    let dir = tempfile::tempdir().unwrap();
    let p = write_tmp(&dir, "t.tif", &tiff_f32(4, 4, &[7.0; 16], None));
    let opts = |x, y| LoadOptions {
        spacing_x: x,
        spacing_y: y,
        ..LoadOptions::default()
    };
    let d = load(&p, &opts(Some(2.0), None)).unwrap();
    assert_eq!((d.spacing_x, d.spacing_y), (2.0, 10.0));
    let d = load(&p, &opts(Some(2.0), Some(3.0))).unwrap();
    assert_eq!((d.spacing_x, d.spacing_y), (2.0, 3.0));
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = load(&p, &opts(Some(bad), None)).unwrap_err();
        assert!(matches!(e, DemError::Spacing { .. }), "{e}");
    }
}

/// `--origin` places a synthetic terrain on WGS 84 degrees at its ground spacing, and a
/// georeferenced GeoTIFF refuses it.
#[test]
fn origin_places_input_without_a_georeference() {
    let opts = LoadOptions {
        origin: Some((8.5, 47.4)),
        ..LoadOptions::default()
    };
    let d = load("synthetic:65", &opts).unwrap();
    let g = d.georef.expect("a georeference");
    assert_eq!((g.epsg, g.first), (4326, [8.5, 47.4]));
    let (mx, _) = crate::geo::ellipsoid::metres_per_degree(47.4);
    assert!((g.step[0] * mx - d.spacing_x).abs() < 1e-9);
    assert_eq!(d.crs.as_deref(), Some("EPSG:4326"));
    assert!(
        load("synthetic:65", &LoadOptions::default())
            .unwrap()
            .georef
            .is_none()
    );
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/fuji_crop.tif");
    let e = load(path, &opts).unwrap_err().to_string();
    assert!(e.contains("--origin") && e.contains("EPSG:4326"), "{e}");
    let off = LoadOptions {
        origin: Some((0.0, 89.0)),
        ..LoadOptions::default()
    };
    assert!(
        load("synthetic:65", &off)
            .unwrap_err()
            .to_string()
            .contains("latitude")
    );
}

#[test]
fn urls_are_named_without_their_query_strings() {
    // A presigned URL's query holds its credentials: messages and the DEM's name drop it.
    assert_eq!(
        shown_source("https://bucket.example.com/dem.tif?X-Amz-Signature=secret#x + N35E138.hgt"),
        "https://bucket.example.com/dem.tif + N35E138.hgt"
    );
    // A file name may hold a `?` of its own.
    assert_eq!(shown_source("odd?name.tif"), "odd?name.tif");
}
