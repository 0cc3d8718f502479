//! Decoding untrusted frames never allocates beyond the codec's limit (the codec's promise:
//! "decoding random bytes never panics and never allocates beyond the limit").
//!
//! A counting global allocator records the largest single allocation made by the decoding thread
//! while it decodes random and adversarial frames; it must stay within the frame limit.
#![allow(unsafe_code)] // Reason: a test-only global allocator that counts, then defers to `System`.

use proptest::prelude::*;
use relief_proto::codec::{HARD_LIMIT, decode};
use relief_proto::cut::Cut;
use relief_proto::delta::{Delta, Known, NoParents};
use relief_proto::msg::{ClientMsg, ServerMsg};
use relief_proto::tree::TreeShape;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static LARGEST: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Whether this thread's allocations are counted: only the thread that decodes, so that the
    /// harness's other threads (a proptest runner drawing its next input, a failing test
    /// formatting its backtrace) never land in the count. Const-initialised with no destructor,
    /// so reading it inside the allocator allocates nothing.
    static COUNTED: Cell<bool> = const { Cell::new(false) };
}

// SAFETY: every call is forwarded unchanged to the system allocator; we only record sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTED.with(Cell::get) {
            LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        }
        // SAFETY: same layout, same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System.alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// Tests in this file run one at a time, so that the counter sees one decoder alone. Counting
/// every thread made the checks flaky: a proptest runner of another test allocated 921 bytes
/// while a 1-byte body's decoder was being measured (limit 512), and one test's failure report
/// failed the others.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn largest_during(f: impl FnOnce()) -> usize {
    largest_after(|| (), |_| f())
}

/// The largest allocation of `f` given what `setup` made, the setup done under the same lock
/// (so that its allocations never land in another test's count) and not counted.
fn largest_after<S>(setup: impl FnOnce() -> S, f: impl FnOnce(&S)) -> usize {
    let _guard = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let s = setup();
    LARGEST.store(0, Ordering::Relaxed);
    COUNTED.with(|c| c.set(true));
    f(&s);
    COUNTED.with(|c| c.set(false));
    LARGEST.load(Ordering::Relaxed)
}

/// A 4097 x 4097 tree and its root cut: a client's state at its session's start.
fn client_at_start() -> (TreeShape, Cut) {
    let shape = TreeShape::new(4097, 4097).unwrap();
    let root = Cut::root(&shape);
    (shape, root)
}

/// The largest allocation decoding `bytes` as a vertex delta body against [`client_at_start`].
fn largest_decoding_body(bytes: &[u8]) -> usize {
    largest_after(client_at_start, |(shape, root)| {
        let known = Known {
            parents: &NoParents,
            cut: root,
        };
        let _ = Delta::unpack_body(shape, 0.1, 0, 0, bytes, known);
    })
}

proptest! {
    #[test]
    fn random_frames_stay_within_the_limit(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let limit = 4096;
        let peak = largest_during(|| {
            let _ = decode::<ServerMsg>(&bytes, limit);
            let _ = decode::<ClientMsg>(&bytes, limit);
        });
        prop_assert!(peak <= limit, "allocated {} bytes for a {}-byte frame", peak, bytes.len());
    }

    #[test]
    fn random_bodies_stay_within_their_size(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let peak = largest_decoding_body(&bytes);
        // At most one entry per bit of input, of a few dozen bytes each.
        prop_assert!(peak <= 64 * 8 * bytes.len().max(1), "allocated {} bytes", peak);
    }
}

#[test]
fn a_length_prefix_claiming_gigabytes_allocates_nothing_large() {
    // ServerMsg::Delta { pose_seq: 0, complete: true, delta: { seq: 1, digest: 2,
    // body: <len = 2^40> } }, then 3 bytes.
    let mut frame = vec![1u8, 0, 1, 1, 2, 0xFD];
    frame.extend_from_slice(&(1u64 << 40).to_le_bytes());
    frame.extend_from_slice(&[1, 2, 3]);
    let peak = largest_during(|| {
        assert!(decode::<ServerMsg>(&frame, HARD_LIMIT).is_err());
    });
    assert!(peak < 1 << 16, "allocated {peak} bytes");
}

/// 8 bytes of garbage that claim 77 merges and 154 splits: the splits' room was reserved for all
/// 154 (4,312 bytes), past one entry per bit of the body (found by the property test above).
#[test]
fn a_short_body_reserves_no_more_than_its_bits() {
    let bytes = [252u8, 119, 228, 0, 0, 0, 0, 0];
    let peak = largest_decoding_body(&bytes);
    assert!(peak <= 64 * 8 * bytes.len(), "allocated {peak} bytes");
}
