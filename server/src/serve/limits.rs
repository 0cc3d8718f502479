//! Admission limits: slots counted in all and per IP address (sessions, connections), and
//! per-address token buckets (the connection rate, the resume work).
//!
//! A holder of a slot keeps a [`SlotPermit`]; dropping it (however the holder ends) gives the
//! slot back, so a panicking or cancelled task cannot leak one.

use std::collections::HashMap;
use std::net::IpAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Why a slot was not given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// Every slot of the server is taken.
    ServerFull,
    /// The address holds its maximum number of slots.
    PerAddress,
}

#[derive(Debug, Default)]
struct Counts {
    /// Slots taken in all.
    total: u32,
    /// Slots taken per address (entries at zero are removed).
    per_ip: HashMap<IpAddr, u32>,
}

/// Counts slots (sessions, or connections) against a total and a per-address limit.
#[derive(Debug)]
pub struct SlotLimits {
    /// Most slots at once.
    max_total: u32,
    /// Most slots at once per address.
    max_per_ip: u32,
    /// The counts, shared with the permits.
    counts: Arc<Mutex<Counts>>,
}

/// One slot, given back when dropped.
#[derive(Debug)]
pub struct SlotPermit {
    /// The counts to give the slot back to.
    counts: Arc<Mutex<Counts>>,
    /// The holder's address.
    ip: IpAddr,
}

impl SlotLimits {
    /// Limits of `max_total` slots and `max_per_ip` per address.
    pub fn new(max_total: u32, max_per_ip: u32) -> SlotLimits {
        SlotLimits {
            max_total,
            max_per_ip,
            counts: Arc::default(),
        }
    }

    /// Gives `ip` a slot, or says why not.
    pub fn admit(&self, ip: IpAddr) -> Result<SlotPermit, Refusal> {
        let mut c = self.counts.lock().unwrap_or_else(|e| e.into_inner());
        if c.total >= self.max_total {
            return Err(Refusal::ServerFull);
        }
        let n = c.per_ip.entry(ip).or_insert(0);
        if *n >= self.max_per_ip {
            return Err(Refusal::PerAddress);
        }
        *n += 1;
        c.total += 1;
        Ok(SlotPermit {
            counts: self.counts.clone(),
            ip,
        })
    }

    /// Slots taken now.
    pub fn open(&self) -> u32 {
        self.counts.lock().unwrap_or_else(|e| e.into_inner()).total
    }

    /// The total limit.
    pub fn max_total(&self) -> u32 {
        self.max_total
    }
}

impl Drop for SlotPermit {
    fn drop(&mut self) {
        let mut c = self.counts.lock().unwrap_or_else(|e| e.into_inner());
        c.total = c.total.saturating_sub(1);
        if let Some(n) = c.per_ip.get_mut(&self.ip) {
            *n -= 1;
            if *n == 0 {
                c.per_ip.remove(&self.ip);
            }
        }
    }
}

/// A token bucket per address: `rate` tokens a second up to `burst`.
///
/// A taker of `cost` tokens needs `min(cost, burst)` in the bucket, and may reserve them ahead
/// when it is willing to wait: the bucket goes negative by the cost, and the next taker waits
/// for that debt too. So one large piece of work (a resume of a big cut) is admitted at once,
/// the next waits in proportion, and a queue longer than a taker's patience is refused.
#[derive(Debug)]
pub struct IpBuckets {
    /// Tokens added per second.
    rate: f64,
    /// Bucket size.
    burst: f64,
    /// Tokens and last refill per address, and the table size at which full buckets are next
    /// forgotten (a full bucket is the same as no bucket).
    buckets: Mutex<(Buckets, usize)>,
}

/// Tokens and the last refill, per address.
type Buckets = HashMap<IpAddr, (f64, Instant)>;

/// The smallest table size that triggers forgetting full buckets.
const PRUNE_AT: usize = 4096;

impl IpBuckets {
    /// Buckets of `burst` tokens refilled at `rate` a second.
    pub fn new(rate: f64, burst: f64) -> IpBuckets {
        IpBuckets {
            rate,
            burst: burst.max(1.0),
            buckets: Mutex::new((HashMap::new(), PRUNE_AT)),
        }
    }

    /// The connection rate: `rate` a second, bursts of twice as many.
    pub fn connection_rate(rate: f64) -> IpBuckets {
        IpBuckets::new(rate, 2.0 * rate)
    }

    /// Takes `cost` tokens for `ip` at `now`, reserving them when they come within
    /// `patience`: `Ok(wait)` says how long to wait before the work (zero when the tokens are
    /// there), `Err(wait)` how long the wait would have been (nothing is taken).
    pub fn take(
        &self,
        ip: IpAddr,
        now: Instant,
        cost: f64,
        patience: Duration,
    ) -> Result<Duration, Duration> {
        let mut guard = self.buckets.lock().unwrap_or_else(|e| e.into_inner());
        let (b, prune_at) = &mut *guard;
        if b.len() >= *prune_at {
            let (rate, burst) = (self.rate, self.burst);
            b.retain(|_, (t, last)| {
                *t + now.saturating_duration_since(*last).as_secs_f64() * rate < burst
            });
            // Many busy addresses: wait for the table to double before the next sweep, so that
            // sweeps cost O(1) per taker on average instead of one each.
            *prune_at = (2 * b.len()).max(PRUNE_AT);
        }
        let (tokens, last) = b.entry(ip).or_insert((self.burst, now));
        *tokens = (*tokens + now.saturating_duration_since(*last).as_secs_f64() * self.rate)
            .min(self.burst);
        *last = now;
        let need = cost.min(self.burst);
        let wait = Duration::from_secs_f64(((need - *tokens) / self.rate).max(0.0));
        if wait <= patience {
            *tokens -= cost;
            Ok(wait)
        } else {
            Err(wait)
        }
    }

    /// Takes one token now: false when the address is over its rate.
    pub fn allow(&self, ip: IpAddr, now: Instant) -> bool {
        self.take(ip, now, 1.0, Duration::ZERO).is_ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn permits_count_and_give_back() {
        let l = SlotLimits::new(3, 2);
        let a: IpAddr = "10.0.0.1".parse().unwrap();
        let b: IpAddr = "10.0.0.2".parse().unwrap();
        let p1 = l.admit(a).unwrap();
        let _p2 = l.admit(a).unwrap();
        assert_eq!(l.admit(a).unwrap_err(), Refusal::PerAddress);
        let _p3 = l.admit(b).unwrap();
        assert_eq!(l.admit(b).unwrap_err(), Refusal::ServerFull);
        drop(p1);
        assert_eq!(l.open(), 2);
        assert!(l.admit(a).is_ok());
    }

    #[test]
    fn rate_allows_a_burst_then_the_rate() {
        let r = IpBuckets::connection_rate(10.0);
        let ip: IpAddr = "10.0.0.1".parse().unwrap();
        let t0 = Instant::now();
        let burst = (0..100).filter(|_| r.allow(ip, t0)).count();
        assert_eq!(burst, 20);
        // Half a second later: five more.
        let t1 = t0 + Duration::from_millis(500);
        assert_eq!((0..100).filter(|_| r.allow(ip, t1)).count(), 5);
        // Another address is unaffected.
        assert!(r.allow("10.0.0.2".parse().unwrap(), t1));
    }

    #[test]
    fn large_work_goes_ahead_then_is_paid_for_and_a_long_queue_is_refused() {
        // 1000 tokens a second, bursts of 2000: a 10,000-token piece goes at once; the next
        // reserves its turn 10 s on (8 s of debt plus 2 s to reach its burst); a third would
        // wait 20 s, past a patience of 15 s, and takes nothing.
        let r = IpBuckets::new(1000.0, 2000.0);
        let ip: IpAddr = "10.0.0.1".parse().unwrap();
        let t0 = Instant::now();
        let p = Duration::from_secs(15);
        assert_eq!(r.take(ip, t0, 10_000.0, p), Ok(Duration::ZERO));
        let wait = r.take(ip, t0, 10_000.0, p).unwrap();
        assert!((wait.as_secs_f64() - 10.0).abs() < 1e-6, "{wait:?}");
        let refused = r.take(ip, t0, 10_000.0, p).unwrap_err();
        assert!((refused.as_secs_f64() - 20.0).abs() < 1e-6, "{refused:?}");
        // Nothing was taken by the refusal: at 20 s the third goes at once.
        let t20 = t0 + Duration::from_secs(20);
        assert_eq!(r.take(ip, t20, 10_000.0, p), Ok(Duration::ZERO));
        // Small work from another address is not held up.
        assert_eq!(
            r.take("10.0.0.2".parse().unwrap(), t0, 500.0, Duration::ZERO),
            Ok(Duration::ZERO)
        );
    }

    #[test]
    fn full_buckets_are_forgotten_and_busy_ones_kept() {
        let r = IpBuckets::connection_rate(1.0);
        let t0 = Instant::now();
        for i in 0..PRUNE_AT as u32 {
            assert!(r.allow(IpAddr::from(i.to_be_bytes()), t0));
        }
        // Ten seconds on, every bucket has refilled: the sweep empties the table.
        let later = t0 + Duration::from_secs(10);
        assert!(r.allow("10.9.9.9".parse().unwrap(), later));
        assert_eq!(r.buckets.lock().unwrap().0.len(), 1);
    }
}
