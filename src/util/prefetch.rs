//! A hint to start loading memory that a loop will read a few iterations later, so
//! that its cache misses overlap instead of waiting one after another. Cut events walk
//! tens of thousands of scattered per-particle entries; on this kind of data the hint
//! hides most of the memory latency. A no-op on targets without a prefetch instruction.

/// Hints that `value` will be read soon. Never faults, whatever the address.
#[inline(always)]
pub fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch has no architectural effect (it never faults, even on an
    // invalid address); the pointer comes from a reference anyway.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>((value as *const T).cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}
