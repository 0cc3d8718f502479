//! When a session's groups are due: distance bands with odometers and timing wheels of flat,
//! reused buckets (see [`super::session`] for what a group is and how its slack is found).
//!
//! - **Bands.** A group is filed in the band of its *lever* (how far a unit of the rotation's
//!   chord may move what it checks, at most the furthest distance from the eye of what it checks:
//!   see the session's `Bounds`), or of its slack where that is larger. Bands are quarter
//!   octaves: band `b` holds levers up to `2^(b/4) (5 + b mod 4) / 4` metres, read off the
//!   lever's float exponent and top two mantissa bits (no libm). The band's bound overestimates a
//!   lever by at most 25 %.
//! - **Odometers.** Each band's odometer advances by the eye's travel plus the band's bound times
//!   the chord of the camera's rotation, `2 sin(theta / 2)` (from the basis vectors' moves: their
//!   squares sum to twice the chord's square); all bands' odometers come from two running sums,
//!   the travel and the chords. A group is due when its band's odometer passes the reading at
//!   filing plus its slack.
//! - **Wheels.** A band's wheel has 16 buckets of `bound / 16` metres of odometer each; a slack
//!   beyond the wheel's horizon (14 buckets, 0.875 of the band's bound) is cut to it (the group
//!   is then examined once per turn, which is conservative; on fuji_srtm3 no more groups were
//!   examined than with a horizon of four bounds, and small sessions hold a quarter of the
//!   bucket headers). Draining a band touches only the buckets the odometer passed. The wheels
//!   lie in one array, from the lowest band in use to the highest, each holding its buckets
//!   in place.
//! - **Entries.** One `u32`: the node's index in the nominal quadtree (levels one after another,
//!   row-major on a level's `2^l x 2^l` lattice, so the level comes back from the index's
//!   leading zeros and the row and column from shifts), the due reading's place within its
//!   bucket (8 bits on grids up to 2049 a side, 7 on 4097, 3 on 16385; rounded down,
//!   so an entry is never held past its due reading, only drained up to that fraction of a bucket
//!   early) and the generation the node had when filed (2 to 4 bits, in what is left). A node
//!   filed again gets a new generation, so its older entry is recognised as stale when drained
//!   (the generation lives in the cut's tag); one whose node has since been filed a multiple
//!   of 4 (or 16) times again passes for current, which costs one early examination.
//! - **Chunks.** A bucket is a list of 32-entry chunks taken from one pool per session, so a
//!   session holds its entries plus a partly filled chunk per bucket, not each bucket's largest
//!   burst; the pool keeps a sixteenth of the chunks in use between updates and gives back the
//!   rest. A bucket holds its first chunk's pointer itself (24 bytes, the further chunks'
//!   list boxed): on a server holding many sessions each update starts with its session's
//!   state out of the caches, and filing into a bucket or draining one then misses on the
//!   wheel's line and the chunk's, not on a list's buffer between them as well (with
//!   a list per bucket, filing and draining took 23 % of the server's time at 750 crop
//!   sessions, and 17 % this way).

use glam::Vec3;
use relief_proto::tree::NodeId;
use relief_proto::view::ViewState;

/// Quarter-octave bands from 1 m to 2^48 m.
const BANDS: usize = 192;
/// Buckets per wheel.
const WHEEL: u64 = 16;
/// Buckets per band bound.
const BUCKETS_PER_BOUND: f64 = 16.0;
/// Key units per bucket (the finest an entry's reading within its bucket can be).
const UNITS: u64 = 256;
/// The largest slack a wheel holds, in buckets: a full turn less one.
const HORIZON_BUCKETS: f64 = (WHEEL - 2) as f64;
/// Added to the rotation's chord against rounding in the view bases (unit vectors to about
/// 1e-7).
const CHORD_GUARD: f64 = 1e-6;
/// Entries per chunk.
const CHUNK: usize = 32;

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
pub const fn band_bound(b: usize) -> f64 {
    // 2^(b / 4) built from its exponent bits (b / 4 < 48).
    f64::from_bits((1023 + (b >> 2) as u64) << 52) * (5 + (b & 3)) as f64 / 4.0
}

/// Each band's bound (a table: a filing reads it for the band's odometer).
const BOUNDS: [f64; BANDS] = {
    let mut t = [0.0; BANDS];
    let mut b = 0;
    while b < BANDS {
        t[b] = band_bound(b);
        b += 1;
    }
    t
};

/// Odometer units per metre in each band (a table: a filing would otherwise divide).
const PER_METRE: [f64; BANDS] = {
    let mut t = [0.0; BANDS];
    let mut b = 0;
    while b < BANDS {
        t[b] = BUCKETS_PER_BOUND * UNITS as f64 / band_bound(b);
        b += 1;
    }
    t
};

/// An odometer reading in units (finite and not negative, far below `2^63`) as an integer:
/// through `i64`, one conversion instruction where `u64`'s takes a dozen on x86-64.
fn units(reading: f64) -> u64 {
    debug_assert!((0.0..9e18).contains(&reading));
    (reading as i64).max(0) as u64
}

/// Odometer units per metre in band `b`.
fn per_metre(b: usize) -> f64 {
    PER_METRE[b]
}

/// The number of nodes above each level in the nominal (power-of-two) quadtree:
/// `(4^l - 1) / 3`.
const ABOVE: [u32; 16] = {
    let mut t = [0u32; 16];
    let mut l = 1;
    while l < 16 {
        t[l] = t[l - 1] + (1 << (2 * (l - 1)));
        l += 1;
    }
    t
};

/// `n`'s index in the nominal quadtree: the nodes of the levels above it, then its row and
/// column on its level's `2^l x 2^l` lattice. An inner node of a tree of depth at most 15 fits
/// in 29 bits.
pub fn node_index(n: NodeId) -> u32 {
    debug_assert!(n.level < 15 && n.x >> n.level == 0 && n.y >> n.level == 0);
    ABOVE[n.level as usize & 15] + (n.y << n.level | n.x)
}

/// The node of [`node_index`]: `3 k + 1` lies in `[4^l, 4^(l+1))`.
pub fn index_node(k: u32) -> NodeId {
    let t = 3 * k as u64 + 1;
    let level = ((63 - t.leading_zeros()) / 2) as u8;
    let m = k - ABOVE[level as usize & 15];
    NodeId {
        level,
        x: m & ((1 << level) - 1),
        y: m >> level,
    }
}

/// How an entry's 32 bits are shared for a tree of a given depth: the node's index on top, then
/// the reading within the bucket, then the generation.
#[derive(Clone, Copy, Debug)]
struct Packing {
    /// Bits of generation.
    gen_bits: u32,
    /// Bits of the due reading within its bucket.
    fine_bits: u32,
}

impl Packing {
    fn new(depth: u8) -> Packing {
        // Inner nodes are at levels 0 to depth - 1.
        let last = ABOVE[depth.min(15) as usize].saturating_sub(1);
        let free = last.leading_zeros();
        // The reading's bits save more examinations than generation bits beyond two do: a
        // stale entry that matches (its node filed a multiple of 4 times since) is only
        // examined early, while a coarse reading drains every entry of a bucket early.
        let fine_bits = free.saturating_sub(2).min(8);
        Packing {
            gen_bits: (free - fine_bits).min(4),
            fine_bits,
        }
    }

    fn entry(&self, node: NodeId, fine: u32, generation: u8) -> u32 {
        let low = self.fine_bits + self.gen_bits;
        let gen_mask = (1u32 << self.gen_bits) - 1;
        ((node_index(node) as u64) << low) as u32
            | fine << self.gen_bits
            | generation as u32 & gen_mask
    }

    fn parts(&self, e: u32) -> (NodeId, u8) {
        let low = self.fine_bits + self.gen_bits;
        let node = ((e as u64) >> low) as u32;
        (index_node(node), (e & ((1 << self.gen_bits) - 1)) as u8)
    }

    /// The place of key `key` within its bucket, rounded down to the entry's bits.
    fn fine_of(&self, key: u64) -> u32 {
        ((key % UNITS) >> (8 - self.fine_bits)) as u32
    }

    fn fine(&self, e: u32) -> u32 {
        (e >> self.gen_bits) & ((1 << self.fine_bits) - 1)
    }
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

/// A chunk of entries: it moves between buckets and the pool as a pointer, never copied.
type Chunk = Box<[u32; CHUNK]>;

/// Chunks not in use, shared by a session's buckets.
#[derive(Default)]
struct Pool {
    free: Vec<Chunk>,
    /// Chunks held by buckets.
    used: usize,
    /// Words in the buckets' lists of further chunks (their `rest`: each list's three and its
    /// room), summed: kept as they grow and shrink, so that the schedule's memory is known
    /// without visiting every bucket.
    rest_room: usize,
}

impl Pool {
    fn take(&mut self) -> Chunk {
        self.used += 1;
        self.free.pop().unwrap_or_else(|| Box::new([0; CHUNK]))
    }

    fn give(&mut self, c: Chunk) {
        self.used -= 1;
        self.free.push(c);
    }

    /// Gives back to the allocator what is beyond a sixteenth of the chunks in use.
    fn trim(&mut self) {
        let keep = 8 + self.used / 16;
        if self.free.len() > keep {
            self.free.truncate(keep);
            if self.free.capacity() > 4 * keep {
                self.free.shrink_to(keep);
            }
        }
    }
}

/// One bucket: its entries in chunks, all full but the last. The first chunk's pointer is held
/// in the bucket itself, which lies in its wheel: filing into a bucket of up to a chunk of
/// entries, or draining it, reads the wheel's line and the chunk's, where a list would add the
/// line of its own buffer, a miss of its own on a loaded server. The list of further
/// chunks is boxed, so that a bucket takes 24 bytes.
#[derive(Default)]
struct Bucket {
    len: u32,
    first: Option<Chunk>,
    /// The chunks after the first, once there are any.
    #[allow(
        clippy::box_collection,
        reason = "a box is one word in the bucket where a list is three"
    )]
    rest: Option<Box<Vec<Chunk>>>,
}

impl Bucket {
    /// Chunk `j` (it exists: `j` is below `len / CHUNK`, rounded up).
    fn chunk(&mut self, j: usize) -> &mut [u32; CHUNK] {
        let c = if j == 0 {
            self.first.as_mut()
        } else {
            self.rest.as_mut().and_then(|r| r.get_mut(j - 1))
        };
        c.unwrap_or_else(|| unreachable!("bucket chunk {j} of {} entries", self.len))
    }

    fn push(&mut self, e: u32, pool: &mut Pool) {
        let (j, i) = (self.len as usize / CHUNK, self.len as usize % CHUNK);
        if i == 0 {
            let c = pool.take();
            if j == 0 {
                self.first = Some(c);
            } else {
                let rest = self.rest.get_or_insert_with(|| {
                    // The list's own three words.
                    pool.rest_room += 3;
                    Box::default()
                });
                let room = rest.capacity();
                rest.push(c);
                pool.rest_room += rest.capacity() - room;
            }
        }
        self.chunk(j)[i] = e;
        self.len += 1;
    }

    /// Gives back the chunks beyond those `self.len` entries fill.
    fn release(&mut self, pool: &mut Pool) {
        let needed = (self.len as usize).div_ceil(CHUNK);
        if let Some(rest) = &mut self.rest {
            while rest.len() + 1 > needed.max(1) {
                if let Some(c) = rest.pop() {
                    pool.give(c);
                }
            }
            if rest.is_empty() && rest.capacity() > 8 {
                // Long lists go; short ones stay for the next burst.
                pool.rest_room -= rest.capacity() + 3;
                self.rest = None;
            }
        }
        if needed == 0
            && let Some(c) = self.first.take()
        {
            pool.give(c);
        }
    }

    /// Moves every entry into `out`.
    fn drain(&mut self, out: &mut Vec<u32>, pool: &mut Pool) {
        let mut left = self.len as usize;
        for c in self
            .first
            .iter()
            .chain(self.rest.iter().flat_map(|r| r.iter()))
        {
            out.extend_from_slice(&c[..left.min(CHUNK)]);
            left = left.saturating_sub(CHUNK);
        }
        self.len = 0;
        self.release(pool);
    }

    /// Moves the entries for which `due` holds into `out`, keeping the others in order. Without
    /// a branch on `due`, which a predictor guesses no better than a coin: each entry is
    /// written both to a small staging buffer and back into the bucket, and only one of the two
    /// positions moves on (staging keeps `out` from growing by the entries kept).
    fn drain_due(&mut self, out: &mut Vec<u32>, pool: &mut Pool, due: impl Fn(u32) -> bool) {
        let len = self.len as usize;
        let mut staged = [0u32; CHUNK];
        let (mut taken, mut kept) = (0, 0);
        for j in 0..len.div_ceil(CHUNK) {
            // A copy of the chunk read, so that the one written (the same or an earlier one:
            // `kept` is at most the entries read) can be borrowed.
            let read = *self.chunk(j);
            let mut w = j;
            let mut write = self.chunk(w);
            for &e in &read[..(len - j * CHUNK).min(CHUNK)] {
                let d = due(e) as usize;
                staged[taken] = e;
                taken += d;
                if taken == CHUNK {
                    out.extend_from_slice(&staged);
                    taken = 0;
                }
                if kept / CHUNK != w {
                    w = kept / CHUNK;
                    write = self.chunk(w);
                }
                write[kept % CHUNK] = e;
                kept += 1 - d;
            }
        }
        out.extend_from_slice(&staged[..taken]);
        self.len = kept as u32;
        self.release(pool);
    }
}

/// One band's wheel, its buckets in place: the wheels lie one after another, so a band's cursor
/// and buckets are found without following a pointer.
#[derive(Default)]
struct Wheel {
    /// The absolute bucket of the odometer at the last drain.
    cursor: u64,
    /// Entries held.
    live: usize,
    /// Bucket `b mod WHEEL` holds absolute bucket `b`.
    buckets: [Bucket; WHEEL as usize],
}

/// All bands' wheels and odometers.
pub struct Schedule {
    /// Per band from the lowest used (`base`) to the highest.
    wheels: Vec<Wheel>,
    /// The band of `wheels[0]`.
    base: usize,
    /// The chunks the buckets are made of.
    pool: Pool,
    /// How entries are packed for this tree.
    packing: Packing,
    /// Metres the eye travelled since the session began.
    travel: f64,
    /// Sum of the rotations' chords since the session began: band `b`'s odometer is
    /// `travel + band_bound(b) * turn`.
    turn: f64,
    /// The previous update's eye and view basis.
    previous: Option<(Vec3, [Vec3; 3])>,
    /// Entries due at the next update whatever the motion.
    next: Vec<u32>,
}

impl Schedule {
    /// An empty schedule for a tree of depth `depth`.
    pub fn new(depth: u8) -> Schedule {
        Schedule {
            wheels: Vec::new(),
            base: 0,
            pool: Pool::default(),
            packing: Packing::new(depth),
            travel: 0.0,
            turn: 0.0,
            previous: None,
            next: Vec::new(),
        }
    }

    /// Band `b`'s odometer: metres of camera-relative motion of a point `band_bound(b)` from
    /// the eye since the session began.
    fn odometer(&self, b: usize) -> f64 {
        self.travel + BOUNDS[b] * self.turn
    }

    /// Advances the odometers by the camera's motion since the last call, and gives back the
    /// chunks the last update freed beyond the pool's share.
    pub fn advance(&mut self, view: &ViewState) {
        self.pool.trim();
        let eye = view.eye();
        let basis = view.basis();
        if let Some((pe, pb)) = self.previous {
            let travel = (eye - pe).length() as f64;
            self.travel += travel;
            self.turn += chord(&pb, &basis);
        }
        self.previous = Some((eye, basis));
    }

    /// The node and generation of entry `e`.
    pub fn entry_parts(&self, e: u32) -> (NodeId, u8) {
        self.packing.parts(e)
    }

    /// What of tag `tag` an entry keeps as its generation.
    pub fn generation(&self, tag: u8) -> u8 {
        tag & ((1 << self.packing.gen_bits) - 1) as u8
    }

    /// Files `node` with generation `generation`: due once the eye's travel plus `lever` times
    /// the rotation's chords, both since now, reach `slack` metres. It goes in the band of
    /// `lever` (or of `slack`, if larger: a wheel holds slacks up to most of its band's bound).
    pub fn file(&mut self, node: NodeId, generation: u8, slack: f64, lever: f64) {
        let band = band_of(lever.max(slack) as f32);
        let per_metre = per_metre(band);
        let slack_units = (slack * per_metre).min(HORIZON_BUCKETS * UNITS as f64);
        let reading = self.odometer(band) * per_metre;
        let key = units(reading + slack_units);
        let i = self.wheel_for(band);
        let wheel = &mut self.wheels[i];
        if wheel.live == 0 {
            // A band taken up again starts at its odometer, as a drain would leave it.
            wheel.cursor = wheel.cursor.max(units(reading) / UNITS);
        }
        // Already due (the band's cursor is past its bucket): due at the cursor's first drain.
        let (bucket, fine) = if key / UNITS < wheel.cursor {
            (wheel.cursor, 0)
        } else {
            (key / UNITS, self.packing.fine_of(key))
        };
        let e = self.packing.entry(node, fine, generation);
        wheel.buckets[(bucket % WHEEL) as usize].push(e, &mut self.pool);
        wheel.live += 1;
    }

    /// The place of band `band`'s wheel, made (with those between it and the bands in use) if need be. The
    /// wheels run from the lowest band used to the highest, exactly: a wheel holds its
    /// buckets, so doubling the room, or starting at band 0 (a session's levers start at tens
    /// of metres), would hold as many again unused.
    fn wheel_for(&mut self, band: usize) -> usize {
        if self.wheels.is_empty() {
            self.base = band;
        }
        if band < self.base {
            let more = self.base - band;
            self.wheels.reserve_exact(more);
            self.wheels
                .splice(0..0, (0..more).map(|_| Wheel::default()));
            self.base = band;
        }
        let i = band - self.base;
        if self.wheels.len() <= i {
            self.wheels.reserve_exact(i + 1 - self.wheels.len());
            self.wheels.resize_with(i + 1, Wheel::default);
        }
        i
    }

    /// Files `node` with generation `generation` as due at the next update.
    pub fn file_next(&mut self, node: NodeId, generation: u8) {
        self.next.push(self.packing.entry(node, 0, generation));
    }

    /// Moves the entries filed for the next update into `out`; the caller checks each against
    /// the node's current generation.
    pub fn drain_next(&mut self, out: &mut Vec<u32>) {
        out.append(&mut self.next);
        if self.next.capacity() > 256 {
            self.next.shrink_to(64);
        }
    }

    /// Moves every band's due entries into `out`, band after band from the lowest; the caller
    /// checks each against the node's current generation.
    pub fn drain_bands(&mut self, out: &mut Vec<u32>) {
        for i in 0..self.wheels.len() {
            self.drain_band(self.base + i, out);
        }
    }

    /// Moves band `band`'s due entries into `out` (a band in use). An entry in the odometer's
    /// own bucket may come out up to its reading's rounding early: examining a group early is
    /// only extra work.
    fn drain_band(&mut self, band: usize, out: &mut Vec<u32>) {
        let now = units(self.odometer(band) * per_metre(band));
        let packing = self.packing;
        let wheel = &mut self.wheels[band - self.base];
        let target = now / UNITS;
        if wheel.live == 0 {
            wheel.cursor = target;
            return;
        }
        let first = wheel.cursor;
        let last = target.min(first + WHEEL - 1);
        let now_fine = packing.fine_of(now);
        for b in first..=last {
            let bucket = &mut wheel.buckets[(b % WHEEL) as usize];
            let before = bucket.len;
            if b < target || target >= first + WHEEL {
                // Wholly passed: every entry is due.
                bucket.drain(out, &mut self.pool);
            } else {
                // The odometer's own bucket: due entries only (an entry a whole turn ahead
                // may come out early).
                bucket.drain_due(out, &mut self.pool, |e| packing.fine(e) <= now_fine);
            }
            wheel.live -= (before - bucket.len) as usize;
        }
        wheel.cursor = target.max(first);
    }

    /// Bytes of memory held.
    pub fn memory_bytes(&self) -> usize {
        // The wheels hold their buckets, each the pointer to its first chunk; the pool counts
        // the chunks and the room of the lists of further ones.
        self.wheels.capacity() * std::mem::size_of::<Wheel>()
            + (self.pool.used + self.pool.free.len()) * CHUNK * 4
            + self.pool.rest_room * 8
            + self.pool.free.capacity() * 8
            + self.next.capacity() * 4
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
        for (level, x, y) in [
            (0, 0, 0),
            (1, 1, 0),
            (5, 31, 17),
            (11, 2047, 0),
            (14, 16383, 9),
        ] {
            let n = NodeId { level, x, y };
            assert_eq!(index_node(node_index(n)), n);
            let depth = level + 1;
            let p = Packing::new(depth);
            let fine = (1 << p.fine_bits) - 1;
            let e = p.entry(n, fine, 13);
            assert_eq!(
                p.parts(e),
                (n, 13 & ((1 << p.gen_bits) - 1)),
                "depth {depth}"
            );
            assert_eq!(p.fine(e), fine);
        }
        // Bits left for the reading within a bucket, by grid side.
        let fine = |d: u8| Packing::new(d).fine_bits;
        assert_eq!(
            [fine(10), fine(11), fine(12), fine(14), fine(15)],
            [8, 8, 7, 3, 1]
        );
        let generation = |d: u8| Packing::new(d).gen_bits;
        assert_eq!(
            [
                generation(10),
                generation(11),
                generation(12),
                generation(15)
            ],
            [4, 3, 2, 2]
        );
    }

    #[test]
    fn an_entry_is_never_drained_late_nor_early_beyond_its_rounding() {
        // The eye moves 1 m an update, without turning; groups 60 m away are filed with slacks
        // of 0.3 to 40 m (so in a few bands).
        use relief_proto::view::{Camera, Lens};
        let view = |x: f32| {
            ViewState::new(
                &Camera {
                    eye: Vec3::new(x, 0.0, 100.0),
                    yaw: 0.0,
                    pitch: -0.3,
                },
                &Lens::STANDARD,
            )
        };
        let mut s = Schedule::new(12);
        s.advance(&view(0.0));
        let slacks: Vec<f64> = (0..400).map(|i| 0.3 + i as f64 * 0.1).collect();
        for (i, &slack) in slacks.iter().enumerate() {
            let n = index_node(i as u32 + 1);
            s.file(n, 1, slack, 60.0);
        }
        let mut seen = vec![false; slacks.len()];
        let mut out = Vec::new();
        for step in 1..=60 {
            let travel = step as f64;
            s.advance(&view(step as f32));
            s.drain_bands(&mut out);
            for e in out.drain(..) {
                let (n, g) = s.entry_parts(e);
                assert_eq!(g, 1);
                let i = node_index(n) as usize - 1;
                assert!(!seen[i], "{i} drained twice");
                seen[i] = true;
                // At most the reading's rounding early (1/128 of a bucket at depth 12).
                let bound = band_bound(band_of((60.0 + slacks[i]) as f32));
                let due = slacks[i].min(bound * HORIZON_BUCKETS / BUCKETS_PER_BOUND);
                let rounding = bound / BUCKETS_PER_BOUND / (1u32 << s.packing.fine_bits) as f64;
                assert!(travel >= due - rounding - 1e-6, "{i} early at {step}");
            }
            // Never late.
            for (i, &slack) in slacks.iter().enumerate() {
                if !seen[i] {
                    assert!(travel < slack, "{i} (slack {slack}) late at {step}");
                }
            }
        }
        assert!(seen.iter().all(|&x| x));
    }

    proptest::proptest! {
        /// A bucket of any size keeps its entries in order through pushes and drains: a drain of
        /// the due ones gives exactly those, in order, and keeps the others, in order; the
        /// chunks held are those the entries fill, and the pool gets the others back.
        #[test]
        fn buckets_keep_their_entries_in_order(
            rounds in proptest::collection::vec((0u32..80, 0u32..4, proptest::bool::ANY), 1..12),
        ) {
            let mut pool = Pool::default();
            let mut bucket = Bucket::default();
            let mut model: Vec<u32> = Vec::new();
            let mut next = 0u32;
            for (pushes, modulus, all) in rounds {
                for _ in 0..pushes {
                    bucket.push(next, &mut pool);
                    model.push(next);
                    next += 1;
                }
                let mut out = Vec::new();
                if all {
                    bucket.drain(&mut out, &mut pool);
                    proptest::prop_assert_eq!(&out, &model);
                    model.clear();
                } else {
                    let due = |e: u32| modulus != 0 && e.is_multiple_of(modulus + 1);
                    bucket.drain_due(&mut out, &mut pool, due);
                    let (taken, left): (Vec<u32>, Vec<u32>) = model.iter().partition(|&&e| due(e));
                    proptest::prop_assert_eq!(&out, &taken);
                    model = left;
                }
                proptest::prop_assert_eq!(bucket.len as usize, model.len());
                proptest::prop_assert_eq!(pool.used, model.len().div_ceil(CHUNK));
                let mut all = Vec::new();
                let mut copy = Bucket::default();
                std::mem::swap(&mut copy, &mut bucket);
                copy.drain(&mut all, &mut pool);
                proptest::prop_assert_eq!(&all, &model);
                for &e in &model {
                    bucket.push(e, &mut pool);
                }
            }
        }
    }
}
