//! When a session's groups are due: distance bands with odometers and timing wheels of flat,
//! reused buckets (see [`super::session`] for what a group is and how its slack is found).
//!
//! - **Bands.** A group is filed in the band of its *reach* (the furthest distance from the eye of
//!   anything it checks, plus its slack). Bands are quarter octaves: band `b` holds reaches up to
//!   `2^(b/4) (5 + b mod 4) / 4` metres, read off the reach's float exponent and top two mantissa
//!   bits (no libm). The band's bound overestimates a reach by at most 25 %.
//! - **Odometers.** Each band's odometer advances by the eye's travel plus the band's bound times
//!   the chord of the camera's rotation, `2 sin(theta / 2)`, the most a point that far away can
//!   move relative to the camera (from the basis vectors' moves: their squares sum to twice the
//!   chord's square); all bands' odometers come from two running sums, the travel and the
//!   chords. A group is due when its band's odometer
//!   passes the reading at filing plus its slack.
//! - **Wheels.** A band's wheel has 16 buckets of `bound / 16` metres of odometer each; a slack
//!   beyond the wheel's horizon (14 buckets, 0.875 of the band's bound) is cut to it (the group
//!   is then examined once per turn, which is conservative; on fuji_srtm3 no more groups were
//!   examined than with a horizon of four bounds, and small sessions hold a quarter of the
//!   bucket headers). Buckets are `Vec`s that keep up to their share of the wheel's entries when
//!   drained, so filing seldom allocates once the session has warmed up and a burst does not
//!   hold memory; draining a band touches only the buckets the odometer passed.
//! - **Entries.** One `u64`: the node packed in 32 bits (level, row, column; inner nodes fit), the
//!   due reading in units of 1/256 bucket (low 24 bits, compared with wrapping arithmetic, rounded
//!   down), and the generation the node had when filed. A node filed again gets a new generation,
//!   so its older entry is recognised as stale when drained (the generation lives in the cut's
//!   tag byte).

use glam::Vec3;
use relief_proto::tree::NodeId;
use relief_proto::view::ViewState;

/// Quarter-octave bands from 1 m to 2^48 m.
const BANDS: usize = 192;
/// Buckets per wheel.
const WHEEL: u64 = 16;
/// Buckets per band bound.
const BUCKETS_PER_BOUND: f64 = 16.0;
/// Key units per bucket.
const UNITS: u64 = 256;
/// The largest slack a wheel holds, in buckets: a full turn less one.
const HORIZON_BUCKETS: f64 = (WHEEL - 2) as f64;
/// Added to the rotation's chord against rounding in the view bases (unit vectors to about
/// 1e-7).
const CHORD_GUARD: f64 = 1e-6;

/// The band of a group whose reach is `reach` metres.
pub fn band_of(reach: f32) -> usize {
    let r = reach.max(1.0);
    if !r.is_finite() {
        return BANDS - 1;
    }
    // Exponent and top two mantissa bits: 4 e + q, for r in [2^e (1 + q/4), 2^e (1 + (q+1)/4)).
    let b = (r.to_bits() >> 21) as i64 - (127 << 2);
    (b.max(0) as usize).min(BANDS - 1)
}

/// The largest reach band `b` holds, metres.
pub fn band_bound(b: usize) -> f64 {
    // 2^(b / 4) built from its exponent bits (b / 4 < 48).
    f64::from_bits((1023 + (b >> 2) as u64) << 52) * (5 + (b & 3)) as f64 / 4.0
}

/// Odometer units per metre in band `b`.
fn per_metre(b: usize) -> f64 {
    BUCKETS_PER_BOUND * UNITS as f64 / band_bound(b)
}

/// A node packed in 32 bits: level (4 bits), row and column (14 bits each). Inner nodes fit:
/// their level is below the tree's depth (at most 15), so their row and column are below 2^14.
pub fn pack_node(n: NodeId) -> u32 {
    debug_assert!(n.level < 15 && n.x < 1 << 14 && n.y < 1 << 14);
    (n.level as u32) << 28 | n.y << 14 | n.x
}

/// The node of [`pack_node`].
pub fn unpack_node(v: u32) -> NodeId {
    NodeId {
        level: (v >> 28) as u8,
        x: v & 0x3FFF,
        y: (v >> 14) & 0x3FFF,
    }
}

/// The node and generation of an entry.
pub fn entry_parts(e: u64) -> (NodeId, u8) {
    (unpack_node((e >> 32) as u32), e as u8)
}

fn entry(node: NodeId, key: u64, generation: u8) -> u64 {
    (pack_node(node) as u64) << 32 | (key & 0xFF_FFFF) << 8 | generation as u64
}

/// An upper bound on how far the camera's turn from basis `a` to basis `b` moves a point at
/// unit distance relative to the camera: the chord `2 sin(theta / 2)` of the rotation's angle.
/// For a rotation, `sum |b - a|^2` over the basis vectors is `6 - 2 trace R`, twice the chord's
/// square; summed from the differences, a small turn's chord stays accurate where `3 - trace`
/// would cancel in single precision.
pub fn chord(a: &[Vec3; 3], b: &[Vec3; 3]) -> f64 {
    let moved: f64 = a
        .iter()
        .zip(b.iter())
        .map(|(a, b)| (*a - *b).length_squared() as f64)
        .sum();
    (moved / 2.0).sqrt() + CHORD_GUARD
}

/// One band's wheel.
#[derive(Default)]
struct Wheel {
    /// `WHEEL` buckets once the band is first used; bucket `b mod WHEEL` holds absolute bucket `b`.
    buckets: Vec<Vec<u64>>,
    /// The absolute bucket of the odometer at the last drain.
    cursor: u64,
    /// Entries held.
    live: usize,
}

/// All bands' wheels and odometers.
pub struct Schedule {
    /// Per band up to the highest one used.
    wheels: Vec<Wheel>,
    /// Metres the eye travelled since the session began.
    travel: f64,
    /// Sum of the rotations' chords since the session began: band `b`'s odometer is
    /// `travel + band_bound(b) * turn`.
    turn: f64,
    /// The previous update's eye and view basis.
    previous: Option<(Vec3, [Vec3; 3])>,
    /// Entries due at the next update whatever the motion.
    next: Vec<u64>,
}

impl Default for Schedule {
    fn default() -> Self {
        Schedule {
            wheels: Vec::new(),
            travel: 0.0,
            turn: 0.0,
            previous: None,
            next: Vec::new(),
        }
    }
}

impl Schedule {
    /// Band `b`'s odometer: metres of camera-relative motion of a point `band_bound(b)` from
    /// the eye since the session began.
    fn odometer(&self, b: usize) -> f64 {
        self.travel + band_bound(b) * self.turn
    }

    /// Advances the odometers by the camera's motion since the last call.
    pub fn advance(&mut self, view: &ViewState) {
        let eye = view.eye();
        let basis = view.basis();
        if let Some((pe, pb)) = self.previous {
            let travel = (eye - pe).length() as f64;
            self.travel += travel;
            self.turn += chord(&pb, &basis);
        }
        self.previous = Some((eye, basis));
    }

    /// Files `node` with generation `generation`: due once its band's odometer has advanced by
    /// `slack` metres. `reach` bounds the distance from the eye of what the group checks.
    pub fn file(&mut self, node: NodeId, generation: u8, slack: f64, reach: f64) {
        let band = band_of((reach + slack) as f32);
        let per_metre = per_metre(band);
        let slack_units = (slack * per_metre).min(HORIZON_BUCKETS * UNITS as f64);
        let key = (self.odometer(band) * per_metre + slack_units) as u64;
        if self.wheels.len() <= band {
            self.wheels.resize_with(band + 1, Wheel::default);
        }
        let wheel = &mut self.wheels[band];
        if wheel.buckets.is_empty() {
            wheel.buckets = (0..WHEEL).map(|_| Vec::new()).collect();
        }
        let bucket = (key / UNITS).max(wheel.cursor);
        wheel.buckets[(bucket % WHEEL) as usize].push(entry(node, key, generation));
        wheel.live += 1;
    }

    /// Files `node` with generation `generation` as due at the next update.
    pub fn file_next(&mut self, node: NodeId, generation: u8) {
        self.next.push(entry(node, 0, generation));
    }

    /// Number of bands in use, for [`Schedule::drain_band`].
    pub fn bands(&self) -> usize {
        self.wheels.len()
    }

    /// Moves the entries filed for the next update into `out`; the caller checks each against
    /// the node's current generation.
    pub fn drain_next(&mut self, out: &mut Vec<u64>) {
        out.append(&mut self.next);
        if self.next.capacity() > 256 {
            self.next.shrink_to(64);
        }
    }

    /// Moves band `band`'s due entries into `out`; the caller checks each against the node's
    /// current generation. Entries filed meanwhile into a band not yet drained may come out in
    /// the same update if already due: examining a group early is only extra work.
    pub fn drain_band(&mut self, band: usize, out: &mut Vec<u64>) {
        let now = (self.odometer(band) * per_metre(band)) as u64;
        let wheel = &mut self.wheels[band];
        {
            let target = now / UNITS;
            if wheel.live == 0 {
                wheel.cursor = target;
                return;
            }
            let first = wheel.cursor;
            let last = target.min(first + WHEEL - 1);
            for b in first..=last {
                let bucket = &mut wheel.buckets[(b % WHEEL) as usize];
                if b < target || target >= first + WHEEL {
                    // Wholly passed: every entry is due.
                    wheel.live -= bucket.len();
                    out.append(bucket);
                    // Keep about a bucket's share of the wheel: a bucket that once took a burst
                    // (the horizon's, say) must not hold its peak for ever.
                    let keep = wheel.live / WHEEL as usize;
                    if bucket.capacity() > keep + keep / 2 + 4 {
                        bucket.shrink_to(keep);
                    }
                } else {
                    // The odometer's own bucket: due entries only.
                    let before = bucket.len();
                    bucket.retain(|&e| {
                        let key = (e >> 8) & 0xFF_FFFF;
                        let behind = (now as u32).wrapping_sub(key as u32) & 0xFF_FFFF;
                        if behind < 1 << 23 {
                            out.push(e);
                            false
                        } else {
                            true
                        }
                    });
                    wheel.live -= before - bucket.len();
                }
            }
            wheel.cursor = target.max(first);
            if wheel.live == 0 {
                // An empty band gives its buckets back.
                wheel.buckets = Vec::new();
            }
        }
    }

    /// Bytes of memory held.
    pub fn memory_bytes(&self) -> usize {
        let wheels: usize = self
            .wheels
            .iter()
            .map(|w| {
                w.buckets.capacity() * std::mem::size_of::<Vec<u64>>()
                    + w.buckets.iter().map(|b| b.capacity() * 8).sum::<usize>()
            })
            .sum();
        wheels + self.next.capacity() * 8 + self.wheels.capacity() * std::mem::size_of::<Wheel>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_bound_their_reaches_within_a_quarter() {
        let mut r = 1.0f32;
        while r < 1e9 {
            let b = band_of(r);
            assert!(band_bound(b) >= r as f64, "{r} in band {b}");
            assert!(band_bound(b) <= 1.25 * r as f64 + 1e-9, "{r} in band {b}");
            r *= 1.07;
        }
        assert_eq!(band_of(0.2), 0);
        assert_eq!(band_of(f32::INFINITY), BANDS - 1);
    }

    #[test]
    fn the_chord_bounds_a_turn_tightly_even_when_small() {
        use relief_proto::view::{Camera, Lens};
        for turn in [1e-5f32, 1e-3, 0.05, 0.7] {
            let cam = |yaw: f32, pitch: f32| {
                ViewState::new(
                    &Camera {
                        eye: Vec3::ZERO,
                        yaw,
                        pitch,
                    },
                    &Lens::STANDARD,
                )
                .basis()
            };
            let (a, b) = (cam(0.3, -0.4), cam(0.3 + turn, -0.4));
            let c = chord(&a, &b);
            // Every basis vector (so every point at unit distance) moves by at most the chord...
            for (u, v) in a.iter().zip(&b) {
                assert!(((*u - *v).length() as f64) <= c, "turn {turn}");
            }
            // ...which is the turn's true chord, not a loose bound on it.
            let truth = 2.0 * (turn as f64 / 2.0).sin();
            assert!(c <= 1.01 * truth + 2e-6, "turn {turn}: {c} vs {truth}");
        }
    }

    #[test]
    fn nodes_pack_and_entries_keep_their_generation() {
        let n = NodeId {
            level: 14,
            x: 16383,
            y: 9,
        };
        assert_eq!(unpack_node(pack_node(n)), n);
        assert_eq!(entry_parts(entry(n, 123_456_789, 77)), (n, 77));
    }
}
