//! End to end through the library: the committed Fuji crop is built into a store and flown along
//! both paths; every delta crosses the wire codec into a client mirror with incremental fans.
//! The benchmark's integrity counters must all be zero; its figures are not asserted (they are
//! reported by `relief-server bench lod`, not tested). `bench build` must report the store it
//! built and the bytes it read, whatever its timings.

use relief_proto::path::PathKind;
use relief_server::bench::lod::{LodBenchOptions, run};
use relief_server::dem;

#[test]
fn crop_flies_without_cracks_desyncs_or_mismatches() {
    let d = dem::embedded_default().unwrap();
    for path in [PathKind::Standard, PathKind::Stress] {
        let opts = LodBenchOptions {
            path,
            px_every: Some(25),
            oracle_frames: 30,
            ..LodBenchOptions::default()
        };
        let r = run(&d, &opts).unwrap();
        assert_eq!(r.frames, if path == PathKind::Standard { 600 } else { 300 });
        assert_eq!(r.cracks, 0, "{r:?}");
        assert_eq!(r.folds, 0, "{r:?}");
        assert_eq!(r.oracle_mismatches, 0, "{r:?}");
        assert!(r.oracle_checks >= 10, "{r:?}");
        assert_eq!(r.desyncs, 0, "{r:?}");
        assert_eq!(r.paper_pass_mismatches, 0, "{r:?}");
        assert!(r.splits_total > 0 && r.triangles_median > 0.0, "{r:?}");
        // The mesh is measured against the DEM, and the error is finite.
        assert!(
            r.px.px_error_frames >= 12 && r.px.px_error_max.is_finite(),
            "{r:?}"
        );
    }
}

#[test]
fn interleaved_sessions_make_the_same_deltas_as_sessions_alone() {
    // `bench sessions` fails unless every session's deltas are the same both ways.
    use relief_server::bench::sessions::{SessionsBenchOptions, run};
    let d = dem::embedded_default().unwrap();
    let opts = SessionsBenchOptions {
        sessions: 6,
        poses: 30,
        ..SessionsBenchOptions::default()
    };
    let r = run(&d, &opts).unwrap();
    assert_eq!((r.sessions, r.poses, r.updates), (6, 30, 6 * 29), "{r:?}");
    assert!(r.changes_p90 > 0.0 && r.body_bytes_mean > 0.0, "{r:?}");
    assert!(
        r.interleaved_us_mean > 0.0 && r.alone_us_mean > 0.0,
        "{r:?}"
    );
    assert!(r.session_bytes_mean > 0.0, "{r:?}");
}

#[test]
fn bench_build_reports_the_store_it_built_and_the_bytes_it_read() {
    // The embedded crop written out as a GeoTIFF file, so that the read is counted.
    use relief_server::bench::build::{BuildBenchOptions, run};
    let dir = tempfile::tempdir().unwrap();
    let tif = dir.path().join("fuji_crop.tif");
    std::fs::write(&tif, dem::EMBEDDED_FUJI).unwrap();
    let store = dir.path().join("crop.relief");
    let opts = BuildBenchOptions {
        inputs: vec![tif.display().to_string()],
        dem: relief_server::dem::DemArgs {
            quiet: true,
            ..Default::default()
        },
        build: Default::default(),
        threads: Some(2),
        output: Some(store.clone()),
    };
    let r = run(&opts).unwrap();
    assert_eq!(
        (r.width, r.height, r.samples),
        (257, 193, 257 * 193),
        "{r:?}"
    );
    assert_eq!(r.threads, 2);
    assert_eq!(
        r.store_bytes,
        std::fs::metadata(&store).unwrap().len(),
        "{r:?}"
    );
    assert_eq!(r.source_bytes, dem::EMBEDDED_FUJI.len() as u64, "{r:?}");
    // The crop is 257 x 193 uncompressed int16 samples: a whole read reads all of them, and
    // the directory again where the decoder seeks back to it (a few KB), never the file twice.
    let samples_bytes = 257 * 193 * 2;
    assert!(
        r.source_bytes_read >= samples_bytes && r.source_bytes_read < 2 * r.source_bytes,
        "{r:?}"
    );
    assert!(r.peak_rss_bytes > 0 && r.cpu_s > 0.0, "{r:?}");
    let phases = r.read_s + r.tree_s + r.tiles_s + r.write_s;
    assert!((phases - r.total_s).abs() < 1e-6, "{r:?}");
    // The store it kept is the one `build` makes.
    let d = dem::load_all(&[tif.display().to_string()], &Default::default()).unwrap();
    let again = dir.path().join("again.relief");
    relief_server::preprocess::build_store(&d, &again, &Default::default()).unwrap();
    assert_eq!(
        std::fs::read(&store).unwrap(),
        std::fs::read(&again).unwrap()
    );
}
