//! `relief-client load --queries MIX`: simulator back ends instead of viewers. Each back end
//! is one query session ([`crate::query`]) driving `--entities` entities that move over the
//! terrain; every tick (`--rate` per second) it sends one batch: HAT/HOT for every entity
//! (with `hat` in the mix), plus the mix's rays (from entities, half grazing at 1-5 degrees
//! down, half steep at 20-80 degrees) and lines of sight (between random pairs of entities,
//! 1 m clearance). Batches are pipelined, at most [`MAX_OUTSTANDING`] unanswered; the latency
//! of a batch runs from its send to its answers' arrival.
//!
//! The stage's report is the stream load test's ([`super::StageReport`]): a batch counts as a
//! pose and its answers as a delta, and [`super::stats`] adds the queries answered per second
//! and the server's CPU per query.

use super::{LoadOptions, SessionOutcome};
use crate::query::{QueryClient, Reply};
use relief_proto::codec;
use relief_proto::msg::{ClientMsg, TerrainInfo};
use relief_proto::query::{Answer, Query, QueryBatch};
use relief_proto::rng::Rng;
use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::{Duration, Instant};
use tokio::sync::{Mutex, Semaphore};

/// Most batches a back end has unanswered; at the limit it waits before its next tick's batch.
pub const MAX_OUTSTANDING: usize = 8;

/// What each back end asks every tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QueryMix {
    /// HAT/HOT for every entity.
    pub hat: bool,
    /// Rays.
    pub rays: usize,
    /// Lines of sight.
    pub sights: usize,
}

impl std::str::FromStr for QueryMix {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let mut mix = QueryMix {
            hat: false,
            rays: 0,
            sights: 0,
        };
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (name, n) =
                match part.split_once('=') {
                    Some((k, v)) => (
                        k.trim(),
                        Some(v.trim().parse::<usize>().map_err(|_| {
                            format!("--queries {s:?}: {v:?} is not a whole number")
                        })?),
                    ),
                    None => (part, None),
                };
            match (name, n) {
                ("hat", None) => mix.hat = true,
                ("ray" | "rays", Some(n)) => mix.rays = n,
                ("sight" | "los", Some(n)) => mix.sights = n,
                _ => {
                    return Err(format!(
                        "--queries {s:?}: {part:?} is not hat, ray=N or sight=N \
                         (e.g. hat,ray=10,sight=10)"
                    ));
                }
            }
        }
        if !mix.hat && mix.rays == 0 && mix.sights == 0 {
            return Err(format!("--queries {s:?} asks for nothing"));
        }
        Ok(mix)
    }
}

impl std::fmt::Display for QueryMix {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut parts = Vec::new();
        if self.hat {
            parts.push("hat".to_string());
        }
        if self.rays > 0 {
            parts.push(format!("ray={}", self.rays));
        }
        if self.sights > 0 {
            parts.push(format!("sight={}", self.sights));
        }
        f.write_str(&parts.join(","))
    }
}

/// A query load: the mix and the entities per back end.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QueryLoad {
    /// What each tick asks.
    pub mix: QueryMix,
    /// Entities per back end.
    pub entities: usize,
}

impl QueryLoad {
    /// Queries in one tick's batch.
    pub fn batch_len(&self) -> usize {
        (if self.mix.hat { self.entities } else { 0 }) + self.mix.rays + self.mix.sights
    }
}

/// One moving entity.
#[derive(Clone, Copy, Debug)]
struct Entity {
    /// Position, metres.
    p: [f64; 3],
    /// Heading, radians.
    heading: f64,
    /// Ground speed, metres per second.
    speed: f64,
}

/// A back end's entities and the batches they ask.
pub struct Fleet {
    /// The entities.
    entities: Vec<Entity>,
    /// The terrain's extent east and north, metres.
    extent: [f64; 2],
    /// What each tick asks.
    load: QueryLoad,
    /// Picks ray directions and sight pairs.
    rng: Rng,
}

impl Fleet {
    /// `load.entities` entities placed at random over `terrain`, 10 m to 500 m above its
    /// highest point minus its relief (so some are low, some high), moving at 5-60 m/s.
    pub fn new(terrain: &TerrainInfo, load: QueryLoad, seed: u64) -> Fleet {
        let mut rng = Rng::new(seed);
        let extent = [
            f64::from(terrain.width.saturating_sub(1)) * f64::from(terrain.spacing_x),
            f64::from(terrain.height.saturating_sub(1)) * f64::from(terrain.spacing_y),
        ];
        let [lo, hi] = terrain.height_range.map(f64::from);
        let entities = (0..load.entities)
            .map(|_| Entity {
                p: [
                    rng.range(0.0, extent[0]),
                    rng.range(0.0, extent[1]),
                    rng.range(lo + 10.0, hi + 500.0),
                ],
                heading: rng.range(0.0, std::f64::consts::TAU),
                speed: rng.range(5.0, 60.0),
            })
            .collect();
        Fleet {
            entities,
            extent,
            load,
            rng,
        }
    }

    /// Moves every entity `dt` seconds, turning back at the terrain's edges.
    pub fn advance(&mut self, dt: f64) {
        for e in &mut self.entities {
            for (axis, v) in [e.heading.cos(), e.heading.sin()].into_iter().enumerate() {
                let next = e.p[axis] + v * e.speed * dt;
                if (0.0..=self.extent[axis]).contains(&next) {
                    e.p[axis] = next;
                } else {
                    // Reflect the heading in this axis.
                    e.heading = if axis == 0 {
                        std::f64::consts::PI - e.heading
                    } else {
                        -e.heading
                    };
                }
            }
        }
    }

    /// This tick's batch.
    pub fn batch(&mut self, id: u64) -> QueryBatch {
        let mut queries = Vec::with_capacity(self.load.batch_len());
        if self.load.mix.hat {
            queries.extend(self.entities.iter().map(|e| Query::Hat { at: e.p }));
        }
        let n = self.entities.len();
        for k in 0..self.load.mix.rays {
            let e = self.entities[self.rng.below(n)];
            let yaw = self.rng.range(0.0, std::f64::consts::TAU);
            let down = if k % 2 == 0 {
                self.rng.range(1.0, 5.0)
            } else {
                self.rng.range(20.0, 80.0)
            }
            .to_radians();
            queries.push(Query::Ray {
                origin: e.p,
                dir: [yaw.cos() * down.cos(), yaw.sin() * down.cos(), -down.sin()],
                max_dist: None,
            });
        }
        for _ in 0..self.load.mix.sights {
            let (a, b) = (self.rng.below(n), self.rng.below(n));
            queries.push(Query::Sight {
                from: self.entities[a].p,
                to: self.entities[b].p,
                clearance: 1.0,
            });
        }
        QueryBatch { id, queries }
    }
}

/// One back end's plan.
pub(super) struct BackEnd {
    /// The stage's options.
    pub opts: LoadOptions,
    /// Its load.
    pub load: QueryLoad,
    /// Its index (seeds its fleet).
    pub index: usize,
    /// The stage's clock.
    pub t0: Instant,
    /// When it connects.
    pub start: Instant,
    /// When it stops.
    pub stop: Instant,
    /// The stage's running count of answered batches, for the progress bar.
    pub answered: Arc<AtomicU64>,
}

/// Runs one back end: connect at its start, tick until its stop, then collect the answers
/// still due.
pub(super) async fn back_end(plan: BackEnd) -> SessionOutcome {
    tokio::time::sleep_until(plan.start.into()).await;
    let began = Instant::now();
    let client = match QueryClient::connect(&plan.opts.url).await {
        Ok(c) => c,
        Err(e) => {
            return SessionOutcome {
                error: Some(e.to_string()),
                ..SessionOutcome::default()
            };
        }
    };
    let mut fleet = Fleet::new(
        &client.welcome.terrain,
        plan.load,
        plan.opts.seed.wrapping_add(plan.index as u64),
    );
    let (mut tx, mut rx) = client.split();
    let period =
        (plan.opts.rate_hz > 0.0).then(|| Duration::from_secs_f64(1.0 / plan.opts.rate_hz));
    // On a clock, up to MAX_OUTSTANDING batches in flight; without one, one at a time.
    let window = Arc::new(Semaphore::new(if period.is_some() {
        MAX_OUTSTANDING
    } else {
        1
    }));
    let sent_at: Arc<Mutex<VecDeque<(u64, Instant)>>> = Arc::default();
    let t0 = plan.t0;
    let receiver = {
        let (window, sent_at, answered) = (window.clone(), sent_at.clone(), plan.answered.clone());
        tokio::spawn(async move {
            let mut t = SessionOutcome::default();
            loop {
                let (reply, bytes) = match rx.next().await {
                    Ok(r) => r,
                    Err(e) => {
                        // The sender closing its half ends the session: not an error once
                        // every batch is answered.
                        if !sent_at.lock().await.is_empty() {
                            t.error = Some(e.to_string());
                        }
                        return t;
                    }
                };
                let Some((id, at)) = sent_at.lock().await.pop_front() else {
                    t.error = Some("an answer to a batch never sent".into());
                    return t;
                };
                if reply.id() != id {
                    t.error = Some(format!(
                        "answers to batch {} came before {id}'s",
                        reply.id()
                    ));
                    return t;
                }
                window.add_permits(1);
                answered.fetch_add(1, Relaxed);
                let ms = at.elapsed().as_secs_f64() * 1e3;
                let log = &mut t.log;
                if log.first_latency_ms.is_none() {
                    log.first_latency_ms = Some(ms);
                } else {
                    log.latencies_ms.push(ms);
                }
                let sec = t0.elapsed().as_secs() as usize;
                if log.bytes_per_second.len() <= sec {
                    log.bytes_per_second.resize(sec + 1, 0);
                }
                log.bytes_per_second[sec] += bytes as u64;
                t.counters.deltas += 1;
                t.counters.bytes_in += bytes as u64;
                match reply {
                    Reply::Answers(a) => {
                        t.queries += a.answers.len() as u64;
                        t.query_faults += a
                            .answers
                            .iter()
                            .filter(|a| matches!(a, Answer::Error { .. }))
                            .count() as u64;
                    }
                    Reply::Refused(r) => {
                        t.error = Some(format!("batch {} refused: {}", r.id, r.reason));
                        return t;
                    }
                }
            }
        })
    };
    let mut next = Instant::now();
    let mut last_move = Instant::now();
    let mut sent = 0u64;
    let mut send_error = None;
    while Instant::now() < plan.stop {
        // The receiver gives the permit back when the batch's answers arrive.
        let Ok(permit) = window.acquire().await else {
            break;
        };
        permit.forget();
        let now = Instant::now();
        fleet.advance(now.duration_since(last_move).as_secs_f64());
        last_move = now;
        sent += 1;
        let bytes = codec::encode(&ClientMsg::Query(fleet.batch(sent)));
        sent_at.lock().await.push_back((sent, Instant::now()));
        if let Err(e) = tx.send_encoded(bytes).await {
            send_error = Some(e.to_string());
            break;
        }
        if let Some(p) = period {
            next += p;
            tokio::time::sleep_until(next.into()).await;
        }
    }
    // Wait for the answers still due (at most a few seconds), then close.
    let deadline = Instant::now() + Duration::from_secs(10);
    while !sent_at.lock().await.is_empty() && Instant::now() < deadline && !receiver.is_finished() {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    tx.close().await;
    let mut out = match tokio::time::timeout(Duration::from_secs(5), receiver).await {
        Ok(Ok(t)) => t,
        Ok(Err(e)) => SessionOutcome {
            error: Some(format!("back end panicked: {e}")),
            ..SessionOutcome::default()
        },
        Err(_) => SessionOutcome {
            error: Some("answers did not arrive within 10 s of the stage's end".into()),
            ..SessionOutcome::default()
        },
    };
    out.log.poses = sent as usize;
    if out.error.is_none() {
        out.error = send_error;
    }
    out.flown_s = began.elapsed().as_secs_f64();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn terrain() -> TerrainInfo {
        TerrainInfo {
            id: 1,
            width: 101,
            height: 51,
            spacing_x: 10.0,
            spacing_y: 20.0,
            z_quantum: 0.25,
            root_z: 0,
            height_range: [100.0, 900.0],
        }
    }

    #[test]
    fn mixes_parse_and_print_back() {
        let m: QueryMix = "hat,ray=10,sight=5".parse().unwrap();
        assert_eq!(
            m,
            QueryMix {
                hat: true,
                rays: 10,
                sights: 5
            }
        );
        assert_eq!(m.to_string(), "hat,ray=10,sight=5");
        assert_eq!("los=3".parse::<QueryMix>().unwrap().sights, 3);
        for bad in ["", "hat,ray", "ray=x", "cows", "ray=0"] {
            assert!(bad.parse::<QueryMix>().is_err(), "{bad}");
        }
    }

    #[test]
    fn a_tick_asks_the_mix_and_entities_stay_on_the_terrain() {
        let load = QueryLoad {
            mix: "hat,ray=4,sight=3".parse().unwrap(),
            entities: 50,
        };
        let mut f = Fleet::new(&terrain(), load, 9);
        for _ in 0..200 {
            f.advance(1.0);
        }
        let b = f.batch(3);
        assert_eq!(b.id, 3);
        assert_eq!(b.queries.len(), load.batch_len());
        assert_eq!(b.queries.iter().filter(|q| q.is_line()).count(), 7);
        for q in &b.queries {
            if let Query::Hat { at } = q {
                assert!((0.0..=1000.0).contains(&at[0]) && (0.0..=1000.0).contains(&at[1]));
            }
        }
    }
}
