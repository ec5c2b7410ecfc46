//! The integration tests, as one crate: a module per area, so that a change to
//! `src/` relinks one test binary, and the tests of a process share one device and
//! its compiled kernels (`common::gpu`).
//!
//! Run one area with `cargo test --test it AREA::` (for example
//! `cargo test --test it resume::`); docs/testing.md says which area covers which
//! part of the code.

mod common;

mod alpha;
mod bad_files;
mod bad_input;
mod bad_outputs;
mod bench_cli;
mod bvh;
mod cli;
mod compare;
mod degenerate;
mod dispatch_loop;
mod fuzz;
mod gltf;
mod gpu_bench_script;
mod gpu_build;
mod gpu_layout;
mod gpu_render;
mod grid_octree;
mod heatmaps;
mod instances;
mod kdtree;
mod kubernetes;
mod manual;
mod mesh_files;
mod microfacet;
mod path;
mod photon;
mod ray_batch;
mod raycast;
mod rayquery;
mod resume;
mod robustness;
mod sampling;
mod scene_inputs;
mod shards;
mod slurm;
mod sppm;
mod surface;
mod timeline;
mod trace_rays_example;
mod transforms;
mod vertex_colors;
mod whitted;
