//! From a scene and a structure to pixels: GPU rendering in short dispatches, the
//! CPU reference, and the output writers.

#![forbid(unsafe_code)]

pub mod cpu;
pub mod cracks;
pub mod gpu;
pub mod output;

use serde::Serialize;

use crate::accel::AccelKind;

/// Which kernel variant to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum KernelChoice {
    /// Only what the scene needs: no sphere code or buffer without spheres, no mesh
    /// code or buffers without triangles, no light loop without lights.
    #[default]
    Specialized,
    /// The general kernel with every buffer bound (empty ones where the scene has
    /// nothing); used by tests to show the specialised kernels agree with it.
    General,
}

/// How to render.
#[derive(Debug, Clone)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel; sample 0 goes through the pixel centre.
    pub spp: u32,
    pub seed: u32,
    pub accel: AccelKind,
    /// Builder parameters (kd-tree, grid, octree).
    pub params: crate::accel::AccelParams,
    pub kernel: KernelChoice,
    /// Trace camera rays only (no shadows, no bounces): the benchmark's primary-ray mode.
    pub primary_only: bool,
    /// Camera rays plus one cosine-distributed ray from each hit, no shading: the
    /// benchmark's incoherent-ray mode (the image is ambient occlusion). Takes
    /// precedence over `primary_only`.
    pub diffuse_probe: bool,
    /// Budget of primitive tests per dispatch; smaller means shorter dispatches.
    pub dispatch_budget: u64,
}

impl RenderSettings {
    /// Default settings for an image of the scene's own size.
    pub fn for_size(width: u32, height: u32) -> Self {
        RenderSettings {
            width,
            height,
            spp: 1,
            seed: 0,
            accel: AccelKind::None,
            params: Default::default(),
            kernel: KernelChoice::Specialized,
            primary_only: false,
            diffuse_probe: false,
            dispatch_budget: DEFAULT_DISPATCH_BUDGET,
        }
    }
}

/// Primitive tests per dispatch: on lavapipe (2 cores) this keeps a dispatch near a
/// quarter of a second; see README "Dispatch splitting".
pub const DEFAULT_DISPATCH_BUDGET: u64 = 60_000_000;

/// A rendered frame: linear radiance (averaged over samples) and the AOVs of the
/// pixel-centre camera ray. Row-major, row 0 at the top.
#[derive(Debug, Clone, Default)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub radiance: Vec<[f32; 3]>,
    /// t of the nearest hit, +inf on a miss.
    pub depth: Vec<f32>,
    /// Shading normal at the hit, zero on a miss.
    pub normal: Vec<[f32; 3]>,
    /// Primitive index, `u32::MAX` on a miss.
    pub prim: Vec<u32>,
    /// Boxes / nodes visited by the camera ray.
    pub nodes: Vec<u32>,
    /// Primitives tested by the camera ray.
    pub tests: Vec<u32>,
    /// Rays traced per pixel over all samples (camera, shadow, bounce).
    pub rays: Vec<u32>,
}

/// The figures `--stats` writes.
#[derive(Debug, Clone, Default, Serialize)]
pub struct RenderStats {
    pub device: String,
    pub scene: String,
    pub triangles: usize,
    pub spheres: usize,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub accel: String,
    /// Structure statistics (nodes, leaves, depth, references, SAH cost, bytes).
    pub build: crate::accel::BuildStats,
    pub kernel: String,
    /// Storage and uniform buffers the kernel bound, by name.
    pub bindings: Vec<String>,
    pub build_ms: f64,
    /// Sum of GPU time of the trace dispatches (timestamps); null without timestamps.
    pub trace_ms: Option<f64>,
    /// Host wall time of the whole trace, uploads and readback included.
    pub wall_ms: f64,
    pub dispatches: u32,
    /// Every ray traced: camera, shadow and bounce rays.
    pub rays: u64,
    pub mrays_per_s: Option<f64>,
    pub accel_bytes: u64,
    /// Mean primitives tested by the pixel-centre camera ray.
    pub mean_prims_tested: f64,
    /// Mean nodes (or boxes) visited by the pixel-centre camera ray.
    pub mean_nodes_visited: f64,
}
