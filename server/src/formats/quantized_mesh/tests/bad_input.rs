//! Bad meshes refused by the encoder, bad bytes by the decoder, and decoding that never panics.

use super::*;

#[test]
fn encode_rejects_bad_meshes() {
    let good = grid(ALPS, 3, 3, sine_terrain);
    let none = QmExtensions::default();
    let with = |f: &dyn Fn(&mut QmMesh)| {
        let mut m = good.clone();
        f(&mut m);
        encode(&m, &none).unwrap_err()
    };
    assert_eq!(
        with(&|m| m.vertices.clear()),
        QmError::Empty {
            vertices: 0,
            triangles: 8
        }
    );
    assert!(matches!(
        with(&|m| {
            m.vertices.clear();
            m.triangles.clear();
        }),
        QmError::Empty {
            vertices: 0,
            triangles: 0
        }
    ));
    assert!(matches!(
        with(&|m| m.triangles.clear()),
        QmError::Empty { .. }
    ));
    assert_eq!(
        with(&|m| m.triangles[3] = [0, 1, 9]),
        QmError::IndexOutOfRange {
            triangle: 3,
            index: 9,
            vertices: 9
        }
    );
    assert!(matches!(
        with(&|m| m.vertices[4][2] = f64::NAN),
        QmError::NonFinite { .. }
    ));
    assert!(matches!(
        with(&|m| m.vertices[4][0] = f64::INFINITY),
        QmError::NonFinite { .. }
    ));
    assert!(matches!(
        with(&|m| m.vertices[4][2] = 1e39),
        QmError::NonFinite { .. }
    ));
    assert!(matches!(
        with(&|m| m.vertices[4][0] = 20.0),
        QmError::OutsideBounds { index: 4, .. }
    ));
    assert!(matches!(
        with(&|m| m.vertices[4][1] = 40.0),
        QmError::OutsideBounds { .. }
    ));
    assert!(matches!(
        with(&|m| m.east = m.west),
        QmError::BadBounds { .. }
    ));
    assert!(matches!(
        with(&|m| m.north = f64::NAN),
        QmError::BadBounds { .. }
    ));
    assert!(matches!(
        with(&|m| m.west = -181.0),
        QmError::BadBounds { .. }
    ));
    // A hair outside is rounded onto the edge.
    let mut m = good.clone();
    m.vertices[0][0] -= 1e-12;
    let tile = decode(&encode(&m, &none).unwrap()).unwrap();
    assert_eq!(tile.u[0], 0);
}

#[test]
fn decode_rejects_every_truncation() {
    let mesh = irregular(11);
    let bytes = encode(&mesh, &QmExtensions::default()).unwrap();
    for len in 0..bytes.len() {
        assert!(
            decode(&bytes[..len]).is_err(),
            "a prefix of {len} bytes decoded"
        );
    }
    // With extensions, every cut but the ones between extensions.
    let full = encode(
        &mesh,
        &QmExtensions {
            normals: true,
            metadata: Some("{}".into()),
        },
    )
    .unwrap();
    let after_normals = bytes.len() + 5 + 2 * mesh.vertices.len();
    for len in bytes.len() + 1..full.len() {
        assert_eq!(decode(&full[..len]).is_ok(), len == after_normals, "{len}");
    }
}

#[test]
fn decode_rejects_bad_fields() {
    let mesh = grid(ALPS, 4, 4, sine_terrain);
    let bytes = encode(&mesh, &QmExtensions::default()).unwrap();
    let invalid = |b: &[u8]| matches!(decode(b), Err(QmError::Invalid { .. }));
    let n = 16;
    // u of vertex 1 pushed past 32767.
    let mut b = bytes.clone();
    b[94..96].copy_from_slice(&65534u16.to_le_bytes());
    b[92..94].copy_from_slice(&65534u16.to_le_bytes());
    assert!(invalid(&b));
    // A first triangle code decoding to vertex 100 (0 - 65436 wraps to 100).
    let tri_at = HEADER_LEN + 4 + 6 * n + 4;
    let mut b = bytes.clone();
    b[tri_at..tri_at + 2].copy_from_slice(&65436u16.to_le_bytes());
    assert!(invalid(&b));
    // An edge index past the vertices.
    let west_at = tri_at + 2 * 3 * mesh.triangles.len() + 4;
    let mut b = bytes.clone();
    b[west_at..west_at + 2].copy_from_slice(&16u16.to_le_bytes());
    assert!(invalid(&b));
    // Normals of the wrong length; twice; metadata not UTF-8; metadata with trailing bytes.
    let ext = |id: u8, data: &[u8]| {
        let mut b = bytes.clone();
        b.push(id);
        b.extend_from_slice(&(data.len() as u32).to_le_bytes());
        b.extend_from_slice(data);
        b
    };
    assert!(invalid(&ext(EXT_OCT_NORMALS, &[0; 30])));
    let mut twice = ext(EXT_OCT_NORMALS, &[0; 32]);
    assert!(decode(&twice).is_ok());
    twice.extend_from_slice(&ext(EXT_OCT_NORMALS, &[0; 32])[bytes.len()..]);
    assert!(invalid(&twice));
    assert!(invalid(&ext(EXT_METADATA, &[2, 0, 0, 0, 0xFF, 0xFE])));
    assert!(invalid(&ext(EXT_METADATA, &[1, 0, 0, 0, b'1', b'2'])));
    assert!(matches!(
        decode(&ext(EXT_METADATA, &[9, 0, 0, 0, b'1'])),
        Err(QmError::Truncated { .. })
    ));
    // A water mask is skipped and listed.
    let tile = decode(&ext(EXT_WATER_MASK, &[255])).unwrap();
    assert_eq!(tile.other_extensions, [(EXT_WATER_MASK, 1)]);
    // A vertex count far beyond the bytes allocates nothing and fails.
    let mut b = bytes.clone();
    b[88..92].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(decode(&b), Err(QmError::Truncated { .. })));
    let mut b = bytes.clone();
    b[tri_at - 4..tri_at].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(decode(&b), Err(QmError::Truncated { .. })));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn decode_of_random_bytes_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let _ = decode(&bytes);
    }

    #[test]
    fn decode_of_damaged_tiles_never_panics(
        seed in 0u64..8,
        edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..8),
        cut in any::<usize>(),
    ) {
        let mesh = grid(ALPS, 6, 5, sine_terrain);
        let mut bytes = encode(&mesh, &QmExtensions { normals: seed % 2 == 0, metadata: Some("{}".into()) }).unwrap();
        for (at, value) in edits {
            let at = at % bytes.len();
            bytes[at] = value;
        }
        bytes.truncate(cut % (bytes.len() + 1));
        let _ = decode(&bytes);
    }

    #[test]
    fn random_meshes_round_trip(
        seed in 1u64..u64::MAX,
        n in 3usize..60,
        nt in 1usize..80,
        tile in 0usize..3,
    ) {
        let b = [ALPS, [-180.0, -90.0, -90.0, 0.0], [120.0, -10.0, 120.000_01, -9.999_99]][tile];
        let mut rng = Rng(seed);
        let vertices = (0..n)
            .map(|_| [rng.range(b[0], b[2]), rng.range(b[1], b[3]), rng.range(-100.0, 9000.0)])
            .collect();
        let triangles = (0..nt)
            .map(|_| [0; 3].map(|_: u32| (rng.next() % n as u64) as u32))
            .collect();
        let mesh = QmMesh { west: b[0], south: b[1], east: b[2], north: b[3], vertices, triangles };
        round_trip(&mesh, &QmExtensions { normals: true, metadata: None });
    }
}
