//! Replays a recorded vertex stream (see `relief-server`'s `record_deltas` example) through the
//! client's path: decode, apply to the [`Mirror`], update the [`FanMesh`]. It prints the time
//! per pose (median and p99 over the poses, best of the runs) and per change, and checks the
//! final mesh against the oracle.
//!
//! `cargo run --release -p relief-proto --example replay -- FILE [RUNS] [POSES] [STAGES] [EVICT_MB]`
//!
//! STAGES is `all` (the default), `mirror` (decode and mirror, no fans) or `decode` (the
//! mirror then follows untimed), to split the cost. Two stages separated by a comma
//! (`mirror,all`) replay the stream through two clients in the same process, pose by pose,
//! each pose's order alternating, and print the median of the per-pose ratios (second over
//! first) as well: a paired comparison that the machine's drifts in speed do not skew
//! (`all,all` shows its noise: a median of 0.995, quartiles 0.948 to 1.040, on fuji_srtm3's
//! first 150 poses with 64 MB written before each pose). EVICT_MB (default 0) writes that many megabytes before each client's pose, untimed,
//! so that each pose starts with cold caches as in `relief-server bench lod`, where the
//! server's work runs between the client's.

use relief_proto::codec;
use relief_proto::delta::{BodyModels, Delta, Known};
use relief_proto::mesh::{FanMesh, oracle};
use relief_proto::mirror::Mirror;
use relief_proto::msg::ServerMsg;
use relief_proto::terrain::TerrainGeometry;
use std::time::Instant;

fn unwire(bytes: &[u8], geom: &TerrainGeometry, models: &mut BodyModels, mirror: &Mirror) -> Delta {
    match codec::decode::<ServerMsg>(bytes, codec::HARD_LIMIT).expect("decodes") {
        ServerMsg::Delta(d) => d
            .delta
            .unpack_in(&geom.shape, geom.z_quantum, models, Known::mirror(mirror))
            .expect("unpacks"),
        other => panic!("expected a delta, got {other:?}"),
    }
}

/// One pose, as the client takes it: returns the number of changes. Not inlined, so that a
/// profile can collect it alone (`valgrind --tool=callgrind --toggle-collect='replay::pose'`).
#[inline(never)]
fn pose(
    msg: &[u8],
    geom: &TerrainGeometry,
    mirror: &mut Mirror,
    mesh: &mut FanMesh,
    models: &mut BodyModels,
    stages: &str,
    pending: &mut Option<Delta>,
) -> usize {
    let d = unwire(msg, geom, models, mirror);
    let shape = &geom.shape;
    let changes = d.splits.len() + d.merges.len();
    match stages {
        // The mirror still follows, untimed: merges are ranks in the client's cut, so the
        // next delta decodes only against this one's result.
        "decode" => *pending = Some(d),
        "mirror" => mirror.apply(geom, &d, |_, _| {}).expect("applies"),
        _ => mirror
            .apply(geom, &d, |c, ch| mesh.update_around(shape, c, ch.node()))
            .expect("applies"),
    }
    changes
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let file = std::fs::read(&args[0]).expect("usage: replay FILE [RUNS] [POSES]");
    let runs: usize = args.get(1).map_or(3, |s| s.parse().expect("RUNS"));
    let poses: usize = args
        .get(2)
        .map_or(usize::MAX, |s| s.parse().expect("POSES"));
    let stages = args.get(3).map_or("all", String::as_str);
    let evict_mb: usize = args.get(4).map_or(0, |s| s.parse().expect("EVICT_MB"));
    let mut evict = vec![0u8; evict_mb << 20];
    let word = |at: usize| <[u8; 4]>::try_from(&file[at..at + 4]).expect("header");
    let f32_at = |at| f32::from_le_bytes(word(at));
    let (w, h) = (u32::from_le_bytes(word(0)), u32::from_le_bytes(word(4)));
    let geom = TerrainGeometry::new(w, h, f32_at(8), f32_at(12), f32_at(16)).expect("geometry");
    let root_z = i32::from_le_bytes(word(20));
    let mut msgs: Vec<&[u8]> = Vec::new();
    let mut at = 24;
    while at < file.len() && msgs.len() <= poses {
        let len = u32::from_le_bytes(word(at)) as usize;
        msgs.push(&file[at + 4..at + 4 + len]);
        at += 4 + len;
    }
    let shape = &geom.shape;
    let stages: Vec<&str> = stages.split(',').collect();
    let new_client = || {
        let mut mirror = Mirror::new(&geom, root_z);
        let mut models = BodyModels::new();
        let first = unwire(msgs[0], &geom, &mut models, &mirror);
        mirror.apply(&geom, &first, |_, _| {}).expect("initial cut");
        let mesh = FanMesh::new(shape, mirror.cut());
        (mirror, models, mesh)
    };
    // Per stage: the best run's time per pose.
    let mut best: Vec<Option<Vec<f64>>> = vec![None; stages.len()];
    let mut ratios = Vec::new();
    let mut changes = 0;
    for _ in 0..runs {
        let mut clients: Vec<_> = stages.iter().map(|_| new_client()).collect();
        let mut us = vec![Vec::with_capacity(msgs.len()); stages.len()];
        let mut pending = None;
        changes = 0;
        for (k, m) in msgs[1..].iter().enumerate() {
            for j in 0..stages.len() {
                // Alternate which client goes first.
                let i = (j + k) % stages.len();
                let (mirror, models, mesh) = &mut clients[i];
                evict.fill(k as u8);
                std::hint::black_box(&evict);
                let t0 = Instant::now();
                let n = pose(m, &geom, mirror, mesh, models, stages[i], &mut pending);
                us[i].push(t0.elapsed().as_secs_f64() * 1e6);
                if i == 0 {
                    changes += n;
                }
                if let Some(d) = pending.take() {
                    mirror.apply(&geom, &d, |_, _| {}).expect("applies");
                }
            }
        }
        for (i, (mirror, _, mesh)) in clients.iter().enumerate() {
            if stages[i] == "all" {
                assert_eq!(
                    mesh.triangles(),
                    oracle(shape, mirror.cut()),
                    "mesh differs"
                );
                eprintln!(
                    "{}: final cut: {} triangles, {} junction cells, {} active nodes; {:.2} \
                     cells recomputed per change (the initial mesh's included)",
                    stages[i],
                    mesh.triangle_count(),
                    mesh.cells().len(),
                    mirror.cut().active_count(),
                    mesh.work() as f64 / changes as f64,
                );
            }
        }
        if stages.len() == 2 {
            ratios.extend(us[0].iter().zip(&us[1]).map(|(a, b)| b / a));
        }
        let total = |v: &[f64]| v.iter().sum::<f64>();
        for (b, u) in best.iter_mut().zip(us) {
            if b.as_ref().is_none_or(|b| total(&u) < total(b)) {
                *b = Some(u);
            }
        }
    }
    for (stage, b) in stages.iter().zip(best) {
        let mut us = b.expect("at least one run");
        let total: f64 = us.iter().sum();
        us.sort_by(f64::total_cmp);
        let q = |p: f64| us[((us.len() - 1) as f64 * p).round() as usize];
        println!(
            "{stage}: poses {} changes {changes} ({:.0}/pose): per pose median {:.0} us p99 {:.0} us; per change {:.3} us",
            us.len(),
            changes as f64 / us.len() as f64,
            q(0.5),
            q(0.99),
            total / changes as f64,
        );
    }
    if !ratios.is_empty() {
        ratios.sort_by(f64::total_cmp);
        let q = |p: f64| ratios[((ratios.len() - 1) as f64 * p).round() as usize];
        println!(
            "{} over {}, per pose over {} poses of {runs} runs: median {:.3}, quartiles {:.3} to {:.3}",
            stages[1],
            stages[0],
            ratios.len() / runs.max(1),
            q(0.5),
            q(0.25),
            q(0.75),
        );
    }
}
