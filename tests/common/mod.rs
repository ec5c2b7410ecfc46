//! Shared by the GPU tests: a device with the Khronos validation layer on.
//!
//! Without any Vulkan device a GPU test prints "skipped: no Vulkan device" and
//! passes, unless ARBOR_REQUIRE_GPU=1 (CI), where it fails. With
//! ARBOR_REQUIRE_GPU=1 the validation layer is also required.

#![allow(dead_code)]

use arbor::gpu::{Context, ContextOptions};

pub mod scenes;

/// Whether CI demands a device.
pub fn gpu_required() -> bool {
    std::env::var("ARBOR_REQUIRE_GPU").is_ok_and(|v| v == "1")
}

/// A validated context, or None (test skipped) when there is no device.
pub fn gpu() -> Option<Context> {
    let with_validation = Context::new(&ContextOptions { validation: true, ..Default::default() });
    match with_validation {
        Ok(c) => Some(c),
        Err(e) if gpu_required() => panic!("ARBOR_REQUIRE_GPU=1 but no validated Vulkan device: {e}"),
        Err(e) => {
            // Fall back to a device without validation when only the layer is missing.
            match Context::new(&ContextOptions::default()) {
                Ok(c) => {
                    eprintln!("warning: validation layer unavailable ({e}); running without it");
                    Some(c)
                }
                Err(e) => {
                    eprintln!("skipped: no Vulkan device ({e})");
                    None
                }
            }
        }
    }
}
