//! Geometry shared by the CPU reference and mirrored in GLSL (`shaders/common/`).
//! Functions with a GLSL twin carry the same name and the same operation order.

#![forbid(unsafe_code)]

pub mod aabb;
pub mod float;
pub mod intersect;

pub use aabb::Aabb;
pub use intersect::{Hit, Ray};
