//! Admission limits: sessions in all and per IP address, and the per-IP connection rate.
//!
//! A session holds a [`SessionPermit`]; dropping it (however the session ends) gives its slot
//! back, so a panicking or cancelled session task cannot leak one.

use std::collections::HashMap;
use std::net::IpAddr;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Why a session was not admitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// The server holds its maximum number of sessions.
    ServerFull,
    /// The address holds its maximum number of sessions.
    PerAddress,
}

#[derive(Debug, Default)]
struct Counts {
    /// Sessions open in all.
    total: u32,
    /// Sessions open per address (entries at zero are removed).
    per_ip: HashMap<IpAddr, u32>,
}

/// Counts open sessions against the limits.
#[derive(Debug)]
pub struct SessionLimits {
    /// Most sessions at once.
    max_total: u32,
    /// Most sessions at once per address.
    max_per_ip: u32,
    /// The counts, shared with the permits.
    counts: Arc<Mutex<Counts>>,
}

/// One admitted session's slot.
#[derive(Debug)]
pub struct SessionPermit {
    /// The counts to give the slot back to.
    counts: Arc<Mutex<Counts>>,
    /// The session's address.
    ip: IpAddr,
}

impl SessionLimits {
    /// Limits of `max_total` sessions and `max_per_ip` per address.
    pub fn new(max_total: u32, max_per_ip: u32) -> SessionLimits {
        SessionLimits {
            max_total,
            max_per_ip,
            counts: Arc::default(),
        }
    }

    /// Admits a session from `ip`, or says why not.
    pub fn admit(&self, ip: IpAddr) -> Result<SessionPermit, Refusal> {
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
        Ok(SessionPermit {
            counts: self.counts.clone(),
            ip,
        })
    }

    /// Sessions open now.
    pub fn open(&self) -> u32 {
        self.counts.lock().unwrap_or_else(|e| e.into_inner()).total
    }
}

impl Drop for SessionPermit {
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

/// A token bucket per address: `rate` connections per second, bursts of `2 * rate`.
#[derive(Debug)]
pub struct ConnectionRate {
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

impl ConnectionRate {
    /// A limiter of `rate` connections per second per address.
    pub fn new(rate: f64) -> ConnectionRate {
        ConnectionRate {
            rate,
            burst: (2.0 * rate).max(1.0),
            buckets: Mutex::new((HashMap::new(), PRUNE_AT)),
        }
    }

    /// Takes a token for a connection from `ip` at `now`; false when the address is over rate.
    pub fn allow(&self, ip: IpAddr, now: Instant) -> bool {
        let mut guard = self.buckets.lock().unwrap_or_else(|e| e.into_inner());
        let (b, prune_at) = &mut *guard;
        if b.len() >= *prune_at {
            let (rate, burst) = (self.rate, self.burst);
            b.retain(|_, (t, last)| {
                *t + now.saturating_duration_since(*last).as_secs_f64() * rate < burst
            });
            // Many busy addresses: wait for the table to double before the next sweep, so that
            // sweeps cost O(1) per connection on average instead of one each.
            *prune_at = (2 * b.len()).max(PRUNE_AT);
        }
        let (tokens, last) = b.entry(ip).or_insert((self.burst, now));
        *tokens = (*tokens + now.saturating_duration_since(*last).as_secs_f64() * self.rate)
            .min(self.burst);
        *last = now;
        if *tokens >= 1.0 {
            *tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn permits_count_and_give_back() {
        let l = SessionLimits::new(3, 2);
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
        let r = ConnectionRate::new(10.0);
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
    fn full_buckets_are_forgotten_and_busy_ones_kept() {
        let r = ConnectionRate::new(1.0);
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
