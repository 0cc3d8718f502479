//! Target `message`: the whole input is one frame, decoded with [`codec::decode`] and the
//! server's default limit as each wire message type: [`ClientMsg`] and [`LodRequest`] (what the
//! server reads), [`ServerMsg`] and [`LodResponse`] (what a client reads).
//!
//! Whatever decodes is re-encoded, and must give the shortest form of the input
//! ([`crate::assert_canonical`]) and decode to the same bytes again. Values are compared through
//! their encodings: `f32` fields may hold NaNs, which `PartialEq` never finds equal.

use crate::LIMIT;
use relief_proto::codec::{self, Decode, Encode};
use relief_proto::msg::{
    ClientMsg, CrackMode, Hello, LodRequest, LodResponse, PROTOCOL_VERSION, Resume, ServerMsg,
    SessionDelta, StreamKind, TerrainInfo, TileStreamParams, Welcome, WireCamera, WireDelta,
    WireLens,
};
use relief_proto::snapshot::Snapshot;
use relief_proto::tile::TileSetInfo;

/// Decodes `data` as every message type; true if any accepted it.
pub fn check(data: &[u8]) -> bool {
    // Not `||`: every type must see every input.
    let decoded = [
        round_trip::<ClientMsg>(data),
        round_trip::<ServerMsg>(data),
        round_trip::<LodRequest>(data),
        round_trip::<LodResponse>(data),
    ];
    decoded.contains(&true)
}

/// Decodes `data` as a `T` and checks the round trip; true if it decoded.
fn round_trip<T: Encode + Decode<()>>(data: &[u8]) -> bool {
    let Ok(msg) = codec::decode::<T>(data, LIMIT) else {
        return false;
    };
    let bytes = codec::encode(&msg);
    crate::assert_canonical(data, &bytes);
    let again: T = codec::decode(&bytes, LIMIT).expect("an encoded message decodes");
    assert_eq!(codec::encode(&again), bytes, "decode changed the message");
    true
}

/// A viewport like the client's.
const LENS: WireLens = WireLens {
    width: 1280,
    height: 720,
    fov_y_deg: 60.0,
    near: 1.0,
};

/// A few real messages of every type.
pub fn seeds() -> Vec<(String, Vec<u8>)> {
    let snapshot = Snapshot {
        digest: 0xE220_A839_7B1D_CDAF,
        bits: vec![0x1F, 0x02],
    };
    let camera = WireCamera {
        eye: [120.0, -40.5, 310.0],
        yaw: 0.5,
        pitch: -0.3,
    };
    let hello = |kind, resume| {
        ClientMsg::Hello(Hello {
            version: PROTOCOL_VERSION,
            kind,
            lens: LENS,
            tau: 2.0,
            budget: Some(250_000),
            resume,
        })
    };
    let tiles = StreamKind::Tiles(TileStreamParams {
        cache_tiles: 4096,
        crack: CrackMode::Patches,
    });
    let resume = Resume {
        terrain_id: 0x0123_4567_89AB_CDEF,
        snapshot: snapshot.clone(),
    };
    let delta = WireDelta {
        seq: 3,
        digest: 0x5A5A_1234_0000_FFFF,
        body: vec![0x90, 0x00, 0x12, 0x34],
    };
    let welcome = Welcome {
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
        tiles: Some(TileSetInfo {
            tile_size: 64,
            depth: 2,
            mesh: "grid".into(),
            level_errors: vec![12.5, 3.0, 0.5],
        }),
    };
    let mut out = vec![
        (
            "hello_vertex",
            codec::encode(&hello(StreamKind::Vertex, None)),
        ),
        (
            "hello_tiles_resume",
            codec::encode(&hello(tiles, Some(resume.clone()))),
        ),
        ("pose", codec::encode(&ClientMsg::Pose { seq: 17, camera })),
        ("ack", codec::encode(&ClientMsg::Ack { seq: 300 })),
        ("welcome", codec::encode(&ServerMsg::Welcome(welcome))),
        (
            "delta",
            codec::encode(&ServerMsg::Delta(SessionDelta {
                pose_seq: 17,
                complete: true,
                delta: delta.clone(),
            })),
        ),
        (
            "reconnect",
            codec::encode(&ServerMsg::Reconnect { after_ms: 500 }),
        ),
    ];
    out.push((
        "lod_request",
        codec::encode(&LodRequest {
            version: PROTOCOL_VERSION,
            lens: LENS,
            tau: 1.5,
            camera,
            base: Some(resume),
        }),
    ));
    out.push((
        "lod_response",
        codec::encode(&LodResponse { delta, snapshot }),
    ));
    out.into_iter().map(|(n, b)| (n.to_string(), b)).collect()
}
