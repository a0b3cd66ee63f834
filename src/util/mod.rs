//! Small helpers with no domain of their own: enums spelled by name in files, memory
//! prefetch hints, sampling keyframes, disjoint sets,
//! values grouped by key, the set bits of a bit array, a radix sort, room in lists that
//! are edited where they lie.

pub mod bits;
pub mod grouping;
pub mod keyframes;
pub(crate) mod named_enum;
pub mod prefetch;
pub mod radix;
pub mod room;
pub mod union_find;
