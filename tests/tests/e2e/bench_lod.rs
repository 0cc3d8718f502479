//! End to end through the library: the committed Fuji crop is built into a store and flown along
//! both paths; every delta crosses the wire codec into a client mirror with incremental fans.
//! The benchmark's integrity counters must all be zero; its figures are not asserted (they are
//! reported by `relief-server bench lod`, not tested).

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
