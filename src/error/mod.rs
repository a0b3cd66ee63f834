//! Errors returned on bad input: each names the field or file and the allowed range. The
//! bounds of what a user gives are declared here once ([`allowed`], the vector bounds
//! and sizes), for the API's checks and the scene file's readers alike.

pub mod allowed;
mod bounds;
mod cleave_error;

pub use bounds::*;
pub use cleave_error::*;
