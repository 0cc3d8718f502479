//! Precedence, address resolution and error messages of the configuration.

use super::*;
use std::io::Write;

#[test]
fn flags_beat_the_file_which_beats_the_defaults() {
    let mut f = tempfile::NamedTempFile::new().unwrap();
    writeln!(
        f,
        "max_sessions = 7\nmax_in_flight = 2\nidle_timeout_s = 1.5"
    )
    .unwrap();
    let args = ServeArgs {
        config: Some(f.path().to_path_buf()),
        max_sessions: Some(9),
        ..ServeArgs::default()
    };
    let c = args.resolve().unwrap();
    assert_eq!(c.limits.max_sessions, 9);
    assert_eq!(c.limits.max_in_flight, 2);
    assert_eq!(c.limits.idle_timeout, Duration::from_millis(1500));
    assert_eq!(
        c.limits.max_sessions_per_ip,
        Limits::default().max_sessions_per_ip
    );
    assert_eq!(c.source, TerrainSource::Embedded);
    assert_eq!(c.addr.to_string(), DEFAULT_ADDR);
}

#[test]
fn host_names_resolve_and_bad_addresses_say_what_to_give() {
    let args = ServeArgs {
        addr: Some("localhost:8080".into()),
        ..ServeArgs::default()
    };
    let c = args.resolve().unwrap();
    assert!(
        c.addr.ip().is_loopback() && c.addr.port() == 8080,
        "{}",
        c.addr
    );
    for bad in ["8080", "localhost", "127.0.0.1:99999"] {
        let args = ServeArgs {
            addr: Some(bad.into()),
            ..ServeArgs::default()
        };
        let e = args.resolve().unwrap_err().to_string();
        assert!(e.contains("HOST:PORT") && e.contains(bad), "{e}");
    }
}

#[test]
fn bad_files_and_values_are_named() {
    let mut f = tempfile::NamedTempFile::new().unwrap();
    writeln!(f, "max_sesions = 7").unwrap();
    let args = ServeArgs {
        config: Some(f.path().to_path_buf()),
        ..ServeArgs::default()
    };
    let e = args.resolve().unwrap_err().to_string();
    assert!(e.contains("max_sesions"), "{e}");

    let args = ServeArgs {
        idle_timeout_s: Some(f64::NAN),
        ..ServeArgs::default()
    };
    assert!(
        args.resolve()
            .unwrap_err()
            .to_string()
            .contains("idle_timeout_s")
    );
    let args = ServeArgs {
        config: Some("/nonexistent/relief.toml".into()),
        ..ServeArgs::default()
    };
    assert!(
        args.resolve()
            .unwrap_err()
            .to_string()
            .contains("cannot read")
    );
}

#[test]
fn connection_limits_follow_the_session_limits_unless_set() {
    let args = ServeArgs {
        max_sessions: Some(20_000),
        max_sessions_per_ip: Some(5000),
        ..ServeArgs::default()
    };
    let c = args.resolve().unwrap();
    assert_eq!(c.limits.max_connections_per_ip, 5100);
    assert_eq!(c.limits.max_connections, 21_000);
    let args = ServeArgs {
        max_connections_per_ip: Some(7),
        body_timeout_s: Some(0.0),
        ..ServeArgs::default()
    };
    assert!(
        args.resolve()
            .unwrap_err()
            .to_string()
            .contains("body_timeout_s")
    );
    let args = ServeArgs {
        max_connections_per_ip: Some(7),
        ..ServeArgs::default()
    };
    let c = args.resolve().unwrap();
    assert_eq!(c.limits.max_connections_per_ip, 7);
    assert_eq!(c.limits.max_connections, Limits::default().max_connections);
}

#[test]
fn a_dem_is_one_spec_or_a_mosaic_from_flags_or_the_file() {
    let mut f = tempfile::NamedTempFile::new().unwrap();
    writeln!(f, "dem = [\"N35E138.hgt\", \"N35E139.hgt\"]").unwrap();
    let file = Some(f.path().to_path_buf());
    let args = ServeArgs {
        config: file.clone(),
        ..ServeArgs::default()
    };
    let TerrainSource::Dem(specs, _) = args.resolve().unwrap().source else {
        panic!("not a DEM")
    };
    assert_eq!(specs, ["N35E138.hgt", "N35E139.hgt"]);
    // Flags beat the file.
    let args = ServeArgs {
        config: file,
        dem: vec!["synthetic:65".into()],
        ..ServeArgs::default()
    };
    let TerrainSource::Dem(specs, _) = args.resolve().unwrap().source else {
        panic!("not a DEM")
    };
    assert_eq!(specs, ["synthetic:65"]);
    let mut f = tempfile::NamedTempFile::new().unwrap();
    writeln!(f, "dem = \"x.tif\"").unwrap();
    let args = ServeArgs {
        config: Some(f.path().to_path_buf()),
        ..ServeArgs::default()
    };
    let TerrainSource::Dem(specs, _) = args.resolve().unwrap().source else {
        panic!("not a DEM")
    };
    assert_eq!(specs, ["x.tif"]);
    let mut f = tempfile::NamedTempFile::new().unwrap();
    writeln!(f, "dem = []").unwrap();
    let args = ServeArgs {
        config: Some(f.path().to_path_buf()),
        ..ServeArgs::default()
    };
    let e = args.resolve().unwrap_err().to_string();
    assert!(e.contains("empty list"), "{e}");
}

#[test]
fn the_web_lib_comes_from_the_flag_then_the_file_then_the_repository() {
    let c = ServeArgs::default().resolve().unwrap();
    assert_eq!(c.web_lib, PathBuf::from(DEFAULT_WEB_LIB));
    assert!(DEFAULT_WEB_LIB.ends_with("/../web/node_modules"));
    let mut f = tempfile::NamedTempFile::new().unwrap();
    writeln!(f, "web_lib = \"/srv/relief/node_modules\"").unwrap();
    let from_file = ServeArgs {
        config: Some(f.path().to_path_buf()),
        ..ServeArgs::default()
    };
    assert_eq!(
        from_file.resolve().unwrap().web_lib,
        PathBuf::from("/srv/relief/node_modules")
    );
    let flag = ServeArgs {
        web_lib: Some("/opt/web".into()),
        ..from_file
    };
    assert_eq!(flag.resolve().unwrap().web_lib, PathBuf::from("/opt/web"));
}
