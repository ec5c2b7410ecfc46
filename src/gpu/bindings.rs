// Binding numbers and kernel tunables: the one source for Rust and GLSL.
// build.rs `include!`s this file and passes every entry of `SHADER_DEFINES` to
// shaderc as a macro, so no GLSL file contains a literal binding number.
// Keep this file free of `use` statements and attributes other than doc comments.

/// Descriptor set 0, binding of the per-render uniform block (`Params`).
pub const BINDING_PARAMS: u32 = 0;
/// Storage: interleaved vertices (`GpuVertex`: position + normal).
pub const BINDING_VERTICES: u32 = 1;
/// Storage: triangles as `uvec4(v0, v1, v2, material)`.
pub const BINDING_TRIANGLES: u32 = 2;
/// Storage: spheres (`GpuSphere`).
pub const BINDING_SPHERES: u32 = 3;
/// Storage: materials followed by lights, as vec4 rows (`GpuMaterial`, `GpuLight`).
pub const BINDING_SHADING: u32 = 4;
/// Storage: per-pixel output (`GpuPixel`: radiance, normal + depth, prim + cost).
pub const BINDING_PIXELS: u32 = 5;
/// Storage: acceleration-structure nodes (layout owned by each accel's `to_gpu`).
pub const BINDING_ACCEL_NODES: u32 = 6;
/// Storage: acceleration-structure primitive indices.
pub const BINDING_ACCEL_INDICES: u32 = 7;

/// Threads per workgroup of the trace kernel (1D).
pub const WORKGROUP_SIZE: u32 = 64;
/// Upper bound on path depth (camera ray + bounces) the kernel will ever follow.
pub const MAX_PATH_DEPTH: u32 = 16;
/// Unroll factors the brute-force kernel offers (shaders/accel/none.glsl: plain
/// loop, UNROLLED_8, UNROLLED), smallest first.
pub const BRUTE_UNROLL_FACTORS: [u32; 3] = [1, 8, 32];
/// Loop iterations one invocation may run in total on llvmpipe (its hard limit is
/// 65535; beyond it the invocation silently stops); the host keeps dispatches under it.
pub const LLVMPIPE_LOOP_BUDGET: u64 = 60_000;
/// Most storage buffers any pipeline may bind per shader stage.
pub const MAX_STORAGE_BUFFERS_PER_STAGE: u32 = 8;

/// Specialization constant ids.
pub const SPEC_SHADOWS: u32 = 0;
pub const SPEC_MAX_DEPTH: u32 = 1;
/// Traversal stack entries (tree depth + 1).
pub const SPEC_STACK_SIZE: u32 = 2;
/// Traversal steps (nodes + primitive tests) one trace may take before the pixel is
/// flagged as overflowed.
pub const SPEC_TREE_STEPS: u32 = 3;
/// Unroll factor of the brute-force loops (one of BRUTE_UNROLL_FACTORS).
pub const SPEC_BRUTE_UNROLL: u32 = 4;
/// Ray/triangle test: 0 watertight (Woop et al. 2013), 1 fast (Moller-Trumbore).
pub const SPEC_INTERSECT: u32 = 5;
/// Trace one cosine-distributed ray from each camera hit instead of shading.
pub const SPEC_DIFFUSE_PROBE: u32 = 6;
/// Bit of `GpuPixel::prim_cost[3]` set when a trace ran out of steps.
pub const OVERFLOW_FLAG: u32 = 0x8000_0000;

/// Every value above that shaders see, by macro name.
pub const SHADER_DEFINES: &[(&str, u32)] = &[
    ("BINDING_PARAMS", BINDING_PARAMS),
    ("BINDING_VERTICES", BINDING_VERTICES),
    ("BINDING_TRIANGLES", BINDING_TRIANGLES),
    ("BINDING_SPHERES", BINDING_SPHERES),
    ("BINDING_SHADING", BINDING_SHADING),
    ("BINDING_PIXELS", BINDING_PIXELS),
    ("BINDING_ACCEL_NODES", BINDING_ACCEL_NODES),
    ("BINDING_ACCEL_INDICES", BINDING_ACCEL_INDICES),
    ("WORKGROUP_SIZE", WORKGROUP_SIZE),
    ("MAX_PATH_DEPTH", MAX_PATH_DEPTH),
    ("SPEC_SHADOWS", SPEC_SHADOWS),
    ("SPEC_MAX_DEPTH", SPEC_MAX_DEPTH),
    ("SPEC_STACK_SIZE", SPEC_STACK_SIZE),
    ("SPEC_TREE_STEPS", SPEC_TREE_STEPS),
    ("SPEC_BRUTE_UNROLL", SPEC_BRUTE_UNROLL),
    ("SPEC_INTERSECT", SPEC_INTERSECT),
    ("SPEC_DIFFUSE_PROBE", SPEC_DIFFUSE_PROBE),
    ("OVERFLOW_FLAG", OVERFLOW_FLAG),
];
