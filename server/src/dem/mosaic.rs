//! Mosaics: several adjacent georeferenced inputs joined into one grid, e.g. neighbouring SRTM
//! `.hgt` files or the terrain-RGB tiles of one zoom (`relief-server build A B C ...`).
//!
//! Rules:
//! - Every piece must carry its own georeference (`.hgt`, GeoTIFF with geo keys, terrain tiles
//!   by z/x/y); a synthetic terrain or a plain PNG has none and is refused.
//! - All pieces share the CRS, and the grid step within 1e-9 of the first piece's (relative):
//!   SRTM1 and SRTM3 files do not mix, nor do tiles of different zooms or sizes.
//! - All pieces lie on one grid: each one's first sample is a whole number of steps from the
//!   first piece's, within 1e-6 of a step.
//! - The result covers the box around all pieces. Samples no piece covers are voids, filled by
//!   the usual fill ([`super::fill`]) like the pieces' own voids: a missing tile in a rectangle
//!   of tiles becomes a smooth patch, so leave none out where it matters.
//! - Where pieces overlap (neighbouring `.hgt` files share their edge row or column; terrain
//!   tiles do not overlap), the pieces should agree. If they do not, **the later piece on the
//!   command line wins**, and Relief logs a warning with the count and the largest difference.
//!   A void never overwrites a measured sample: where the later piece has a void and an earlier
//!   one a height, the height stays.
//! - The ground spacing is recomputed for the whole (at the latitude of its centre, for WGS 84
//!   degrees and Web Mercator); `--spacing-x` and `--spacing-y` still override it.
//!
//! Joining takes two passes: the first learns each piece's size and place (a GeoTIFF's, local
//! or by URL, from its directory alone; other formats, small by nature, are read and let go),
//! the second reads each piece and copies it into the whole before the next one is read. So a
//! mosaic needs the memory of the result and of its largest piece, not of all the pieces.
//!
//! A folder given as an input stands for the `.tif` and `.tiff` files in it, in name order
//! ([`folder_tiffs`]): a folder of Cloud-Optimized GeoTIFFs is one mosaic, as GDAL's VRTs are
//! used.

use super::{DemError, IoStats, LoadOptions, RawGrid, VoidMask, check_size, read_file};
use crate::geo::Georef;

/// Relative tolerance on the pieces' grid steps.
const STEP_TOLERANCE: f64 = 1e-9;
/// Tolerance, in steps, on the pieces' offsets being whole numbers of steps.
const OFFSET_TOLERANCE: f64 = 1e-6;

/// Reads the files `specs` and joins them into one grid; returns the mosaic's name (the
/// specs joined by ` + `, for messages and store metadata) and its samples.
pub fn join(specs: &[&str], opts: &LoadOptions) -> Result<(String, RawGrid), DemError> {
    let source = specs.join(" + ");
    if opts.tile.is_some() {
        return Err(DemError::BadOptions {
            input: source,
            detail: "--tile places one tile; in a mosaic each tile takes its z/x/y from its \
                     path (.../Z/X/Y.png or Z-X-Y.png)"
                .into(),
        });
    }
    // Pass 1: each piece's size and place.
    let mut pieces = Vec::with_capacity(specs.len());
    for &spec in specs {
        let err = |detail: String| DemError::Mosaic {
            input: spec.into(),
            detail,
        };
        if spec.starts_with("synthetic:") {
            return Err(err(
                "a synthetic terrain has no place on the Earth of its own; a mosaic joins \
                 georeferenced files (SRTM .hgt, GeoTIFFs with geo keys, terrain-RGB or \
                 Terrarium tiles)"
                    .into(),
            ));
        }
        let layout = super::read_layout(spec, opts)?;
        let Some(g) = layout.georef.clone() else {
            return Err(err(
                "it has no georeference (no EPSG code or tie point), so it cannot be placed \
                 beside the others"
                    .into(),
            ));
        };
        pieces.push((spec, g, layout));
    }
    let (first, g0) = (pieces[0].0, pieces[0].1.clone());
    // Each piece's (column, row) offset from the first piece, in samples.
    let mut offsets = Vec::with_capacity(pieces.len());
    for (spec, g, _) in &pieces {
        offsets.push(offset(spec, g, first, &g0)?);
    }
    let min_c = offsets.iter().map(|o| o.0).min().unwrap_or(0);
    let min_r = offsets.iter().map(|o| o.1).min().unwrap_or(0);
    let max_c = pieces
        .iter()
        .zip(&offsets)
        .map(|((_, _, l), o)| o.0 + l.width as i64)
        .max()
        .unwrap_or(0);
    let max_r = pieces
        .iter()
        .zip(&offsets)
        .map(|((_, _, l), o)| o.1 + l.height as i64)
        .max()
        .unwrap_or(0);
    let clamp = |v: i64| u32::try_from(v).unwrap_or(u32::MAX);
    let (w, h) = (clamp(max_c - min_c), clamp(max_r - min_r));
    check_size(&source, w, h, opts)?;
    let n = w as usize * h as usize;
    let mut heights = vec![0.0f32; n];
    let mut measured = VoidMask::new(n);
    let mut io = IoStats::default();
    // Pass 2: each piece read and copied into the whole, one at a time.
    for ((spec, _, layout), &(oc, or)) in pieces.iter().zip(&offsets) {
        let raw = read_file(spec, opts)?;
        if (raw.width, raw.height) != (layout.width, layout.height) {
            return Err(DemError::Mosaic {
                input: spec.to_string(),
                detail: format!(
                    "it was {} x {} samples and is now {} x {}: it changed while the mosaic \
                     was read",
                    layout.width, layout.height, raw.width, raw.height
                ),
            });
        }
        // The directory read in the first pass counts as read; the file, once.
        io += raw.io;
        io.bytes_read += layout.io.bytes_read;
        let (mut differ, mut worst) = (0u64, 0.0f32);
        let (c0, r0) = ((oc - min_c) as usize, (or - min_r) as usize);
        for r in 0..raw.height as usize {
            for c in 0..raw.width as usize {
                let i = r * raw.width as usize + c;
                let v = raw.heights[i];
                if raw.voids.get(i) || (raw.nan_is_void && v.is_nan()) {
                    continue;
                }
                let j = (r0 + r) * w as usize + c0 + c;
                if measured.get(j) && heights[j] != v {
                    differ += 1;
                    worst = worst.max((heights[j] - v).abs());
                }
                heights[j] = v;
                measured.set(j);
            }
        }
        if differ > 0 {
            tracing::warn!(
                "{spec}: {differ} samples it shares with the inputs before it differ from \
                 theirs, by up to {worst} m; its own win"
            );
        }
    }
    let mut voids = VoidMask::new(n);
    for i in 0..n {
        if !measured.get(i) {
            voids.set(i);
        }
    }
    let georef = Georef {
        epsg: g0.epsg,
        first: g0.model(min_c as f64, min_r as f64),
        step: g0.step,
    };
    let spacing = match georef.ground_spacing(h) {
        Some(s) => Ok(s),
        // Projected CRSs: their units are the ground's, the same for every piece.
        None => pieces[0].2.spacing.clone(),
    };
    let raw = RawGrid {
        width: w,
        height: h,
        heights,
        voids,
        spacing,
        crs: Some(georef.crs()),
        georef: Some(georef),
        nan_is_void: false,
        io,
    };
    Ok((source, raw))
}

/// The `.tif` and `.tiff` files directly in the folder `dir`, sorted by name: the pieces of the
/// mosaic a folder stands for. A folder without any is an error, not an empty terrain.
pub fn folder_tiffs(dir: &str) -> Result<Vec<String>, DemError> {
    let io = |source| DemError::Io {
        path: dir.into(),
        source,
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        let tiff = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("tif") || e.eq_ignore_ascii_case("tiff"));
        if tiff && path.is_file() {
            files.push(path.display().to_string());
        }
    }
    if files.is_empty() {
        return Err(DemError::BadOptions {
            input: dir.into(),
            detail: "the folder holds no .tif or .tiff files; a folder input is the mosaic of \
                     the GeoTIFFs in it"
                .into(),
        });
    }
    files.sort();
    Ok(files)
}

/// The offset in whole samples (columns east, rows south) of the grid `g` of `spec` from the
/// first piece's grid `g0`, or why it is not on that grid.
fn offset(spec: &str, g: &Georef, first: &str, g0: &Georef) -> Result<(i64, i64), DemError> {
    let err = |detail: String| DemError::Mosaic {
        input: spec.into(),
        detail,
    };
    if g.epsg != g0.epsg {
        return Err(err(format!(
            "its CRS is {} and that of {first} is {}; the pieces of a mosaic must share a CRS",
            g.crs(),
            g0.crs()
        )));
    }
    let same = |a: f64, b: f64| (a - b).abs() <= STEP_TOLERANCE * b.abs();
    if !(same(g.step[0], g0.step[0]) && same(g.step[1], g0.step[1])) {
        return Err(err(format!(
            "its samples are {} x {} apart and those of {first} {} x {} (in {} units); the \
             pieces of a mosaic must share the grid step (SRTM1 and SRTM3 files do not mix, nor \
             do tiles of different zooms or pixel sizes)",
            g.step[0],
            g.step[1],
            g0.step[0],
            g0.step[1],
            g.crs()
        )));
    }
    let [dc, dr] = g0.sample(g.first[0], g.first[1]);
    let whole = |v: f64| (v - v.round()).abs() <= OFFSET_TOLERANCE;
    if !(whole(dc) && whole(dr)) || dc.abs() > i32::MAX as f64 || dr.abs() > i32::MAX as f64 {
        return Err(err(format!(
            "its first sample lies {dc} columns and {dr} rows from that of {first}, not a \
             whole number of samples: the pieces are not on one grid"
        )));
    }
    Ok((dc.round() as i64, dr.round() as i64))
}

#[cfg(test)]
mod tests {
    use super::super::rgb_tile::tests::{surface, write_tile};
    use super::super::tests::{GeoTags, tiff_bytes, write_tmp};
    use super::super::{Dem, DemError, LoadOptions, load, load_all};
    use crate::formats::hgt::tests::write_hgt;
    use crate::formats::hgt::{SRTM1_SIZE, SRTM3_SIZE, VOID};
    use crate::formats::terrain_rgb::Encoding;
    use crate::geo::mercator::TileId;
    use tiff::encoder::colortype;

    /// Heights of a 2401 x 1201 area at (c, r), 138..140 E, 35..36 N at 3"; a few voids.
    fn whole(c: u32, r: u32) -> i16 {
        if (c, r) == (700, 300) || (c, r) == (1900, 1000) {
            return VOID;
        }
        (((c as f32 / 37.0).sin() * 800.0 + (r as f32 / 53.0).cos() * 600.0) as i16) + 900
    }

    /// The GeoTIFF of `f` over `w` x `h` samples, 3" apart, the first at 138 E, 36 N.
    fn geotiff(w: u32, h: u32, f: impl Fn(u32, u32) -> i16) -> Vec<u8> {
        let step = 1.0 / 1200.0;
        let keys = [1u16, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326];
        let tags = GeoTags {
            scale: Some([step, step, 0.0]),
            // Pixels are areas: the tie point is the north-west pixel's corner.
            tie: Some([0.0, 0.0, 0.0, 138.0 - step / 2.0, 36.0 + step / 2.0, 0.0]),
            keys: Some(&keys),
            nodata: Some("-32768"),
            ..GeoTags::default()
        };
        let v: Vec<i16> = (0..w * h).map(|i| f(i % w, i / w)).collect();
        tiff_bytes::<colortype::GrayI16>(w, h, &v, &tags)
    }

    fn assert_same(a: &Dem, b: &Dem, tol: f64) {
        assert_eq!((a.width, a.height), (b.width, b.height));
        assert_eq!(a.voids, b.voids);
        assert_eq!(a.heights, b.heights);
        let (ga, gb) = (a.georef.as_ref().unwrap(), b.georef.as_ref().unwrap());
        assert_eq!(ga.epsg, gb.epsg);
        for k in 0..2 {
            assert!((ga.first[k] - gb.first[k]).abs() <= tol, "{ga:?} {gb:?}");
            assert!(
                (ga.step[k] - gb.step[k]).abs() <= tol * 1e-3,
                "{ga:?} {gb:?}"
            );
        }
        assert!((a.spacing_x - b.spacing_x).abs() < 1e-6 * b.spacing_x);
        assert!((a.spacing_y - b.spacing_y).abs() < 1e-6 * b.spacing_y);
    }

    #[test]
    fn two_hgt_files_make_the_whole() {
        let dir = tempfile::tempdir().unwrap();
        let n = SRTM3_SIZE;
        // The west file has a void on the shared column where the east one has a height, and
        // the east one a void where the west one has a height: the heights stay.
        let west = write_hgt(dir.path(), "N35E138.hgt", n, |c, r| match (c, r) {
            (1200, 10) => VOID,
            _ => whole(c, r),
        });
        let east = write_hgt(dir.path(), "N35E139.hgt", n, |c, r| match (c, r) {
            (0, 20) => VOID,
            _ => whole(c + 1200, r),
        });
        // The whole area as one GeoTIFF, the reference.
        let tif = geotiff(2401, 1201, whole);
        let opts = LoadOptions::default();
        let w = load(&write_tmp(&dir, "whole.tif", &tif), &opts).unwrap();
        let m = load_all(&[&west, &east], &opts).unwrap();
        assert_eq!(m.source, format!("{west} + {east}"));
        assert_eq!(m.voids.count(), 2);
        assert_same(&m, &w, 1e-9);
        // The order does not matter where the pieces agree.
        let m2 = load_all(&[&east, &west], &opts).unwrap();
        assert_same(&m2, &w, 1e-9);
        assert_eq!(m2.georef.unwrap().first, [138.0, 36.0]);
    }

    #[test]
    fn a_folder_is_the_mosaic_of_its_geotiffs_in_name_order() {
        let dir = tempfile::tempdir().unwrap();
        let step = 1.0 / 1200.0;
        let keys = [1u16, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326];
        // Columns c0.. of the whole, w wide; the pieces share column 30.
        let piece = |c0: u32, w: u32| {
            let west = 138.0 - step / 2.0 + c0 as f64 * step;
            let tags = GeoTags {
                scale: Some([step, step, 0.0]),
                tie: Some([0.0, 0.0, 0.0, west, 36.0 + step / 2.0, 0.0]),
                keys: Some(&keys),
                ..GeoTags::default()
            };
            let v: Vec<i16> = (0..w * 40).map(|i| whole(c0 + i % w, i / w)).collect();
            tiff_bytes::<colortype::GrayI16>(w, 40, &v, &tags)
        };
        let folder = dir.path().join("cogs");
        std::fs::create_dir(&folder).unwrap();
        std::fs::write(folder.join("b.tif"), piece(30, 30)).unwrap();
        std::fs::write(folder.join("a.TIF"), piece(0, 31)).unwrap();
        std::fs::write(folder.join("notes.txt"), "not a DEM").unwrap();
        let opts = LoadOptions::default();
        let whole_tif = write_tmp(&dir, "whole.tif", &geotiff(60, 40, whole));
        let reference = load(&whole_tif, &opts).unwrap();
        let f = folder.display().to_string();
        for d in [load(&f, &opts).unwrap(), load_all(&[&f], &opts).unwrap()] {
            assert_eq!(d.source, format!("{f}/a.TIF + {f}/b.tif"));
            assert_same(&d, &reference, 1e-9);
        }
        let empty = dir.path().join("empty");
        std::fs::create_dir(&empty).unwrap();
        let e = load_all(&[empty.to_str().unwrap()], &opts).unwrap_err();
        assert!(matches!(e, DemError::BadOptions { .. }), "{e}");
        assert!(e.to_string().contains("no .tif or .tiff files"), "{e}");
    }

    #[test]
    fn where_pieces_disagree_the_later_wins() {
        let dir = tempfile::tempdir().unwrap();
        let n = SRTM3_SIZE;
        let a = write_hgt(dir.path(), "N35E138.hgt", n, |_, _| 100);
        let b = write_hgt(dir.path(), "N36E138.hgt", n, |_, _| 200);
        let opts = LoadOptions::default();
        // b lies north of a; they share a's first row (36 N).
        let ab = load_all(&[&a, &b], &opts).unwrap();
        let ba = load_all(&[&b, &a], &opts).unwrap();
        assert_eq!((ab.width, ab.height), (1201, 2401));
        assert_eq!(
            (ab.at(5, 1199), ab.at(5, 1200), ab.at(5, 1201)),
            (200.0, 200.0, 100.0)
        );
        assert_eq!(ba.at(5, 1200), 100.0);
        assert_eq!(ab.georef.unwrap().first, [138.0, 37.0]);
    }

    #[test]
    fn gaps_between_pieces_are_voids_and_filled() {
        let dir = tempfile::tempdir().unwrap();
        let n = SRTM3_SIZE;
        // Diagonal neighbours: the other two cells of the 2 x 2 box are gaps.
        let a = write_hgt(dir.path(), "N35E138.hgt", n, |_, _| 100);
        let b = write_hgt(dir.path(), "N36E139.hgt", n, |_, _| 300);
        let d = load_all(&[&a, &b], &LoadOptions::default()).unwrap();
        assert_eq!((d.width, d.height), (2401, 2401));
        // Each gap is 1200 x 1200 samples less the corner sample the pieces share.
        assert_eq!(d.voids.count(), 2 * 1200 * 1200);
        assert!(d.is_void(0) && !d.is_void(2400));
        let v = d.at(600, 600);
        assert!((100.0..=300.0).contains(&v), "{v}");
    }

    #[test]
    fn four_tiles_make_their_parent() {
        let dir = tempfile::tempdir().unwrap();
        for enc in Encoding::ALL {
            let parent = TileId::new(4, 10, 5).unwrap();
            let whole = write_tile(dir.path(), parent, 32, enc, surface);
            let kids: Vec<String> = [(20, 10), (21, 10), (20, 11), (21, 11)]
                .into_iter()
                .map(|(x, y)| {
                    let t = TileId::new(5, x, y).unwrap();
                    write_tile(dir.path(), t, 16, enc, surface)
                })
                .collect();
            let opts = LoadOptions {
                encoding: Some(enc),
                ..LoadOptions::default()
            };
            let w = load(&whole, &opts).unwrap();
            // In any order.
            for order in [[0, 1, 2, 3], [3, 1, 0, 2]] {
                let specs: Vec<&str> = order.iter().map(|&i| kids[i].as_str()).collect();
                let m = load_all(&specs, &opts).unwrap();
                assert_same(&m, &w, 1e-6);
                assert_eq!(m.crs.as_deref(), Some("EPSG:3857"));
            }
            // Two tiles side by side.
            let m = load_all(&[&kids[0], &kids[1]], &opts).unwrap();
            assert_eq!((m.width, m.height, m.voids.count()), (32, 16, 0));
            assert_eq!(&m.heights[..32], &w.heights[..32]);
        }
    }

    #[test]
    fn pieces_that_do_not_fit_are_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let opts = LoadOptions::default();
        let a = write_hgt(dir.path(), "N35E138.hgt", SRTM3_SIZE, |_, _| 100);
        let fine = write_hgt(dir.path(), "N35E139.hgt", SRTM1_SIZE, |_, _| 100);
        let e = load_all(&[&a, &fine], &opts).unwrap_err();
        assert!(matches!(e, DemError::Mosaic { .. }), "{e}");
        let m = e.to_string();
        assert!(
            m.starts_with(&fine) && m.contains("grid step") && m.contains(&a),
            "{m}"
        );

        let enc = Encoding::Terrarium;
        let tile = write_tile(
            dir.path(),
            TileId::new(5, 20, 10).unwrap(),
            16,
            enc,
            surface,
        );
        let with = LoadOptions {
            encoding: Some(enc),
            ..LoadOptions::default()
        };
        // An .hgt (EPSG:4326) and a tile (EPSG:3857): --encoding is refused by the .hgt
        // first.
        let e = load_all(&[&tile, &a], &with).unwrap_err();
        assert!(e.to_string().contains("--encoding"), "{e}");
        // Tiles of two sizes.
        let big = write_tile(
            dir.path(),
            TileId::new(5, 21, 10).unwrap(),
            32,
            enc,
            surface,
        );
        let e = load_all(&[&tile, &big], &with).unwrap_err();
        assert!(e.to_string().contains("grid step"), "{e}");
        // --tile with several tiles.
        let one = LoadOptions {
            tile: TileId::new(5, 20, 10).ok(),
            ..with.clone()
        };
        let e = load_all(&[&tile, &tile], &one).unwrap_err();
        assert!(e.to_string().contains("--tile"), "{e}");

        // Another CRS: a GeoTIFF in EPSG:4326 beside a UTM one.
        let utm = [1u16, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 32654];
        let tags = GeoTags {
            scale: Some([30.0, 30.0, 0.0]),
            tie: Some([0.0, 0.0, 0.0, 300_000.0, 3_900_000.0, 0.0]),
            keys: Some(&utm),
            ..GeoTags::default()
        };
        let u = write_tmp(
            &dir,
            "utm.tif",
            &tiff_bytes::<colortype::Gray32Float>(4, 4, &[1.0; 16], &tags),
        );
        let e = load_all(&[&a, &u], &opts).unwrap_err();
        let m = e.to_string();
        assert!(m.contains("EPSG:32654") && m.contains("EPSG:4326"), "{m}");
        // Off the grid: half a pixel east.
        let tags = GeoTags {
            tie: Some([0.0, 0.0, 0.0, 300_015.0, 3_900_000.0, 0.0]),
            ..tags
        };
        let off = write_tmp(
            &dir,
            "off.tif",
            &tiff_bytes::<colortype::Gray32Float>(4, 4, &[1.0; 16], &tags),
        );
        let e = load_all(&[&u, &off], &opts).unwrap_err();
        let m = e.to_string();
        assert!(m.starts_with(&off) && m.contains("0.5 columns"), "{m}");
        // No georeference, or a synthetic terrain.
        let plain = write_tmp(
            &dir,
            "plain.tif",
            &tiff_bytes::<colortype::Gray32Float>(4, 4, &[1.0; 16], &GeoTags::default()),
        );
        let e = load_all(&[&a, &plain], &opts).unwrap_err();
        assert!(e.to_string().contains("no georeference"), "{e}");
        let e = load_all(&[a.as_str(), "synthetic:33"], &opts).unwrap_err();
        assert!(e.to_string().contains("synthetic"), "{e}");
        // Nothing.
        let none: [&str; 0] = [];
        assert!(load_all(&none, &opts).is_err());
        // A mosaic too large for --max-samples is refused before it is allocated.
        let b = write_hgt(dir.path(), "N36E139.hgt", SRTM3_SIZE, |_, _| 100);
        let small = LoadOptions {
            max_samples: 2 * 1201 * 1201,
            ..LoadOptions::default()
        };
        let e = load_all(&[&a, &b], &small).unwrap_err();
        assert!(matches!(e, DemError::TooLarge { .. }), "{e}");
    }
}
