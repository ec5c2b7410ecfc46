//! What a sample does: each integrator sets its kernel's constants, parameters and
//! extra data, and hands them to the render loop ([`super::dispatch`]).

pub mod envdist;
pub mod path;
#[warn(missing_docs)]
pub mod rays;
pub mod sppm;
pub mod whitted;
