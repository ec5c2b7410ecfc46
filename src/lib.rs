//! # arbor
//!
//! A headless Vulkan compute ray tracer for triangle meshes and analytic spheres,
//! built around spatial data structures. Data flows one way:
//!
//! ```text
//! scene file / mesh file / builtin
//!    -> scene::Scene          (flat triangles, spheres, materials, lights, camera; validated once)
//!    -> accel::<kind>::build  (CPU builder, sees only bounds + centroids)
//!    -> accel::<kind>::validate / stats
//!    -> gpu:: upload + dispatch trace.comp specialised for this scene
//!    -> render:: readback, accumulate, write PNG / EXR / PFM / stats JSON
//! ```
//!
//! Lint policy: `unsafe` is denied everywhere and allowed only in [`gpu`]; the other
//! modules forbid it outright. (The binary's `main.rs` has one more block, setting an
//! allocator option: docs/build-notes.md, "Host memory".)

#![deny(unsafe_code)]
#![warn(missing_debug_implementations)]

pub mod accel;
pub mod bench;
pub mod error;
#[allow(unsafe_code)]
pub mod gpu;
pub mod info;
pub mod math;
pub mod render;
pub mod scene;
pub mod timeline;

pub use error::{Error, Result};
