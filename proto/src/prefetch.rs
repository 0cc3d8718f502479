//! Software prefetch: a hint that a cache line will be read soon, so that the loads of work
//! queued ahead overlap with the work at hand (a loaded server finds each session's state out
//! of the caches).
#![allow(unsafe_code)] // Reason: the x86-64 prefetch instruction is only reachable through an intrinsic that is `unsafe` to call.

/// Hints that the cache line holding `*r` will be read soon (into every level of the cache). A
/// no-op where the target has no stable prefetch intrinsic.
#[inline(always)]
pub fn prefetch<T>(r: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch never faults and changes no memory, whatever the address (here that
    // of a live reference), and SSE, which provides it, is part of every x86-64 target.
    unsafe {
        use core::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>((r as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = r;
}
