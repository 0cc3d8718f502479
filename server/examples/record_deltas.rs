//! Records the vertex stream's deltas over a camera path to a file, as they go on the wire, for
//! `relief-proto`'s `replay` example (the client's decode, mirror and fans, timed or profiled
//! without the server's work around it).
//!
//! `cargo run --release -p relief-server --example record_deltas -- DEM OUT [FRAMES]`
//!
//! The file holds the grid's width, height, spacings, z quantum and root height (little-endian
//! u32, u32, f32, f32, f32, i32), then each pose's encoded `ServerMsg::Delta` with its u32 byte
//! length in front; the first is the session's initial cut.

use relief_proto::codec;
use relief_proto::msg::{ServerMsg, SessionDelta, WireDelta};
use relief_proto::path::PathKind;
use relief_proto::view::{Lens, ViewState};
use relief_server::bench::flight::Flight;
use relief_server::dem::{self, LoadOptions};
use relief_server::lod::vertex::session::VertexSession;
use relief_server::lod::vertex::{LodParams, UpdateStats, VertexEngine};
use std::io::Write;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [dem, out, rest @ ..] = args.as_slice() else {
        anyhow::bail!("usage: record_deltas DEM OUT [FRAMES]");
    };
    let frames: usize = rest.first().map_or(Ok(usize::MAX), |s| s.parse())?;
    let dem = dem::load(dem, &LoadOptions::default())?;
    let flight = Flight::prepare(
        &dem,
        PathKind::Standard,
        relief_server::preprocess::BuildOptions {
            tile_size: 256,
            ..Default::default()
        },
        Some(usize::MAX),
        1,
        false,
    )?;
    let store = &flight.store;
    let engine = VertexEngine::new(store);
    let geom = store.geometry();
    let (lens, p) = (Lens::STANDARD, LodParams::default());
    let mut session = VertexSession::new(&engine, &ViewState::new(&flight.cams[0], &lens), &p);
    let mut file = std::io::BufWriter::new(std::fs::File::create(out)?);
    let s = &geom.shape;
    file.write_all(&s.width().to_le_bytes())?;
    file.write_all(&s.height().to_le_bytes())?;
    for v in [geom.frame.dx, geom.frame.dy, geom.z_quantum] {
        file.write_all(&v.to_le_bytes())?;
    }
    file.write_all(&store.root_z().to_le_bytes())?;
    // One connection: the body models carry from each delta to the next.
    let mut models = relief_proto::delta::BodyModels::new();
    // Each body is packed against the session's cut after it.
    let mut write = |delta: &relief_proto::delta::Delta,
                     after: &relief_proto::cut::Cut|
     -> anyhow::Result<()> {
        let known = relief_proto::delta::Known {
            parents: &engine,
            cut: after,
        };
        let bytes = codec::encode(&ServerMsg::Delta(SessionDelta {
            pose_seq: delta.seq,
            complete: true,
            delta: WireDelta::pack_in(delta, s, &mut models, geom.z_quantum, known),
        }));
        file.write_all(&(bytes.len() as u32).to_le_bytes())?;
        Ok(file.write_all(&bytes)?)
    };
    write(&engine.full_delta(session.cut_ref(), 0), session.cut_ref())?;
    let mut changes = 0;
    for (f, cam) in flight.cams.iter().enumerate().skip(1).take(frames) {
        let view = ViewState::new(cam, &lens);
        let d = session.update(&engine, &view, &p, f as u64, &mut UpdateStats::default());
        changes += d.splits.len() + d.merges.len();
        write(&d, session.cut_ref())?;
    }
    file.flush()?;
    eprintln!(
        "{} poses, {changes} changes",
        flight.cams.len().min(frames.saturating_add(1))
    );
    Ok(())
}
