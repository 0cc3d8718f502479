//! The integer codes against vectors written by hand from the spec, and encode-decode round
//! trips: a grid with extensions, shuffled irregular meshes, the 16/32-bit index boundary.

use super::*;

#[test]
fn zigzag_known_vectors() {
    // The spec's zigZagDecode: (value >> 1) ^ (-(value & 1)).
    let pairs: [(i16, u16); 9] = [
        (0, 0),
        (-1, 1),
        (1, 2),
        (-2, 3),
        (2, 4),
        (-3, 5),
        (100, 200),
        (32767, 65534),
        (-32767, 65533),
    ];
    for (delta, code) in pairs {
        assert_eq!(zigzag_encode(delta), code, "encode {delta}");
        assert_eq!(zigzag_decode(code), i32::from(delta), "decode {code}");
    }
    // u = 0, 5, 3, 32767, 0: deltas 0, 5, -2, 32764, -32767.
    let mesh = QmMesh {
        west: 0.0,
        south: 0.0,
        east: 3.2767,
        north: 1.0,
        vertices: [0.0, 5.0, 3.0, 32767.0, 0.0]
            .iter()
            .map(|&u| [u * 1e-4, 0.0, 0.0])
            .collect(),
        triangles: vec![[0, 1, 2], [2, 3, 4]],
    };
    let bytes = encode(&mesh, &QmExtensions::default()).unwrap();
    let u: Vec<u16> = bytes[92..102]
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    assert_eq!(u, [0, 10, 3, 65528, 65533]);
}

#[test]
fn hwm_known_vectors() {
    // By hand from the spec's decoder: highest starts at 0; code 0 is a new vertex.
    // 0 1 2 | 2 1 3 | 0 3 4  ->  0 0 0 | 1 2 0 | 4 1 0
    let indices = [0, 1, 2, 2, 1, 3, 0, 3, 4];
    let codes = [0, 0, 0, 1, 2, 0, 4, 1, 0];
    for wide in [false, true] {
        assert_eq!(hwm_encode(&indices, wide).unwrap(), codes);
        assert_eq!(hwm_decode(&codes, wide), indices);
    }
    // Not in first-use order: vertex 2 before vertex 1.
    assert_eq!(hwm_encode(&[0, 2, 1], false), None);
}

#[test]
fn hwm_wraps_like_a_u16_array_at_65536_vertices() {
    // All 65536 vertices seen, then 0 and 1 again: highest - index is 65536 = 0 mod 2^16, which
    // a decoder storing into a Uint16Array reads as 0 and 1 (and counts as new vertices).
    let mut indices: Vec<u32> = (0..65536).collect();
    indices.extend([0, 1, 65535, 7]);
    let codes = hwm_encode(&indices, false).unwrap();
    assert_eq!(&codes[65536..], [0, 0, 3, 65531]);
    assert!(codes.iter().all(|&c| c <= 0xFFFF));
    assert_eq!(hwm_decode(&codes, false), indices);
    assert_eq!(
        hwm_decode(&hwm_encode(&indices, true).unwrap(), true),
        indices
    );
}

#[test]
fn round_trip_grid_with_extensions() {
    let mesh = grid(ALPS, 65, 65, sine_terrain);
    let metadata = availability_metadata(&[vec![TileRange {
        start_x: 0,
        start_y: 0,
        end_x: 1,
        end_y: 1,
    }]]);
    let ext = QmExtensions {
        normals: true,
        metadata: Some(metadata.clone()),
    };
    let (_, tile) = round_trip(&mesh, &ext);
    assert_eq!(vertex_order(&mesh).unwrap().len(), 65 * 65);
    assert_eq!((tile.west.len(), tile.south.len()), (65, 65));
    assert_eq!((tile.east.len(), tile.north.len()), (65, 65));
    assert_eq!(tile.normals.as_ref().map(Vec::len), Some(65 * 65));
    assert_eq!(tile.metadata.as_deref(), Some(metadata.as_str()));
    assert!(tile.other_extensions.is_empty());
}

#[test]
fn round_trip_irregular_shuffled_mesh() {
    for seed in 1..6 {
        let mesh = irregular(seed);
        let order = vertex_order(&mesh).unwrap();
        assert_ne!(order, (0..order.len() as u32).collect::<Vec<_>>());
        // The unused vertex goes last.
        assert_eq!(order.last(), Some(&(mesh.vertices.len() as u32 - 1)));
        let (_, tile) = round_trip(
            &mesh,
            &QmExtensions {
                normals: true,
                metadata: None,
            },
        );
        assert_eq!(tile.west.len(), 13);
        assert_eq!(tile.south.len(), 17);
    }
}

#[test]
fn index_width_switches_above_65536_vertices() {
    let tile_bounds = [10.0, 45.0, 10.5, 45.5];
    // 256 x 256 = 65536 vertices: 16-bit; one more triangle using vertices 0 and 1 after all
    // were seen exercises the wrap of the 16-bit high-water mark.
    let mut mesh = grid(tile_bounds, 256, 256, |lon, lat| 100.0 * (lon + lat));
    mesh.triangles.push([0, 1, 2]);
    let (bytes, tile) = round_trip(&mesh, &QmExtensions::default());
    assert!(!tile.wide_indices);
    let n = 65536;
    let index_at = HEADER_LEN + 4 + 6 * n;
    let nt = mesh.triangles.len();
    assert_eq!(
        u32::from_le_bytes(bytes[index_at..index_at + 4].try_into().unwrap()) as usize,
        nt
    );
    let last = index_at + 4 + 2 * 3 * (nt - 1);
    let code = |k: usize| u16::from_le_bytes([bytes[last + 2 * k], bytes[last + 2 * k + 1]]);
    assert_eq!((code(0), code(1)), (0, 0), "the wrapped codes");
    assert!(tile.triangles.last().unwrap()[..2].contains(&0));

    // 65537 vertices (one unused, last): 32-bit indices, after 2 bytes of padding (92 + 6 * 65537
    // is 2 mod 4).
    let mut mesh = grid(tile_bounds, 256, 256, |lon, lat| 100.0 * (lon + lat));
    mesh.vertices.push([10.25, 45.25, 0.0]);
    let (bytes, tile) = round_trip(&mesh, &QmExtensions::default());
    assert!(tile.wide_indices);
    let n = 65537;
    let pad_at = HEADER_LEN + 4 + 6 * n;
    assert_eq!(pad_at % 4, 2);
    assert_eq!(&bytes[pad_at..pad_at + 2], [0, 0]);
    let count = u32::from_le_bytes(bytes[pad_at + 2..pad_at + 6].try_into().unwrap());
    assert_eq!(count as usize, mesh.triangles.len());
    // 4 bytes an index: count, indices, four edge lists with their counts.
    let edges = tile.west.len() + tile.south.len() + tile.east.len() + tile.north.len();
    assert_eq!(
        bytes.len(),
        pad_at + 2 + 4 + 4 * 3 * mesh.triangles.len() + 4 * (4 + edges)
    );
}
