//! The background pool: the threads that run long computations (one-shot LOD steps, query
//! batches, ray-cast pictures, raster tiles, the parsing and writing of large JSON bodies, and the
//! updates of sessions that have grown expensive), apart from the sessions' ordinary updates.
//!
//! Sessions' updates run on the async workers when cheap and on tokio's blocking pool when not;
//! this pool has threads of its own, so that a flood of one-shots never queues ahead of a session.
//! Its threads also run at a lower scheduling priority (nice [`NICE`] on Linux): on a machine with
//! every core busy, the kernel gives the short session work the CPU first, and the long work
//! still gets every idle cycle. Work is admitted through slots (one per thread), and a caller
//! waits for a slot asynchronously, holding no thread.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use tokio::sync::{Semaphore, oneshot};

/// The nice value of the pool's threads: where both want the same core, the kernel's scheduler
/// gives a nice-10 thread about a tenth of the CPU a nice-0 thread gets (weights 110 and 1024).
pub const NICE: u32 = 10;

/// A unit of work.
type Job = Box<dyn FnOnce() + Send>;

/// Why the pool did not give back a result.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum PoolError {
    /// The server is stopping: no more work is taken.
    #[error("the server is stopping")]
    Stopping,
    /// The work panicked (logged where it happened).
    #[error("the computation failed")]
    Panicked,
}

/// Threads at a lower priority, and the slots that admit work to them.
pub struct Pool {
    /// One per thread: a job admitted always finds a thread free.
    slots: Semaphore,
    /// Where jobs go; the threads end when it is dropped.
    jobs: Mutex<mpsc::Sender<Job>>,
    /// Threads (and slots).
    threads: usize,
}

impl Pool {
    /// A pool of `threads` threads named `relief-bg`.
    pub fn new(threads: usize) -> Pool {
        let threads = threads.max(1);
        let (tx, rx) = mpsc::channel::<Job>();
        let rx = Arc::new(Mutex::new(rx));
        for i in 0..threads {
            let rx = rx.clone();
            let spawned = std::thread::Builder::new()
                .name(format!("relief-bg-{i}"))
                .spawn(move || {
                    lower_priority();
                    loop {
                        let job = rx.lock().unwrap_or_else(|e| e.into_inner()).recv();
                        match job {
                            Ok(job) => job(),
                            Err(_) => break,
                        }
                    }
                });
            if let Err(e) = spawned {
                tracing::error!("cannot start a background thread: {e}");
            }
        }
        Pool {
            slots: Semaphore::new(threads),
            jobs: Mutex::new(tx),
            threads,
        }
    }

    /// Threads in the pool.
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Slots free now.
    pub fn free(&self) -> usize {
        self.slots.available_permits()
    }

    /// Runs `work` on a pool thread once a slot is free, and returns what it returns. The
    /// caller waits for the slot without holding a thread; a panic in `work` is caught, logged,
    /// and answered with [`PoolError::Panicked`].
    pub async fn run<T: Send + 'static>(
        &self,
        work: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T, PoolError> {
        let _slot = self
            .slots
            .acquire()
            .await
            .map_err(|_| PoolError::Stopping)?;
        let (tx, rx) = oneshot::channel();
        let job: Job = Box::new(move || match catch_unwind(AssertUnwindSafe(work)) {
            Ok(v) => {
                let _ = tx.send(v);
            }
            Err(_) => tracing::error!("a background computation panicked"),
        });
        self.jobs
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .send(job)
            .map_err(|_| PoolError::Stopping)?;
        rx.await.map_err(|_| PoolError::Panicked)
    }

    /// Takes no more work: callers waiting for a slot get [`PoolError::Stopping`].
    pub fn close(&self) {
        self.slots.close();
    }
}

/// Lowers the calling thread's priority to [`NICE`]. Where the system refuses (or has no such
/// thing), the thread keeps its priority: the pool is still apart from the sessions' threads.
fn lower_priority() {
    use thread_priority::{ThreadPriority, ThreadPriorityValue, set_current_thread_priority};
    // The crate maps its 0..=99 scale onto nice 19..=-20 for the normal policy: 22 is nice 10
    // (a test reads the thread's nice value back).
    let set = ThreadPriorityValue::try_from(22u8)
        .map_err(|e| format!("{e:?}"))
        .and_then(|p| {
            set_current_thread_priority(ThreadPriority::Crossplatform(p))
                .map_err(|e| format!("{e:?}"))
        });
    if let Err(e) = set {
        tracing::debug!("background thread keeps its priority: {e}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn runs_work_and_survives_a_panic() {
        let pool = Pool::new(2);
        assert_eq!(pool.run(|| 6 * 7).await, Ok(42));
        let r: Result<(), _> = pool.run(|| panic!("on purpose")).await;
        assert_eq!(r, Err(PoolError::Panicked));
        // The slot and the thread came back.
        assert_eq!(pool.run(|| 1).await, Ok(1));
        assert_eq!(pool.free(), 2);
        pool.close();
        assert_eq!(pool.run(|| 1).await, Err(PoolError::Stopping));
    }

    #[cfg(target_os = "linux")]
    #[tokio::test]
    async fn its_threads_run_at_a_lower_priority() {
        let pool = Pool::new(1);
        // Field 19 of /proc/thread-self/stat is the nice value (after the command's parenthesis).
        let nice = pool
            .run(|| {
                let s = std::fs::read_to_string("/proc/thread-self/stat").unwrap();
                let rest = &s[s.rfind(')').unwrap() + 2..];
                rest.split(' ').nth(16).unwrap().parse::<i32>().unwrap()
            })
            .await
            .unwrap();
        assert_eq!(nice, NICE as i32);
    }
}
