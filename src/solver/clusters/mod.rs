//! Cluster shape matching, the solver's dense SIMD core: the term itself ([`term`]),
//! the rows and batches the kernel reads, the batched fit, the shared rest shape, the
//! colouring, the patch after a cut, the clusters' turn carried from substep to
//! substep, and their plasticity.

pub mod batches;
pub mod colouring;
pub mod creep;
pub mod fit;
pub mod patch;
pub mod plastic;
pub mod rows;
pub mod spin;
pub mod template;
pub mod term;
