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
//! ## As a library
//!
//! The jobs people embed arbor for (docs/library.md): load or build a scene, build
//! any structure and read its statistics, trace a batch of rays on the device and on
//! the CPU reference. The names below are re-exported at the crate root.
//!
//! ```no_run
//! use arbor::{Accel, AccelKind, Context, ContextOptions, Ray, RayTracer, Scene, TraceOptions};
//! use arbor::glam::Vec3; // arbor's glam, re-exported: no version of your own to match
//!
//! # fn main() -> arbor::Result<()> {
//! let scene = Scene::load("builtin:cornell")?; // a mesh file, a scene TOML or builtin:NAME
//! let accel = Accel::build(AccelKind::BvhSah, &scene);
//! let stats = accel.stats(&scene); // nodes, leaves, depth, SAH cost, bytes, build ms
//! println!("{} nodes, SAH cost {:.1}", stats.nodes, stats.sah_cost);
//!
//! let rays = vec![Ray { origin: Vec3::new(0.0, 1.0, 3.0), dir: Vec3::NEG_Z, tmin: 0.0, tmax: f32::INFINITY }];
//! let ctx = Context::new(&ContextOptions::default())?; // the first Vulkan device
//! let tracer = RayTracer::new(&ctx, &scene, &accel, &TraceOptions::default())?;
//! let hits = tracer.trace(&rays)?; // Vec<Option<Hit>>: None is a miss
//! let reference = accel.trace_cpu(&scene, &rays);
//! if let (Some(g), Some(c)) = (hits[0], reference[0]) {
//!     assert_eq!(g.prim, c.prim);
//!     println!("t {} prim {} barycentrics ({}, {})", g.t, g.prim, g.u, g.v);
//! }
//! # Ok(())
//! # }
//! ```
//!
//! Every fallible call returns [`Error`]; the library prints nothing and never exits
//! the process.
//!
//! Lint policy: `unsafe` is denied everywhere and allowed only in [`gpu`]; the other
//! modules forbid it outright. (The binary's `main.rs` has one more block, setting an
//! allocator option: docs/build-notes.md, "Host memory".)

#![deny(unsafe_code)]
#![warn(missing_debug_implementations)]
#![warn(missing_docs)]

pub mod accel;
// The `arbor bench` and `arbor info` commands' library half: for the binary only.
#[doc(hidden)]
#[allow(missing_docs)]
pub mod bench;
pub mod error;
#[allow(unsafe_code)]
pub mod gpu;
#[doc(hidden)]
#[allow(missing_docs)]
pub mod info;
pub mod math;
pub mod photon;
pub mod raycast;
// The renderer's parts, public for the binary, the tests and the benchmarks (their
// settings are documented in the CLI help and docs/); `render::integrators::rays`, the ray-batch
// API, is documented in full and re-exported at the crate root.
#[allow(missing_docs)]
pub mod render;
pub mod scene;
pub mod timeline;

/// The vector library of arbor's public types (`Ray`, `Hit`, `Scene`), re-exported so
/// that a caller uses the same version without naming it in its own Cargo.toml.
pub use glam;

pub use accel::{Accel, AccelKind, AccelParams, BuildStats};
pub use error::{Error, Result};
pub use gpu::{Context, ContextOptions};
pub use math::{Hit, Ray};
pub use render::integrators::rays::{trace_rays, BatchStats, RayTracer, TraceOptions};
pub use scene::Scene;
