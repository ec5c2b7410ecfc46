//! Shared by the GPU tests: one device per test process, with the Khronos validation
//! layer on.
//!
//! Without any Vulkan device a GPU test prints "skipped: no Vulkan device" and
//! passes, unless ARBOR_REQUIRE_GPU=1 (CI), where it fails. With
//! ARBOR_REQUIRE_GPU=1 the validation layer is also required.
//!
//! The tests of a process share a few [`Context`]s (one per core, at most two), so
//! that a kernel compiled for one test is reused by later ones (the context's kernel
//! cache): on lavapipe the compile is most of a small render's time. A test holds
//! its context for as long as it holds the [`Gpu`] guard. Each test is judged by its own validation messages: those
//! left by an earlier test that failed are dropped when the guard is taken, and any
//! left when a passing test lets go fail that test. A test that expects validation
//! errors makes its own context.

#![allow(dead_code)]

use std::sync::{Mutex, MutexGuard, OnceLock};
use std::time::{Duration, Instant};

use arbor::gpu::{Context, ContextOptions, KernelCacheStats};

pub mod scenes;

/// Whether CI demands a device.
pub fn gpu_required() -> bool {
    std::env::var("ARBOR_REQUIRE_GPU").is_ok_and(|v| v == "1")
}

/// A validated context, or None (test skipped) when there is no device.
fn open() -> Option<Context> {
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

/// The process's context, held by one test at a time, and since when.
pub struct Gpu(MutexGuard<'static, Context>, Instant, Duration, KernelCacheStats);

impl std::ops::Deref for Gpu {
    type Target = Context;
    fn deref(&self) -> &Context {
        &self.0
    }
}

/// With ARBOR_TEST_TIMES=FILE, each test appends a line to FILE when it lets the
/// context go: its name, the milliseconds it waited for the context and held it, and
/// the pipelines it compiled and found compiled (docs/testing.md: finding the slow
/// tests).
fn log_time(waited: Duration, held: Duration, compiled: u64, reused: u64) {
    let Some(path) = std::env::var_os("ARBOR_TEST_TIMES") else { return };
    let name = std::thread::current().name().unwrap_or("?").to_string();
    let line =
        format!("{name}\t{:.0}\t{:.0}\t{compiled}\t{reused}\n", waited.as_secs_f64() * 1e3, held.as_secs_f64() * 1e3);
    if let Ok(mut f) = std::fs::OpenOptions::new().create(true).append(true).open(path) {
        use std::io::Write;
        let _ = f.write_all(line.as_bytes());
    }
}

impl Drop for Gpu {
    fn drop(&mut self) {
        let now = self.0.kernel_cache_stats();
        log_time(self.2, self.1.elapsed(), now.misses - self.3.misses, now.hits - self.3.hits);
        let left = self.0.take_validation_errors();
        if !left.is_empty() && !std::thread::panicking() {
            panic!("{} validation error(s) left by this test; the first: {}", left.len(), left[0]);
        }
    }
}

/// The process's contexts, opened by the first test that asks: one per core the
/// tests run on (at most [`MAX_CONTEXTS`]), so that one test's kernel compile (one
/// core on lavapipe) need not wait for another's. Empty without a device.
fn shared() -> &'static [Mutex<Context>] {
    static SHARED: OnceLock<Vec<Mutex<Context>>> = OnceLock::new();
    SHARED.get_or_init(|| {
        let n = std::thread::available_parallelism().map_or(1, |n| n.get()).clamp(1, MAX_CONTEXTS);
        let Some(first) = open() else { return Vec::new() };
        let mut all = vec![Mutex::new(first)];
        all.extend((1..n).filter_map(|_| open()).map(Mutex::new));
        all
    })
}

/// Contexts a test process opens at most.
const MAX_CONTEXTS: usize = 2;

/// Whether there is a device, for tests that run the `arbor` binary (which opens its
/// own): they need not wait for a shared context. False means skipped (a failure
/// under ARBOR_REQUIRE_GPU=1, as for [`gpu`]).
pub fn has_gpu() -> bool {
    !shared().is_empty()
}

/// A shared validated context, or None (test skipped) when there is no device.
pub fn gpu() -> Option<Gpu> {
    let all = shared();
    if all.is_empty() {
        return None;
    }
    let asked = Instant::now();
    // The first free context; a test that panicked while holding one poisons its
    // lock, but the context itself is still sound (every submission waits).
    let guard = loop {
        let free = all.iter().find_map(|m| match m.try_lock() {
            Ok(g) => Some(g),
            Err(std::sync::TryLockError::Poisoned(p)) => Some(p.into_inner()),
            Err(std::sync::TryLockError::WouldBlock) => None,
        });
        match free {
            Some(g) => break g,
            None => std::thread::sleep(Duration::from_millis(5)),
        }
    };
    let earlier = guard.take_validation_errors();
    if !earlier.is_empty() {
        eprintln!("note: dropped {} validation error(s) left by a failed test", earlier.len());
    }
    let stats = guard.kernel_cache_stats();
    Some(Gpu(guard, Instant::now(), asked.elapsed(), stats))
}

/// A context of the test's own (for tests that expect validation errors, or that
/// must see a fresh device), or None (test skipped) when there is no device.
pub fn private_gpu() -> Option<Context> {
    open()
}
