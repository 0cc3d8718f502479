//! SRTM `.hgt` files: a square grid of big-endian signed 16-bit heights in metres, row 0 at the
//! north, no header. The size follows from the file's length: 1201 x 1201 samples
//! ([`SRTM3_SIZE`], 3 arc-seconds apart) or 3601 x 3601 ([`SRTM1_SIZE`], 1 arc-second); other
//! lengths are refused. -32768 marks voids.
//!
//! The file carries no georeference: its name does. `N35E138.hgt` covers the one-degree cell
//! whose south-west corner is 35 N, 138 E (`S`/`W` for south and west; the name may go on after
//! the seven characters, as in `N35E138.SRTMGL1.hgt`). Samples are points on whole multiples of
//! the step, and the cell's edges are samples, so neighbouring files share their edge row or
//! column: the first (north-west) sample lies at 138 E, 36 N, the last (south-east) at 139 E,
//! 35 N, in WGS 84 (EPSG:4326). The ground spacing is the step in metres at the cell's centre
//! latitude ([`metres_per_degree`]).

use crate::dem::{DemError, LoadOptions, RawGrid, VoidMask, check_size};
use crate::geo::Georef;
use crate::geo::ellipsoid::metres_per_degree;
use crate::geo::georef::EPSG_WGS84;
use std::io::Read;

/// Samples a side of an SRTM3 (3 arc-second) file.
pub const SRTM3_SIZE: u32 = 1201;
/// Samples a side of an SRTM1 (1 arc-second) file.
pub const SRTM1_SIZE: u32 = 3601;
/// The value of voids.
pub const VOID: i16 = i16::MIN;

/// The samples a side of an `.hgt` file of `len` bytes, if it is one of the two sizes.
pub fn size_of_len(len: u64) -> Option<u32> {
    [SRTM3_SIZE, SRTM1_SIZE]
        .into_iter()
        .find(|&n| n as u64 * n as u64 * 2 == len)
}

/// The south-west corner (latitude, longitude, whole degrees) an `.hgt` file's name gives:
/// `N35E138...` is (35, 138), `S12W077...` is (-12, -77). `None` if the name (the last
/// component of `path`) does not start so, or names a cell off the globe.
pub fn parse_name(path: &str) -> Option<(i32, i32)> {
    let name = std::path::Path::new(path).file_name()?.to_str()?;
    let b = name.as_bytes();
    if b.len() < 7 || b.get(7).is_some_and(u8::is_ascii_digit) {
        return None;
    }
    let num = |r: std::ops::Range<usize>| -> Option<i32> {
        let s = name.get(r)?;
        s.bytes()
            .all(|c| c.is_ascii_digit())
            .then(|| s.parse().ok())?
    };
    let lat = match b[0].to_ascii_uppercase() {
        b'N' => num(1..3)?,
        b'S' => -num(1..3)?,
        _ => return None,
    };
    let lon = match b[3].to_ascii_uppercase() {
        b'E' => num(4..7)?,
        b'W' => -num(4..7)?,
        _ => return None,
    };
    ((-90..=89).contains(&lat) && (-180..=179).contains(&lon)).then_some((lat, lon))
}

/// Where the samples of an `.hgt` file of `size` samples a side, whose name gives the
/// south-west corner `lat`, `lon`, lie: the first at (`lon`, `lat` + 1), `1 / (size - 1)`
/// degrees apart.
pub fn georef(lat: i32, lon: i32, size: u32) -> Georef {
    let step = 1.0 / (size - 1) as f64;
    Georef {
        epsg: EPSG_WGS84,
        first: [lon as f64, lat as f64 + 1.0],
        step: [step, step],
    }
}

/// The bytes of an `.hgt` file holding `samples` (row-major, row 0 north; voids [`VOID`]).
pub fn to_bytes(samples: &[i16]) -> Vec<u8> {
    samples.iter().flat_map(|v| v.to_be_bytes()).collect()
}

/// Reads an `.hgt` file of `len` bytes from `reader`; `path` (its name) places it and is used
/// in messages.
pub fn read<R: Read>(
    path: &str,
    len: u64,
    mut reader: R,
    opts: &LoadOptions,
) -> Result<RawGrid, DemError> {
    let Some(n) = size_of_len(len) else {
        return Err(DemError::Corrupt {
            path: path.into(),
            kind: "SRTM .hgt",
            detail: format!(
                "{len} bytes; an .hgt file holds {a}x{a} (SRTM3, 3 arc-second: {} bytes) or \
                 {b}x{b} (SRTM1, 1 arc-second: {} bytes) big-endian 16-bit samples",
                size_bytes(SRTM3_SIZE),
                size_bytes(SRTM1_SIZE),
                a = SRTM3_SIZE,
                b = SRTM1_SIZE,
            ),
        });
    };
    let Some((lat, lon)) = parse_name(path) else {
        return Err(DemError::Place {
            input: path.into(),
            detail: "an SRTM .hgt file is placed by its name, which must start with the \
                     south-west corner of its one-degree cell, as in N35E138.hgt or S12W077.hgt \
                     (N or S and two digits of latitude, E or W and three of longitude); keep the \
                     name the file was published with"
                .into(),
        });
    };
    check_size(path, n, n, opts)?;
    let mut bytes = vec![0u8; len as usize];
    reader
        .read_exact(&mut bytes)
        .map_err(|source| DemError::Io {
            path: path.into(),
            source,
        })?;
    let mut voids = VoidMask::new(n as usize * n as usize);
    let heights = bytes
        .chunks_exact(2)
        .enumerate()
        .map(|(i, b)| {
            let v = i16::from_be_bytes([b[0], b[1]]);
            if v == VOID {
                voids.set(i);
            }
            v as f32
        })
        .collect();
    let g = georef(lat, lon, n);
    let (mx, my) = metres_per_degree(lat as f64 + 0.5);
    Ok(RawGrid {
        width: n,
        height: n,
        heights,
        voids,
        spacing: Ok((g.step[0] * mx, g.step[1] * my)),
        crs: Some(g.crs()),
        georef: Some(g),
        nan_is_void: false,
        io: Default::default(),
    })
}

/// The length of an `.hgt` file of `n` x `n` samples.
fn size_bytes(n: u32) -> u64 {
    n as u64 * n as u64 * 2
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::dem::{LoadOptions, load};

    /// Writes an `.hgt` file named `name` in `dir` whose sample (c, r) is `f(c, r)`.
    pub(crate) fn write_hgt(
        dir: &std::path::Path,
        name: &str,
        n: u32,
        f: impl Fn(u32, u32) -> i16,
    ) -> String {
        let v: Vec<i16> = (0..n * n).map(|i| f(i % n, i / n)).collect();
        let p = dir.join(name);
        std::fs::write(&p, to_bytes(&v)).unwrap();
        p.display().to_string()
    }

    #[test]
    fn names_give_the_south_west_corner() {
        assert_eq!(parse_name("N35E138.hgt"), Some((35, 138)));
        assert_eq!(parse_name("/data/srtm/s12w077.hgt"), Some((-12, -77)));
        assert_eq!(parse_name("N00W180.SRTMGL1.hgt"), Some((0, -180)));
        assert_eq!(parse_name("S90E179.hgt"), Some((-90, 179)));
        for bad in [
            "fuji.hgt",
            "N35E13.hgt",
            "N35E1380.hgt",
            "X35E138.hgt",
            "N35Q138.hgt",
            "N90E000.hgt",
            "N35E180.hgt",
            "N3aE138.hgt",
            "N+5E138.hgt",
            "",
        ] {
            assert_eq!(parse_name(bad), None, "{bad}");
        }
        assert_eq!(size_of_len(1201 * 1201 * 2), Some(1201));
        assert_eq!(size_of_len(3601 * 3601 * 2), Some(3601));
        assert_eq!(size_of_len(1201 * 1201 * 2 - 2), None);
    }

    #[test]
    fn hgt_files_read_with_voids_and_their_place() {
        let dir = tempfile::tempdir().unwrap();
        let f = |c: u32, r: u32| match (c, r) {
            (5, 7) | (600, 600) => VOID,
            _ => (c as i32 - r as i32).clamp(-500, 3000) as i16,
        };
        let p = write_hgt(dir.path(), "S12W077.hgt", SRTM3_SIZE, f);
        let d = load(&p, &LoadOptions::default()).unwrap();
        assert_eq!((d.width, d.height), (1201, 1201));
        assert_eq!(
            d.voids.iter().collect::<Vec<_>>(),
            vec![7 * 1201 + 5, 600 * 1201 + 600]
        );
        assert_eq!(d.at(1200, 0), 1200.0);
        assert_eq!(d.at(0, 300), -300.0);
        assert_eq!(d.crs.as_deref(), Some("EPSG:4326"));
        let g = d.georef.clone().unwrap();
        assert_eq!(g.first, [-77.0, -11.0]);
        assert_eq!(g.model(1200.0, 1200.0), [-76.0, -12.0]);
        // 3" at 11.5 S: about 92 m north-south, 91 m east-west.
        let (mx, my) = metres_per_degree(-11.5);
        assert!((d.spacing_x - mx / 1200.0).abs() < 1e-9, "{}", d.spacing_x);
        assert!((d.spacing_y - my / 1200.0).abs() < 1e-9, "{}", d.spacing_y);
        assert!((90.0..92.0).contains(&d.spacing_x) && (92.0..93.0).contains(&d.spacing_y));

        // SRTM1.
        let p = write_hgt(dir.path(), "N47E008.hgt", SRTM1_SIZE, |c, r| {
            (400 + c / 10 + r / 10) as i16
        });
        let d = load(&p, &LoadOptions::default()).unwrap();
        assert_eq!((d.width, d.height, d.voids.count()), (3601, 3601, 0));
        assert_eq!(d.at(3600, 3600), 1120.0);
        let g = d.georef.unwrap();
        assert_eq!((g.first, g.step), ([8.0, 48.0], [1.0 / 3600.0; 2]));
        assert!((20.0..22.0).contains(&d.spacing_x) && (30.0..31.5).contains(&d.spacing_y));
    }

    #[test]
    fn bad_hgt_files_are_refused_by_name_and_length() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("N35E138.hgt");
        std::fs::write(&p, vec![0u8; 1000]).unwrap();
        let p = p.display().to_string();
        let e = load(&p, &LoadOptions::default()).unwrap_err();
        assert!(matches!(e, DemError::Corrupt { .. }), "{e}");
        let m = e.to_string();
        assert!(
            m.contains(&p) && m.contains("1000 bytes") && m.contains("3601x3601"),
            "{m}"
        );

        let p = write_hgt(dir.path(), "fuji.hgt", SRTM3_SIZE, |_, _| 10);
        let e = load(&p, &LoadOptions::default()).unwrap_err();
        assert!(matches!(e, DemError::Place { .. }), "{e}");
        let m = e.to_string();
        assert!(m.contains(&p) && m.contains("N35E138.hgt"), "{m}");

        // All void.
        let p = write_hgt(dir.path(), "N35E138.hgt", SRTM3_SIZE, |_, _| VOID);
        let e = load(&p, &LoadOptions::default()).unwrap_err();
        assert!(matches!(e, DemError::AllVoid(_)), "{e}");
        // The size limit holds before anything is read.
        let p = write_hgt(dir.path(), "N35E139.hgt", SRTM3_SIZE, |_, _| 1);
        let small = LoadOptions {
            max_samples: 1000,
            ..LoadOptions::default()
        };
        let e = load(&p, &small).unwrap_err();
        assert!(matches!(e, DemError::TooLarge { .. }), "{e}");
        // An .hgt is placed by its name: --origin is refused.
        let o = LoadOptions {
            origin: Some((1.0, 2.0)),
            ..LoadOptions::default()
        };
        let e = load(&p, &o).unwrap_err();
        assert!(e.to_string().contains("--origin"), "{e}");
    }
}
