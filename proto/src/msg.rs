//! Wire messages (DESIGN.md section 6). Each is one binary WebSocket frame, encoded by
//! [`crate::codec`]; `docs/protocol.md` specifies every field, unit and close reason.
//!
//! A session: the client sends [`ClientMsg::Hello`]; the server answers [`ServerMsg::Welcome`]
//! (or closes with a [`CloseReason`]). The client then sends [`ClientMsg::Pose`]s whenever its
//! camera moves; the server coalesces them (the latest wins) and answers with
//! [`ServerMsg::Delta`]s, which the client acknowledges with [`ClientMsg::Ack`]. At most
//! [`Welcome::max_in_flight`] deltas are unacknowledged at any time.

use crate::codec::{Decode, Encode};
use crate::delta::{BodyError, BodyModels, Delta, Known};
use crate::query::{AnswerBatch, BatchRefused, QueryBatch};
use crate::snapshot::Snapshot;
use crate::terrain::TerrainGeometry;
use crate::tile::TileSetInfo;
use crate::tree::{ShapeError, TreeShape};
use crate::view::{Camera, Lens};

/// The protocol version this crate speaks. A hello with another version is refused with
/// [`CloseReason::Version`].
pub const PROTOCOL_VERSION: u32 = 5;

/// Which stream a session receives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Encode, Decode)]
pub enum StreamKind {
    /// The vertex stream of paper 000: Haar splits and merges of the vertex quadtree.
    Vertex,
    /// The tile stream of paper 001: tiles with their crack patches ([`crate::tile`]).
    Tiles(TileStreamParams),
    /// No stream: terrain queries ([`crate::query`]), batches answered in order. The hello's
    /// lens, tau and budget are not used, and it must not resume.
    Query,
}

/// How a tile session's cracks are closed: what its tile bodies carry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Encode, Decode)]
pub enum CrackMode {
    /// Tiles carry their precomputed crack patches, which the client always draws.
    Patches,
    /// Tiles carry no patches; the client hangs skirts from every tile edge (the baseline).
    Skirts,
    /// Tiles carry nothing for cracks (to show that cracks exist).
    None,
}

/// What a tile session asks for beyond a vertex session.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Encode, Decode)]
pub struct TileStreamParams {
    /// The most tiles the client keeps, active and cached together ([`crate::tile::cache`]);
    /// `u32::MAX` for no limit.
    pub cache_tiles: u32,
    /// What the tile bodies carry against cracks.
    pub crack: CrackMode,
}

/// A camera pose on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Encode, Decode)]
pub struct WireCamera {
    /// Eye position in world metres: x east, y north, z up ([`crate::tree::WorldFrame`]).
    pub eye: [f32; 3],
    /// Heading in radians, counter-clockwise from east.
    pub yaw: f32,
    /// Elevation of the view direction in radians, in (-pi/2, pi/2); negative looks down.
    pub pitch: f32,
}

impl From<Camera> for WireCamera {
    fn from(c: Camera) -> Self {
        WireCamera {
            eye: c.eye.to_array(),
            yaw: c.yaw,
            pitch: c.pitch,
        }
    }
}

impl From<WireCamera> for Camera {
    fn from(c: WireCamera) -> Self {
        Camera {
            eye: c.eye.into(),
            yaw: c.yaw,
            pitch: c.pitch,
        }
    }
}

/// Viewport and lens on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Encode, Decode)]
pub struct WireLens {
    /// Viewport width in pixels.
    pub width: u32,
    /// Viewport height in pixels.
    pub height: u32,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f32,
    /// Near plane distance in metres.
    pub near: f32,
}

impl From<Lens> for WireLens {
    fn from(l: Lens) -> Self {
        WireLens {
            width: l.width,
            height: l.height,
            fov_y_deg: l.fov_y_deg,
            near: l.near,
        }
    }
}

impl From<WireLens> for Lens {
    fn from(l: WireLens) -> Self {
        Lens {
            width: l.width,
            height: l.height,
            fov_y_deg: l.fov_y_deg,
            near: l.near,
        }
    }
}

/// The opening message of a session.
#[derive(Clone, Debug, PartialEq, Encode, Decode)]
pub struct Hello {
    /// Must equal the server's [`PROTOCOL_VERSION`].
    pub version: u32,
    /// The stream wanted.
    pub kind: StreamKind,
    /// The client's viewport: screen errors are measured in its pixels.
    pub lens: WireLens,
    /// Screen-space error threshold in pixels.
    pub tau: f32,
    /// Bandwidth budget in bytes per second of delta bodies; `None` for unlimited.
    pub budget: Option<u32>,
    /// The cut to resume from, with the terrain it belongs to; `None` starts from the root.
    pub resume: Option<Resume>,
}

/// What a client sends to continue a session on any server holding the same terrain.
#[derive(Clone, Debug, PartialEq, Eq, Encode, Decode)]
pub struct Resume {
    /// [`TerrainInfo::id`] of the terrain the cut belongs to.
    pub terrain_id: u64,
    /// The client's cut.
    pub snapshot: Snapshot,
}

/// What a client needs to know of the terrain.
#[derive(Clone, Debug, PartialEq, Encode, Decode)]
pub struct TerrainInfo {
    /// Identifier of the store's contents; resume snapshots name it.
    pub id: u64,
    /// Grid width in samples.
    pub width: u32,
    /// Grid height in samples.
    pub height: u32,
    /// Ground metres between columns.
    pub spacing_x: f32,
    /// Ground metres between rows.
    pub spacing_y: f32,
    /// Metres per height quantum.
    pub z_quantum: f32,
    /// The root node's height in quanta: with the deltas' details, every height follows.
    pub root_z: i32,
    /// Lowest and highest height in metres, for camera placement and colour ramps.
    pub height_range: [f32; 2],
}

impl TerrainInfo {
    /// The geometry both ends compute node positions and boxes from.
    pub fn geometry(&self) -> Result<TerrainGeometry, ShapeError> {
        TerrainGeometry::new(
            self.width,
            self.height,
            self.spacing_x,
            self.spacing_y,
            self.z_quantum,
        )
    }
}

/// The server's answer to a hello.
#[derive(Clone, Debug, PartialEq, Encode, Decode)]
pub struct Welcome {
    /// The server's [`PROTOCOL_VERSION`].
    pub version: u32,
    /// Identifies the session in the server's logs and metrics.
    pub session_id: u64,
    /// The terrain.
    pub terrain: TerrainInfo,
    /// Whether the session continues from the hello's resume snapshot (else from the root).
    pub resumed: bool,
    /// Digest of the session's cut now: the root's, or the resumed cut's.
    pub digest: u64,
    /// How many deltas may be unacknowledged at once.
    pub max_in_flight: u32,
    /// The largest message the server accepts, in bytes.
    pub max_message_bytes: u32,
    /// The server closes a session that sends nothing for this long, milliseconds: a client
    /// at rest should send a ping (or repeat its last acknowledgement) more often.
    pub idle_timeout_ms: u32,
    /// The tile pyramid, in the welcome of a tile session (`None` for a vertex session).
    pub tiles: Option<TileSetInfo>,
}

/// A delta as it travels: the header in the clear, merges and splits in the compact body
/// ([`crate::delta`]).
#[derive(Clone, Debug, PartialEq, Eq, Encode, Decode)]
pub struct WireDelta {
    /// Sequence number within the connection, from 1.
    pub seq: u64,
    /// Digest of the cut after the delta.
    pub digest: u64,
    /// Merges and splits, range-coded (docs/protocol.md section 5).
    pub body: Vec<u8>,
}

impl WireDelta {
    /// Packs `delta` into a body with fresh models (a one-shot delta) for a terrain of shape
    /// `shape` and z quantum `quantum`; `known`: the
    /// parents and the cut after the delta ([`Known`]).
    pub fn pack(delta: &Delta, shape: &TreeShape, quantum: f32, known: Known<'_>) -> WireDelta {
        WireDelta {
            seq: delta.seq,
            digest: delta.digest,
            body: delta.pack_body(shape, quantum, known),
        }
    }

    /// Packs the next delta of a connection with its body models ([`BodyModels`]).
    pub fn pack_in(
        delta: &Delta,
        shape: &TreeShape,
        models: &mut BodyModels,
        quantum: f32,
        known: Known<'_>,
    ) -> WireDelta {
        WireDelta {
            seq: delta.seq,
            digest: delta.digest,
            body: delta.pack_body_in(shape, models, quantum, known),
        }
    }

    /// Unpacks a one-shot delta (fresh models) against the terrain, against what the
    /// receiver holds before it (`known`: [`Known::mirror`]).
    pub fn unpack(
        &self,
        shape: &TreeShape,
        quantum: f32,
        known: Known<'_>,
    ) -> Result<Delta, BodyError> {
        Delta::unpack_body(shape, quantum, self.seq, self.digest, &self.body, known)
    }

    /// Unpacks the next delta of a connection with its body models ([`BodyModels`]).
    pub fn unpack_in(
        &self,
        shape: &TreeShape,
        quantum: f32,
        models: &mut BodyModels,
        known: Known<'_>,
    ) -> Result<Delta, BodyError> {
        Delta::unpack_body_in(
            shape,
            quantum,
            self.seq,
            self.digest,
            &self.body,
            models,
            known,
        )
    }
}

/// A delta in a session, with what it answers.
#[derive(Clone, Debug, PartialEq, Eq, Encode, Decode)]
pub struct SessionDelta {
    /// Sequence number of the newest pose the delta reflects.
    pub pose_seq: u64,
    /// Whether the cut now meets tau for that pose; false while a bandwidth budget holds splits
    /// back (more deltas follow without a new pose).
    pub complete: bool,
    /// The delta.
    pub delta: WireDelta,
}

/// The body of `POST /v1/lod`: one stateless LOD step.
#[derive(Clone, Debug, PartialEq, Encode, Decode)]
pub struct LodRequest {
    /// Must equal the server's [`PROTOCOL_VERSION`].
    pub version: u32,
    /// The client's viewport.
    pub lens: WireLens,
    /// Screen-space error threshold in pixels.
    pub tau: f32,
    /// The camera.
    pub camera: WireCamera,
    /// The client's current cut; `None` for the root alone.
    pub base: Option<Resume>,
}

/// The answer to `POST /v1/lod`.
#[derive(Clone, Debug, PartialEq, Eq, Encode, Decode)]
pub struct LodResponse {
    /// The delta from the base cut to the cut for the camera (sequence number 1).
    pub delta: WireDelta,
    /// The new cut, to send as the base of the next request.
    pub snapshot: Snapshot,
}

/// Messages from client to server.
#[derive(Clone, Debug, PartialEq, Encode, Decode)]
pub enum ClientMsg {
    /// Opens the session; first message, once.
    Hello(Hello),
    /// The camera moved.
    Pose {
        /// Increases with every pose of the connection; a pose not newer than the last one
        /// received is ignored.
        seq: u64,
        /// The pose.
        camera: WireCamera,
    },
    /// Every delta up to and including `seq` has been applied.
    Ack {
        /// Sequence number of the newest applied delta.
        seq: u64,
    },
    /// A batch of terrain queries (query sessions only).
    Query(QueryBatch),
}

/// Messages from server to client.
#[derive(Clone, Debug, PartialEq, Encode, Decode)]
pub enum ServerMsg {
    /// The answer to a hello.
    Welcome(Welcome),
    /// An incremental update of the client's cut.
    Delta(SessionDelta),
    /// The server is going away; reconnect and resume after the given delay.
    Reconnect {
        /// Milliseconds to wait before reconnecting.
        after_ms: u32,
    },
    /// The answers to a query batch, in the batch's order.
    Answers(AnswerBatch),
    /// A query batch refused whole (over the limits); the session goes on.
    Refused(BatchRefused),
}
#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::{CodecError, decode, encode};
    use proptest::prelude::*;

    fn delta_msg(seq: u64, digest: u64, body: Vec<u8>) -> ServerMsg {
        ServerMsg::Delta(SessionDelta {
            pose_seq: seq / 2,
            complete: seq.is_multiple_of(2),
            delta: WireDelta { seq, digest, body },
        })
    }

    proptest! {
        #[test]
        fn messages_round_trip(seq in any::<u64>(), digest in any::<u64>(),
                               body in proptest::collection::vec(any::<u8>(), 0..300),
                               x in -1e6f32..1e6, budget in proptest::option::of(any::<u32>())) {
            let m = delta_msg(seq, digest, body.clone());
            prop_assert_eq!(decode::<ServerMsg>(&encode(&m), 1 << 20).unwrap(), m);
            let hello = ClientMsg::Hello(Hello {
                version: PROTOCOL_VERSION,
                kind: StreamKind::Vertex,
                lens: Lens::STANDARD.into(),
                tau: x,
                budget,
                resume: Some(Resume {
                    terrain_id: digest,
                    snapshot: Snapshot { digest: seq, bits: body },
                }),
            });
            prop_assert_eq!(decode::<ClientMsg>(&encode(&hello), 1 << 20).unwrap(), hello);
            let pose = ClientMsg::Pose {
                seq,
                camera: WireCamera { eye: [x, -x, 3.0], yaw: 0.5, pitch: -0.2 },
            };
            prop_assert_eq!(decode::<ClientMsg>(&encode(&pose), 1 << 20).unwrap(), pose);
        }

        #[test]
        fn random_frames_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = decode::<ServerMsg>(&bytes, 1 << 20);
            let _ = decode::<ClientMsg>(&bytes, 1 << 20);
            let _ = decode::<LodRequest>(&bytes, 1 << 20);
        }
    }

    #[test]
    fn oversized_and_lying_frames_are_refused() {
        let bytes = encode(&delta_msg(1, 2, vec![7; 100]));
        assert!(matches!(
            decode::<ServerMsg>(&bytes, 50),
            Err(CodecError::TooLarge(..))
        ));
        // A length prefix claiming far more bytes than follow.
        let lie = [1u8, 0, 1, 1, 2, 0xFC, 0xFF, 0xFF, 0xFF, 0x7F];
        assert!(matches!(
            decode::<ServerMsg>(&lie, 1 << 20),
            Err(CodecError::Malformed(_))
        ));
        let mut trailing = bytes.clone();
        trailing.push(0);
        assert!(matches!(
            decode::<ServerMsg>(&trailing, 1 << 20),
            Err(CodecError::Trailing(1))
        ));
    }

    #[test]
    fn cameras_and_lenses_convert_both_ways() {
        let c = Camera {
            eye: glam::Vec3::new(1.0, 2.0, 3.0),
            yaw: 0.25,
            pitch: -0.5,
        };
        assert_eq!(Camera::from(WireCamera::from(c)), c);
        assert_eq!(Lens::from(WireLens::from(Lens::STANDARD)), Lens::STANDARD);
    }

    #[test]
    fn the_welcome_example_of_the_protocol_doc_is_what_the_code_sends() {
        let w = ServerMsg::Welcome(Welcome {
            version: PROTOCOL_VERSION,
            session_id: 42,
            terrain: TerrainInfo {
                id: 0x0123_4567_89AB_CDEF,
                width: 5,
                height: 3,
                spacing_x: 10.0,
                spacing_y: 10.0,
                z_quantum: 0.5,
                root_z: 195,
                height_range: [93.0, 104.5],
            },
            resumed: false,
            digest: 0xE220_A839_7B1D_CDAF,
            max_in_flight: 4,
            max_message_bytes: 1 << 20,
            idle_timeout_ms: 60_000,
            tiles: None,
        });
        let doc = include_str!("../../docs/protocol.md");
        let start = doc.find("**Welcome** (session 42").expect("the example");
        let block = &doc[start..];
        let block = &block[block.find("```").expect("code")..];
        let block = &block[3..block[3..].find("```").expect("end") + 3];
        // The example's hex bytes: the leading columns of each line, before the comment.
        let hex: Vec<u8> = block
            .lines()
            .flat_map(|l| {
                l.split("  ")
                    .take_while(|part| {
                        part.trim()
                            .split(' ')
                            .all(|b| b.len() == 2 && u8::from_str_radix(b, 16).is_ok())
                    })
                    .flat_map(|part| {
                        part.trim()
                            .split(' ')
                            .filter_map(|b| u8::from_str_radix(b, 16).ok())
                            .collect::<Vec<_>>()
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        assert_eq!(encode(&w), hex);
    }
    /// Every place `docs/protocol.md` states the protocol version states this one: a client
    /// written from the document must send what the server accepts (it said 3 in five places
    /// while the server spoke 5, and such a client got `4001 version`).
    #[test]
    fn the_protocol_doc_states_this_version_everywhere() {
        let doc = include_str!("../../docs/protocol.md");
        // What precedes a version number where the document states one.
        let cues = [
            "version ",
            "== ",
            "must be ",
            "is not ",
            "version (",
            "| number | ",
            "PROTOCOL_VERSION = ",
        ];
        let mut stated = Vec::new();
        for (i, line) in doc.lines().enumerate() {
            // Other things' versions: the Prometheus text format's, in its content type.
            if !line.contains("version") || line.contains("version=") {
                continue;
            }
            for cue in cues {
                for (at, _) in line.match_indices(cue) {
                    let rest = &line[at + cue.len()..];
                    let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
                    if let Ok(v) = digits.parse::<u32>() {
                        stated.push((i + 1, v));
                    }
                }
            }
        }
        assert!(stated.len() >= 9, "too few statements found: {stated:?}");
        for (line, v) in stated {
            assert_eq!(
                v, PROTOCOL_VERSION,
                "docs/protocol.md line {line} says version {v}"
            );
        }
    }

    /// The hex bytes of `cell`, a table cell such as `` `03 72 71 74` ``.
    fn cell_hex(cell: &str) -> Vec<u8> {
        let inner = cell.split('`').nth(1).expect("a code span");
        inner
            .split_whitespace()
            .map(|b| u8::from_str_radix(b, 16).expect("hex"))
            .collect()
    }

    /// Section 2.1's examples of `String`, `Vec<f32>` and `f64`, against the codec (bincode's
    /// derived encoding and the hand-written decoders of [`crate::codec`] alike).
    #[test]
    fn the_type_examples_of_the_protocol_doc_are_what_the_codec_writes() {
        let doc = include_str!("../../docs/protocol.md");
        let start = doc.find("### 2.1 Types").expect("2.1");
        let end = doc.find("### 2.2 Varint").expect("2.2");
        let section = &doc[start..end];
        let row = |first: &str| -> &str {
            section
                .lines()
                .find(|l| l.starts_with(&format!("| {first} |")))
                .unwrap_or_else(|| panic!("the doc lacks the row {first:?}"))
                .rsplit('|')
                .nth(1)
                .expect("a bytes cell")
        };
        let long = "a".repeat(300);
        let texts: [(&str, &str); 2] = [("`String` `\"rqt\"`", "rqt"), ("`String` `\"é\"`", "é")];
        for (first, text) in texts {
            let want = cell_hex(row(first));
            assert_eq!(encode(&text.to_string()), want, "{first}");
            assert_eq!(decode::<String>(&want, 1 << 20).unwrap(), text);
            // The hand-written decoder of refusals' and errors' texts reads the same bytes.
            let refused = crate::query::BatchRefused {
                id: 7,
                reason: text.to_string(),
            };
            let mut bytes = vec![7];
            bytes.extend_from_slice(&want);
            assert_eq!(encode(&refused), bytes);
            assert_eq!(
                decode::<crate::query::BatchRefused>(&bytes, 1 << 20).unwrap(),
                refused
            );
        }
        let cell = row("`String` of 300 `a`s");
        assert!(cell.contains("then 300 bytes `61`"), "{cell}");
        let mut want = cell_hex(cell);
        want.extend_from_slice(long.as_bytes());
        assert_eq!(encode(&long), want);
        assert_eq!(decode::<String>(&want, 1 << 20).unwrap(), long);
        let floats: [(&str, Vec<f32>); 2] = [
            ("`Vec<f32>` `[1.5, 0.25]`", vec![1.5, 0.25]),
            ("`Vec<f32>` `[]`", vec![]),
        ];
        for (first, v) in floats {
            let want = cell_hex(row(first));
            assert_eq!(encode(&v), want, "{first}");
            assert_eq!(decode::<Vec<f32>>(&want, 1 << 20).unwrap(), v);
        }
        assert_eq!(encode(&1.0f64), cell_hex(row("`f64` `1.0`")));
        assert!(
            decode::<String>(&[0x02, 0xC3, 0x28], 1 << 20).is_err(),
            "not UTF-8"
        );
    }

    /// Section 15.1's `TileSetInfo` example, alone and as a welcome's `tiles`.
    #[test]
    fn the_tile_set_example_of_the_protocol_doc_is_what_the_codec_writes() {
        let info = TileSetInfo {
            tile_size: 64,
            depth: 2,
            mesh: "rqt".into(),
            level_errors: vec![1.5, 0.25, 0.0],
        };
        let doc = include_str!("../../docs/protocol.md");
        let start = doc.find("### 15.1 The pyramid").expect("15.1");
        let cue = "`level_errors = [1.5, 0.25, 0.0]` is";
        let at = start + doc[start..].find(cue).expect("the example");
        let want = cell_hex(&doc[at + cue.len()..]);
        assert_eq!(encode(&info), want);
        assert_eq!(decode::<TileSetInfo>(&want, 1 << 20).unwrap(), info);
        assert!(doc[at..].contains(&format!("({} bytes;", want.len())));
        let mut some = vec![1];
        some.extend_from_slice(&want);
        assert_eq!(encode(&Some(info)), some);
    }
}
