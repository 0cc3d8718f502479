//! The order-0 entropy of a run's split payloads under the delta body's own contexts
//! (`docs/vertex-stream.md`, "Bytes per split"): the benchmark's `split_entropy_bytes`.
//!
//! The body's range coder keeps one adaptive model per context: per level and component for the
//! details, one for the error residuals, one for the split positions' level steps and one for
//! their values. An ideal coder with the same contexts and the whole run's statistics known in
//! advance would spend, per symbol, the order-0 entropy of that context's symbols over the run.
//! [`SplitEntropy`] tallies the symbols of every split of every delta it is given and sums:
//! - **details**: their residuals against the prediction from the parent's details (protocol 5,
//!   [`super::predict`]), zigzag-mapped, by value, with one context per level and component
//!   (`dv`, `dh`, `dd`);
//! - **error residuals**: by value, one context;
//! - **positions**: the level step by value, and the position value (Morton gap or code) as its
//!   Exp-Golomb bucket (bit length of `v + 1`) plus the bits below the bucket's leading one at one
//!   bit each: positions spread over millions of values, so a by-value tally would merely count
//!   how rare each one is in this run.
//!
//! It is the cost of an ideal coder of these symbols with these contexts, each context's
//! distribution fixed for the run and known in advance. Merges are not in it:
//! `split_bytes_mean` counts them, so the two differ by the merges' positions too.
//! [`SplitEntropy::delta_bytes_per_split`] adds the merge positions (level steps and the buckets
//! of their ranks in the client's cut, protocol 5, in contexts of their own, raw bits at one bit
//! each): the benchmark's `delta_entropy_bytes`.
//!
//! Neither is a floor for the real coder. Its models adapt: where a context's statistics drift
//! along the path (near and far terrain, rough and smooth ground) they track them, and they carry
//! over from body to body within a connection; it also models the top two bits below each
//! position's leading one. On both benchmark terrains `split_bytes_mean` is below
//! `delta_entropy_bytes`.

use super::predict::Predictor;
use super::{Delta, Known, merge_positions, morton, positions, predicted_code};
use crate::bits::zigzag;
use crate::tree::TreeShape;
use rustc_hash::FxHashMap;

/// The contexts of the tally.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Context {
    /// One of the three details (`dv`, `dh`, `dd`) of splits at this level.
    Detail(u8, u8),
    /// The error residuals.
    Residual,
    /// The level steps of split positions.
    Step,
    /// The Exp-Golomb buckets of split position values.
    PositionBucket,
    /// The level steps of merge positions.
    MergeStep,
    /// The Exp-Golomb buckets of merge position values.
    MergePositionBucket,
}

impl Context {
    /// Whether the context is a merge's (not in the split payloads).
    fn is_merge(self) -> bool {
        matches!(self, Context::MergeStep | Context::MergePositionBucket)
    }
}

/// Symbol counts of the split payloads of many deltas.
#[derive(Clone, Debug, Default)]
pub struct SplitEntropy {
    /// How often each symbol occurred, per context.
    counts: FxHashMap<(Context, u64), u64>,
    /// Bits below the leading one of the split position values, counted at one bit each.
    raw_bits: u64,
    /// The same for the merge position values.
    merge_raw_bits: u64,
    /// Splits tallied.
    splits: u64,
}

impl SplitEntropy {
    /// Tallies the splits and merges of `delta`, coded with z quantum `quantum` against `known`
    /// (the parents and the cut after the delta) as the body coder codes them: the details'
    /// residuals and the merges' ranks are counted.
    pub fn add(&mut self, delta: &Delta, shape: &TreeShape, quantum: f32, known: Known<'_>) {
        let mut merges: Vec<_> = delta.merges.iter().map(|&n| (n.level, morton(n))).collect();
        merges.sort_unstable();
        let mut splits: Vec<_> = delta
            .splits
            .iter()
            .map(|s| (s.node.level, morton(s.node), s))
            .collect();
        splits.sort_unstable_by_key(|&(l, m, _)| (l, m));
        for (step, value) in merge_positions(&merges, &splits, known.cut) {
            self.count(Context::MergeStep, step as u64);
            let bucket = 64 - (value + 1).leading_zeros() as u64;
            self.count(Context::MergePositionBucket, bucket);
            self.merge_raw_bits += bucket - 1;
        }
        for (step, value) in positions(splits.iter().map(|&(l, m, _)| (l, m))) {
            self.count(Context::Step, step as u64);
            let bucket = 64 - (value + 1).leading_zeros() as u64;
            self.count(Context::PositionBucket, bucket);
            self.raw_bits += bucket - 1;
        }
        let mut predictor = Predictor::new(known.parents);
        for (k, &(level, _, s)) in splits.iter().enumerate() {
            let residuals = predictor.residuals(shape, &splits, k);
            for (i, r) in residuals.into_iter().enumerate() {
                self.count(Context::Detail(level, i as u8), r);
            }
            let residual = zigzag(s.err_code as i64 - predicted_code(s.details, quantum) as i64);
            self.count(Context::Residual, residual);
        }
        self.splits += splits.len() as u64;
    }

    fn count(&mut self, c: Context, symbol: u64) {
        *self.counts.entry((c, symbol)).or_default() += 1;
    }

    /// Splits tallied.
    pub fn splits(&self) -> u64 {
        self.splits
    }

    /// The entropy of the tallied split payloads, in bytes per split (0 with no splits).
    pub fn bytes_per_split(&self) -> f64 {
        (self.bits(false) + self.raw_bits as f64) / 8.0 / self.splits.max(1) as f64
    }

    /// The entropy of the split payloads and the merge positions together, in bytes per split:
    /// what a static model per context, fitted to the run, spends on its bodies (the counts
    /// aside).
    pub fn delta_bytes_per_split(&self) -> f64 {
        let bits = self.bits(false) + self.bits(true);
        (bits + (self.raw_bits + self.merge_raw_bits) as f64) / 8.0 / self.splits.max(1) as f64
    }

    /// Order-0 bits of the modelled symbols in the merges' contexts or in the others.
    fn bits(&self, merges: bool) -> f64 {
        let mut totals: FxHashMap<Context, u64> = FxHashMap::default();
        for (&(c, _), &n) in &self.counts {
            *totals.entry(c).or_default() += n;
        }
        self.counts
            .iter()
            .filter(|((c, _), _)| c.is_merge() == merges)
            .map(|(&(c, _), &n)| n as f64 * (totals[&c] as f64 / n as f64).log2())
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cut::Cut;
    use crate::delta::Split;
    use crate::delta::tests::{alone, full_cut};
    use crate::tree::{NodeId, TreeShape};

    /// A split of the level-3 node whose Morton code is `m`.
    fn split(m: u32, details: [i32; 3]) -> Split {
        let bits = |v: u32| (0..3).map(|i| ((v >> (2 * i)) & 1) << i).sum::<u32>();
        Split {
            node: NodeId {
                level: 3,
                x: bits(m),
                y: bits(m >> 1),
            },
            err_code: predicted_code(details, 0.1),
            details,
        }
    }

    #[test]
    fn constant_payloads_cost_only_their_positions() {
        // Neighbours with equal details: details and residuals carry nothing; the positions are
        // one step (first node) and gaps of 0 after it.
        let d = Delta {
            splits: (0..8).map(|x| split(x, [5, -3, 1])).collect(),
            ..Delta::default()
        };
        let mut e = SplitEntropy::default();
        e.add(
            &d,
            &TreeShape::new(65, 65).unwrap(),
            0.1,
            alone(&Cut::root(&TreeShape::new(65, 65).unwrap())),
        );
        assert_eq!(e.splits(), 8);
        // Steps {3, 0 x7} and buckets {1 x8}: H(steps) = 8 * h(1/8) bits, no raw bits.
        let h = (1.0f64 / 8.0) * 8f64.log2() + (7.0 / 8.0) * (8.0f64 / 7.0).log2();
        assert!(
            (e.bytes_per_split() - h / 8.0).abs() < 1e-9,
            "{} {}",
            e.bytes_per_split(),
            h / 8.0
        );
    }

    #[test]
    fn the_entropy_never_exceeds_the_packed_body() {
        let shape = TreeShape::new(65, 65).unwrap();
        let root = Cut::root(&shape);
        let d = Delta {
            splits: (0..8)
                .map(|x| split(x, [x as i32 * 7 - 20, (x as i32 - 4).pow(3), x as i32 % 3]))
                .collect(),
            ..Delta::default()
        };
        let mut e = SplitEntropy::default();
        e.add(&d, &shape, 0.1, alone(&root));
        assert!(e.bytes_per_split() * 8.0 <= d.pack_body(&shape, 0.1, alone(&root)).len() as f64);
        assert_eq!(e.delta_bytes_per_split(), e.bytes_per_split());
    }

    #[test]
    fn merges_count_in_the_delta_entropy_only() {
        let shape = TreeShape::new(65, 65).unwrap();
        // Every inner node interior but the merged ones: a merge's rank is its Morton gap.
        let mut after = full_cut(&shape);
        let mut d = Delta {
            splits: (0..8).map(|x| split(x, [5, -3, 1])).collect(),
            ..Delta::default()
        };
        let mut e = SplitEntropy::default();
        e.add(&d, &shape, 0.1, alone(&after));
        let splits_only = e.bytes_per_split();
        // Merges far apart: their gaps carry raw bits.
        d.merges = (0..4)
            .map(|i| NodeId {
                level: 6,
                x: i * 7,
                y: 3 * i,
            })
            .collect();
        for &m in &d.merges {
            after.merge(&shape, m).unwrap();
        }
        let mut e = SplitEntropy::default();
        e.add(&d, &shape, 0.1, alone(&after));
        assert_eq!(e.bytes_per_split(), splits_only);
        // Morton codes 0, 31, 124, 403: steps {6, 0, 0, 0}, values 0, 30, 92, 278 in buckets
        // {1, 5, 7, 9} with 0 + 4 + 6 + 8 raw bits.
        let steps = 4.0 * (0.25 * 4f64.log2() + 0.75 * (4.0f64 / 3.0).log2());
        let buckets = 4.0 * 4f64.log2();
        let want = splits_only + (steps + buckets + 18.0) / 8.0 / 8.0;
        assert!(
            (e.delta_bytes_per_split() - want).abs() < 1e-9,
            "{}",
            e.delta_bytes_per_split()
        );
    }
}
