//! The tile stream's worked example of `docs/protocol.md` (section 15), checked against the
//! code that produces it.

#[cfg(test)]
mod tests {
    use crate::tile::body::{encode_mesh, encode_patches, find_patches};
    use crate::tile::cache::set_digest;
    use crate::tile::delta::{AddedTile, TileBlobs, TileDelta};
    use crate::tile::{TileId, TileShape};

    /// The toy terrain's samples, z quanta, row-major (5 x 3).
    const Z: [i32; 15] = [
        204, 198, 191, 190, 192, 201, 197, 195, 185, 188, 200, 196, 190, 187, 186,
    ];

    fn blobs(shape: &TileShape, t: TileId) -> TileBlobs {
        let sp = shape.span(t);
        let z: Vec<i32> = (0..sp.vertex_count() as u32)
            .map(|v| {
                let (c, r) = sp.vertex_pos(v);
                Z[(r * 5 + c) as usize]
            })
            .collect();
        let p = find_patches(shape, t, &z, |c, r| Z[(r * 5 + c) as usize]);
        TileBlobs {
            mesh: encode_mesh(&sp, &z),
            patches: encode_patches(shape, t, &z, &p),
        }
    }

    fn hex(b: &[u8]) -> String {
        b.iter()
            .map(|x| format!("{x:02X}"))
            .collect::<Vec<_>>()
            .join(" ")
    }

    #[test]
    fn the_tile_examples_of_the_protocol_doc_are_what_the_code_sends() {
        let shape = TileShape::new(5, 3, 2).unwrap();
        let root = TileId::ROOT;
        let first = TileDelta {
            removed: vec![],
            added: vec![AddedTile {
                tile: 0,
                body: Some(blobs(&shape, root)),
            }],
        };
        let kids: Vec<TileId> = shape.children(root).collect();
        let split = TileDelta {
            removed: vec![0],
            added: kids
                .iter()
                .map(|&k| AddedTile {
                    tile: shape.index(k),
                    body: Some(blobs(&shape, k)),
                })
                .collect(),
        };
        let back = TileDelta {
            removed: vec![1, 2],
            added: vec![AddedTile {
                tile: 0,
                body: None,
            }],
        };
        let got = [
            hex(&first.encode()),
            format!("{:016X}", set_digest([0])),
            hex(&split.encode()),
            format!("{:016X}", set_digest([1, 2])),
            hex(&back.encode()),
        ];
        for g in &got {
            println!("{g}");
        }
        let doc = include_str!("../../../docs/protocol.md");
        let start = doc.find("### 15.6 Worked example").expect("the example");
        for g in &got {
            assert!(doc[start..].contains(g.as_str()), "the doc lacks {g}");
        }
    }
}
