//! The tile stream's worked example of `docs/protocol.md` (section 15), checked against the
//! code that produces it.

#[cfg(test)]
mod tests {
    use crate::tile::body::{encode_mesh, encode_patches, find_patches};
    use crate::tile::cache::set_digest;
    use crate::tile::delta::{AddedTile, TileBlobs, TileDelta, TileDeltaError};
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

    /// The hex bytes of the first code span (between backticks) after `cue` in `doc`.
    fn hex_after(doc: &str, cue: &str) -> Vec<u8> {
        let at = doc
            .find(cue)
            .unwrap_or_else(|| panic!("the doc lacks {cue:?}"))
            + cue.len();
        let rest = &doc[at..];
        let open = rest.find('`').expect("a code span") + 1;
        let close = open + rest[open..].find('`').expect("its end");
        rest[open..close]
            .split_whitespace()
            .map(|b| u8::from_str_radix(b, 16).unwrap_or_else(|_| panic!("not hex: {b}")))
            .collect()
    }

    /// Asserts that `doc` holds every line of `want`, in this order, after `start`.
    fn in_order(doc: &str, start: usize, want: &[String]) {
        let mut at = start;
        for w in want {
            let found = doc[at..]
                .find(w.as_str())
                .unwrap_or_else(|| panic!("the doc lacks, or misorders, {w:?}"));
            at += found + w.len();
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

    /// The `rqt` example of section 15.2: a 5 x 5 lattice. Its recursion reads the bits in the
    /// order the document lists (the child `(m, a, c)` first); a decoder that takes the other
    /// child first reads the same number of bits but gives other heights, so the document's
    /// bytes, decoded by the real decoder, pin the order.
    #[test]
    fn the_rqt_example_of_the_protocol_doc_decodes_in_the_documented_order() {
        use crate::tile::body::decode_mesh;
        use crate::tile::body::rqt::{Pos, encode_rqt, rqt_triangles};
        const Z: [[i32; 5]; 5] = [
            [10, 12, 20, 14, 16],
            [11, 13, 21, 30, 17],
            [12, 14, 22, 23, 24],
            [13, 15, 17, 19, 21],
            [14, 16, 18, 20, 26],
        ];
        let active = |p: Pos| matches!(p, [2, 2] | [4, 2] | [3, 1] | [2, 0]);
        let z_at = |p: Pos| Z[p[1] as usize][p[0] as usize];
        let shape = TileShape::new(5, 5, 4).unwrap();
        let span = shape.span(TileId::ROOT);
        // The visits, as the document lists them.
        let p = |p: Pos| format!("[{},{}]", p[0], p[1]);
        let mut seen = std::collections::HashSet::new();
        let mut visits = Vec::new();
        let (vertices, triangles) = rqt_triangles(4, |m, a, b| {
            let on = active(m);
            let head = format!("{} of {}-{}:", p(m), p(a), p(b));
            visits.push(if !seen.insert(m) {
                format!("{head} again, {}", if on { "split" } else { "leaf" })
            } else if on {
                let pred = (z_at(a) + z_at(b)).div_euclid(2);
                format!("{head} 1, SEG {} - {pred} = {}", z_at(m), z_at(m) - pred)
            } else {
                format!("{head} 0")
            });
            on
        });
        for v in &visits {
            println!("{v}");
        }
        let blob = encode_rqt(&span, active, z_at).unwrap();
        println!("{}", hex(&blob));
        let doc = include_str!("../../../docs/protocol.md");
        let start = doc.find("*Example* (`rqt`").expect("the rqt example");
        let rows: Vec<String> = Z
            .iter()
            .map(|r| r.map(|v| v.to_string()).join(" "))
            .map(|r| format!("`{r}`"))
            .collect();
        in_order(doc, start, &rows);
        in_order(doc, start, &visits);
        let bytes = hex_after(&doc[start..], "the blob is ");
        assert_eq!(bytes, blob, "the doc's blob is not what the encoder writes");
        let got = decode_mesh(&span, &bytes).unwrap();
        let mesh = got.irregular.expect("an rqt mesh");
        assert_eq!(mesh.at, vertices);
        assert_eq!(mesh.triangles, triangles);
        let numbered: Vec<String> = vertices
            .iter()
            .zip(&got.z)
            .enumerate()
            .map(|(i, (&v, z))| format!("{i} = {} ({z})", p(v)))
            .collect();
        let tris: Vec<String> = triangles
            .iter()
            .map(|t| format!("[{}, {}, {}]", t[0], t[1], t[2]))
            .collect();
        println!("{}", numbered.join(", "));
        println!("{}", tris.join(" "));
        in_order(doc, start, &[numbered.join(", "), tris.join(" ")]);
        for (v, z) in vertices.iter().zip(&got.z) {
            assert_eq!(*z, z_at(*v));
        }
        // The other push order reads the same bits to the same padding, and other heights.
        let (right, left) = replay(&bytes, 4, true).expect("the documented order decodes");
        assert_eq!(left, 6);
        assert!(right.iter().all(|(&p, &z)| z == i64::from(z_at(p))));
        assert_eq!(right.len(), vertices.len());
        let (wrong, left) = replay(&bytes, 4, false).expect("the other order reads as far");
        assert_eq!(left, 6);
        assert_eq!(
            wrong.get(&[2, 0]),
            Some(&16),
            "[2,0] takes [4,2]'s residual 3"
        );
        assert!(wrong.iter().any(|(&p, &z)| z != i64::from(z_at(p))));
    }

    /// A bare `rqt` decoder, written from the document: the heights it reads, by lattice
    /// position, and the bits left after the last code. `a_first`: push `(m, c, b)`, then
    /// `(m, a, c)` (the documented order); else the other way round.
    fn replay(
        bytes: &[u8],
        side: u32,
        a_first: bool,
    ) -> Option<(std::collections::BTreeMap<[u32; 2], i64>, u64)> {
        use crate::bits::BitReader;
        let mut r = BitReader::new(bytes);
        (r.get(2)? == 1).then_some(())?;
        let zmin = i64::from(r.get(32)? as i32);
        let k = r.get(4)?;
        let mut z = std::collections::BTreeMap::new();
        for c in [[0, 0], [side, 0], [0, side], [side, side]] {
            z.insert(c, zmin + r.get_eg(k)? as i64);
        }
        let mut seen = std::collections::BTreeMap::new();
        let mut stack = vec![
            ([0, side], [0, 0], [side, side]),
            ([side, 0], [side, side], [0, 0]),
        ];
        while let Some((c, a, b)) = stack.pop() {
            let sum = [a[0] + b[0], a[1] + b[1]];
            if sum[0] % 2 != 0 || sum[1] % 2 != 0 {
                continue;
            }
            let m = sum.map(|v| v / 2);
            let on = match seen.get(&m) {
                Some(&on) => on,
                None => {
                    let on = r.get(1)? == 1;
                    if on {
                        let res = r.get_eg_signed(k)?;
                        z.insert(m, (z[&a] + z[&b]).div_euclid(2) + res);
                    }
                    seen.insert(m, on);
                    on
                }
            };
            if on && a_first {
                stack.extend([(m, c, b), (m, a, c)]);
            } else if on {
                stack.extend([(m, a, c), (m, c, b)]);
            }
        }
        Some((z, r.remaining()))
    }

    /// The lines of the first code block after `cue`, and the leading hex bytes of each (the
    /// columns before the comment).
    fn block_hex(doc: &str, cue: &str) -> Vec<u8> {
        let at = doc
            .find(cue)
            .unwrap_or_else(|| panic!("the doc lacks {cue:?}"));
        let rest = &doc[at..];
        let open = rest.find("```\n").expect("a code block") + 4;
        let close = open + rest[open..].find("```").expect("its end");
        rest[open..close]
            .lines()
            .flat_map(|l| {
                l.split_whitespace()
                    .map_while(|b| (b.len() == 2).then(|| u8::from_str_radix(b, 16).ok())?)
                    .collect::<Vec<_>>()
            })
            .collect()
    }

    /// Section 15.4's varints are LEB128, not section 2.2's: each row of its table, checked
    /// against the tile delta's encoder and decoder, and its other column against the codec.
    #[test]
    fn the_tile_varints_of_the_protocol_doc_are_leb128() {
        use crate::tile::delta::{get_varint, put_varint};
        let doc = include_str!("../../../docs/protocol.md");
        let start = doc.find("### 15.4 Tile delta body").expect("15.4");
        let table = &doc[start..];
        let table = &table[table.find("| Value | Here (LEB128)").expect("the table")..];
        let mut rows = 0;
        for line in table.lines().skip(2).take_while(|l| l.starts_with('|')) {
            let cells: Vec<&str> = line
                .split('|')
                .map(|c| c.trim().trim_matches('`'))
                .collect();
            let v: u32 = cells[1].parse().expect("a value");
            let bytes = |c: &str| -> Vec<u8> {
                c.split(' ')
                    .map(|b| u8::from_str_radix(b, 16).expect("hex"))
                    .collect()
            };
            let (leb, bincode) = (bytes(cells[2]), bytes(cells[3]));
            let mut out = Vec::new();
            put_varint(&mut out, v);
            assert_eq!(out, leb, "{v} in a tile body");
            let mut at = 0;
            assert_eq!(get_varint(&leb, &mut at), Ok(v));
            assert_eq!(at, leb.len());
            assert_eq!(
                crate::codec::encode(&v),
                bincode,
                "{v} as section 2.2 writes it"
            );
            rows += 1;
        }
        assert!(rows >= 5, "{rows} rows");
        // What the document says the decoder accepts and refuses.
        let mut at = 0;
        assert_eq!(get_varint(&[0x80, 0x00], &mut at), Ok(0));
        for bad in [
            &[0xFF, 0xFF, 0xFF, 0xFF, 0x1F][..],
            &[0x80, 0x80, 0x80, 0x80, 0x80, 0x00],
        ] {
            assert_eq!(get_varint(bad, &mut 0), Err(TileDeltaError::Varint));
        }
    }

    /// Section 15.4's example with values past 127, decoded by the real decoder.
    #[test]
    fn the_tile_delta_example_past_127_decodes_as_the_doc_says() {
        let doc = include_str!("../../../docs/protocol.md");
        let start = doc.find("### 15.4 Tile delta body").expect("15.4");
        let mut body = block_hex(&doc[start..], "*Example* with values of 128 and more");
        assert_eq!(
            body,
            [0x02, 0x05, 0xC3, 0x01, 0x01, 0xAC, 0x02, 0x82, 0x01, 0x00]
        );
        let mesh: Vec<u8> = (0..130u8).collect();
        body.extend_from_slice(&mesh);
        assert!(doc[start..].contains(&format!("{} bytes:", body.len())));
        let shape = TileShape::new(257, 257, 16).unwrap();
        assert_eq!(shape.tile_count(), 341);
        let want = TileDelta {
            removed: vec![5, 200],
            added: vec![AddedTile {
                tile: 300,
                body: Some(TileBlobs {
                    mesh,
                    patches: vec![],
                }),
            }],
        };
        assert_eq!(
            TileDelta::decode(&body, shape.tile_count()),
            Ok(want.clone())
        );
        assert_eq!(want.encode(), body);
        // Hence "at least 301 tiles": in a smaller pyramid tile 300 does not exist.
        assert_eq!(
            TileDelta::decode(&body, 300),
            Err(TileDeltaError::Tile(300))
        );
    }

    /// An empty patch blob has no bytes: a patch or curtain blob always holds its 4-bit `k`, so
    /// their decoders refuse zero bytes and take `00` (k = 0, nothing to patch).
    #[test]
    fn an_empty_patch_blob_is_no_bytes_not_a_blob() {
        use crate::tile::body::{TileBodyError, decode_patches};
        let shape = TileShape::new(5, 3, 2).unwrap();
        let z = vec![0; shape.span(TileId::ROOT).vertex_count()];
        assert_eq!(
            decode_patches(&shape, TileId::ROOT, &z, &[]),
            Err(TileBodyError::Truncated)
        );
        assert!(decode_patches(&shape, TileId::ROOT, &z, &[0x00]).is_ok());
        // A curtain blob likewise.
        use crate::tile::body::curtain::decode_curtains;
        assert_eq!(decode_curtains(&[], &[]), Err(TileBodyError::Truncated));
        assert_eq!(decode_curtains(&[], &[0x00]), Ok(vec![]));
    }
}
