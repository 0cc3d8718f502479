//! The extensions' bytes, the availability metadata JSON and Accept-header parsing.

use super::*;

#[test]
fn extensions_are_written_in_id_order_with_their_lengths() {
    let mesh = grid(ALPS, 5, 5, sine_terrain);
    let plain = encode(&mesh, &QmExtensions::default()).unwrap();
    let json = r#"{"available":[]}"#;
    let ext = QmExtensions {
        normals: true,
        metadata: Some(json.into()),
    };
    let full = encode(&mesh, &ext).unwrap();
    assert_eq!(&full[..plain.len()], plain.as_slice());
    let rest = &full[plain.len()..];
    assert_eq!(rest[0], EXT_OCT_NORMALS);
    assert_eq!(u32::from_le_bytes(rest[1..5].try_into().unwrap()), 50);
    let rest = &rest[5 + 50..];
    assert_eq!(rest[0], EXT_METADATA);
    let len = json.len() as u32;
    assert_eq!(u32::from_le_bytes(rest[1..5].try_into().unwrap()), 4 + len);
    assert_eq!(u32::from_le_bytes(rest[5..9].try_into().unwrap()), len);
    assert_eq!(&rest[9..], json.as_bytes());
    // Only metadata.
    let only = encode(
        &mesh,
        &QmExtensions {
            normals: false,
            metadata: Some(json.into()),
        },
    )
    .unwrap();
    let tile = decode(&only).unwrap();
    assert_eq!((tile.normals, tile.metadata.as_deref()), (None, Some(json)));
}

#[test]
fn availability_metadata_is_cesium_json() {
    let json = availability_metadata(&[
        vec![TileRange {
            start_x: 0,
            start_y: 0,
            end_x: 1,
            end_y: 1,
        }],
        vec![
            TileRange {
                start_x: 0,
                start_y: 0,
                end_x: 1,
                end_y: 3,
            },
            TileRange {
                start_x: 2,
                start_y: 0,
                end_x: 3,
                end_y: 1,
            },
        ],
    ]);
    assert_eq!(
        json,
        r#"{"available":[[{"startX":0,"startY":0,"endX":1,"endY":1}],[{"startX":0,"startY":0,"endX":1,"endY":3},{"startX":2,"startY":0,"endX":3,"endY":1}]]}"#
    );
}

#[test]
fn accept_header_cases() {
    let ask = |normals, metadata| RequestedExtensions { normals, metadata };
    let cases = [
        (
            "application/vnd.quantized-mesh;extensions=octvertexnormals-metadata,application/octet-stream;q=0.9,*/*;q=0.01",
            ask(true, true),
        ),
        (
            "application/vnd.quantized-mesh,application/octet-stream;q=0.9",
            ask(false, false),
        ),
        (
            "application/vnd.quantized-mesh;extensions=octvertexnormals-watermask",
            ask(true, false),
        ),
        (
            "application/vnd.quantized-mesh;extensions=watermask-metadata",
            ask(false, true),
        ),
        (
            "application/vnd.quantized-mesh;extensions=metadata",
            ask(false, true),
        ),
        // Deprecated, with a big-endian length: not what Relief writes.
        (
            "application/vnd.quantized-mesh;extensions=vertexnormals",
            ask(false, false),
        ),
        (
            r#"Application/Vnd.Quantized-Mesh ; Extensions="OctVertexNormals-Metadata" ; q=0.5"#,
            ask(true, true),
        ),
        (
            "application/vnd.quantized-mesh;extensions=octvertexnormals;q=0",
            ask(false, false),
        ),
        (
            "application/vnd.quantized-mesh;q=0.0;extensions=metadata",
            ask(false, false),
        ),
        (
            "application/octet-stream;extensions=octvertexnormals-metadata",
            ask(false, false),
        ),
        ("*/*", ask(false, false)),
        ("", ask(false, false)),
        (";;,=,;extensions=", ask(false, false)),
        (
            "application/vnd.quantized-mesh;extensions=octvertexnormals, application/vnd.quantized-mesh;extensions=metadata",
            ask(true, true),
        ),
        (
            "application/vnd.quantized-mesh;extensions=octvertexnormals-",
            ask(true, false),
        ),
    ];
    for (accept, want) in cases {
        assert_eq!(extensions_from_accept(accept), want, "{accept}");
    }
}
