//! Colour sweeps: the clusters (or edges) of one colour share no particle, so their tasks
//! may write their particles' entries in parallel. [`Disjoint`] carries those writes, and
//! those of any pass whose tasks each own distinct entries (the contact particles, each
//! applying its own sum of its pairs' moves).

/// A per-particle or per-cluster array written by the tasks of one colour.
///
/// Soundness rests on the colouring: the clusters of one colour have pairwise disjoint
/// member sets, and a task writes only the entries of its own clusters and of their
/// members, so no entry is written by two tasks, nor read by one task while another
/// writes it. No reference to the array is alive while a colour runs. (Likewise for a
/// pass whose tasks own distinct entries.)
#[derive(Clone, Copy)]
pub(in crate::solver) struct Disjoint<T>(*mut T);

// SAFETY: see the type's docs; tasks of one colour touch pairwise disjoint entries.
unsafe impl<T> Send for Disjoint<T> {}
// SAFETY: as above.
unsafe impl<T> Sync for Disjoint<T> {}

impl<T: Copy> Disjoint<T> {
    pub(in crate::solver) fn new(v: &mut [T]) -> Self {
        Self(v.as_mut_ptr())
    }

    /// The array's first entry.
    pub(in crate::solver) fn as_ptr(self) -> *const T {
        self.0
    }

    /// Reads entry `i`.
    ///
    /// # Safety
    /// `i` is in bounds and no other task writes entry `i` during this colour.
    #[inline(always)]
    pub(in crate::solver) unsafe fn read(self, i: usize) -> T {
        // SAFETY: guaranteed by the caller.
        unsafe { self.0.add(i).read() }
    }

    /// Reads the entry at byte offset `at` (its index × its size).
    ///
    /// # Safety
    /// As [`Disjoint::read`] for the entry's index.
    #[inline(always)]
    pub(in crate::solver) unsafe fn read_at(self, at: u32) -> T {
        // SAFETY: guaranteed by the caller.
        unsafe { self.0.byte_add(at as usize).read() }
    }

    /// Writes the entry at byte offset `at` (its index × its size).
    ///
    /// # Safety
    /// As [`Disjoint::write`] for the entry's index.
    #[inline(always)]
    pub(in crate::solver) unsafe fn write_at(self, at: u32, value: T) {
        // SAFETY: guaranteed by the caller.
        unsafe { self.0.byte_add(at as usize).write(value) }
    }

    /// Writes entry `i`.
    ///
    /// # Safety
    /// `i` is in bounds and belongs to the calling task during this colour.
    #[inline(always)]
    pub(in crate::solver) unsafe fn write(self, i: usize, value: T) {
        // SAFETY: guaranteed by the caller.
        unsafe { self.0.add(i).write(value) }
    }
}
