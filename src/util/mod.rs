//! Small helpers with no domain of their own: enums spelled by name in files, memory
//! prefetch hints, sampling keyframes.

pub mod keyframes;
pub(crate) mod named_enum;
pub mod prefetch;
