//! A bystander: an ordinary session that keeps flying while a test attacks the server, and
//! records how long each of its poses took to be answered. The hostile-input tests compare
//! its latency during an attack with its latency before.

use relief_client::session::{Counters, Session, SessionConfig};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::time::{Duration, Instant};
use tokio::sync::Mutex;

/// A session flying a loop in the background.
pub struct Bystander {
    /// Pose latencies so far.
    latencies: Arc<Mutex<Vec<Duration>>>,
    /// Tells the flight to stop.
    stop: Arc<AtomicBool>,
    /// The flight; its result is the session's counters.
    task: tokio::task::JoinHandle<Counters>,
}

/// Median, 90th percentile and maximum of some latencies, milliseconds.
#[derive(Clone, Copy, Debug)]
pub struct Latency {
    /// Poses measured.
    pub n: usize,
    /// Median.
    pub median_ms: f64,
    /// 90th percentile.
    pub p90_ms: f64,
    /// 99th percentile.
    pub p99_ms: f64,
    /// Largest.
    pub max_ms: f64,
}

impl Latency {
    /// The figures of `v`.
    pub fn of(v: &[Duration]) -> Latency {
        let mut ms: Vec<f64> = v.iter().map(|d| d.as_secs_f64() * 1e3).collect();
        ms.sort_by(f64::total_cmp);
        let at = |q: f64| {
            ms.get(((ms.len() as f64 - 1.0) * q).round() as usize)
                .copied()
        };
        Latency {
            n: ms.len(),
            median_ms: at(0.5).unwrap_or(f64::NAN),
            p90_ms: at(0.9).unwrap_or(f64::NAN),
            p99_ms: at(0.99).unwrap_or(f64::NAN),
            max_ms: ms.last().copied().unwrap_or(f64::NAN),
        }
    }
}

impl Bystander {
    /// Connects to `url` and flies path `which` (see [`crate::path`]) in a loop, a pose every
    /// 20 ms after the previous was answered.
    pub async fn start(url: &str, which: usize) -> Bystander {
        Self::start_with(SessionConfig::new(url), which, Duration::from_millis(20)).await
    }

    /// A bystander with `config`, a pose every `gap` after the previous was answered.
    pub async fn start_with(config: SessionConfig, which: usize, gap: Duration) -> Bystander {
        let mut s = Session::connect(config).await.expect("bystander connects");
        let latencies = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let cams = crate::path(which, 120);
        let task = tokio::spawn({
            let (latencies, stop) = (latencies.clone(), stop.clone());
            async move {
                for cam in cams.iter().cycle() {
                    if stop.load(Relaxed) {
                        break;
                    }
                    let t = Instant::now();
                    let seq = s.send_pose(*cam).await.expect("bystander pose");
                    s.wait_for_pose(seq).await.expect("bystander delta");
                    latencies.lock().await.push(t.elapsed());
                    tokio::time::sleep(gap).await;
                }
                s.counters()
            }
        });
        Bystander {
            latencies,
            stop,
            task,
        }
    }

    /// Latencies recorded from now on for `d`.
    pub async fn measure(&self, d: Duration) -> Latency {
        let from = self.latencies.lock().await.len();
        tokio::time::sleep(d).await;
        Latency::of(&self.latencies.lock().await[from..])
    }

    /// Latencies recorded while `work` runs, and after it (while what it returns, such as
    /// held connections, is still alive) until at least five poses were answered, or 5 s.
    pub async fn during<F: Future>(&self, work: F) -> (F::Output, Latency) {
        let from = self.latencies.lock().await.len();
        let out = work.await;
        let deadline = Instant::now() + Duration::from_secs(5);
        while self.latencies.lock().await.len() < from + 5 && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        let l = Latency::of(&self.latencies.lock().await[from..]);
        (out, l)
    }

    /// Stops the flight; returns the session's counters.
    pub async fn stop(self) -> Counters {
        self.stop.store(true, Relaxed);
        self.task.await.expect("bystander flight")
    }
}

/// Asserts that the bystander kept its latency under attack: the attack's 90th percentile
/// within four times the calm one plus 100 ms, and no pose over 2 s. Prints both.
pub fn assert_kept(what: &str, calm: Latency, attacked: Latency) {
    eprintln!("bystander during {what}: calm {calm:?}, attacked {attacked:?}");
    assert!(attacked.n > 0, "{what}: the bystander got no answer at all");
    assert!(
        attacked.p90_ms <= 4.0 * calm.p90_ms + 100.0 && attacked.max_ms <= 2000.0,
        "{what}: bystander latency went from {calm:?} to {attacked:?}"
    );
}
