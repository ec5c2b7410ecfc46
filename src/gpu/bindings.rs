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
/// The driver's top-level acceleration structure (`--accel rayquery`), traced with
/// VK_KHR_ray_query; not a buffer.
pub const BINDING_TLAS: u32 = 8;
/// Storage: the resume pool of a resumable family's kernels (shaders/common/resume.glsl):
/// two job lists, then two halves of trace records. A 16-byte stand-in for the trace
/// kernel, the pool itself for the resume kernel (src/render/resume.rs).
pub const BINDING_RESUME: u32 = 9;
/// Texel (RGBA32UI): the rays of a ray batch (`GpuRay`, two texels each), read by the
/// `rays_<family>_<geometry>` kernels only (src/render/rays.rs).
pub const BINDING_RAYS: u32 = 10;

/// GPU BVH build (src/accel/bvh/gpu_build.rs, shaders/build_*.comp): a header of
/// counters and the centroid box (`BUILD_HDR_*` words).
pub const BINDING_BUILD_HEADER: u32 = 0;
/// Build: per-primitive boxes, two vec4 (min, max) each.
pub const BINDING_BUILD_PRIM_BOUNDS: u32 = 4;
/// Build: (Morton code, primitive) pairs being sorted.
pub const BINDING_BUILD_PAIRS: u32 = 5;
/// Build: the other half of the radix sort's ping-pong.
pub const BINDING_BUILD_PAIRS_OUT: u32 = 6;
/// Build: radix-sort digit counts per block, then their exclusive prefix sums.
pub const BINDING_BUILD_HIST: u32 = 7;
/// Build: canonical binary nodes, two uvec4 each (min + left, max + right).
pub const BINDING_BUILD_NODES: u32 = 8;
/// Build: per-node uvec4 (parent, primitive count, cost or emit info, visit counter).
pub const BINDING_BUILD_AUX: u32 = 9;
/// Build: output nodes in the traversal layout (`GpuBvhNode`).
pub const BINDING_BUILD_OUT_NODES: u32 = 10;
/// Build: output primitive indices.
pub const BINDING_BUILD_OUT_INDICES: u32 = 11;
/// Build: the schedule of the passes by height (per-height counts, offsets and dispatch
/// arguments, the nodes listed by height, node heights; see build/common.glsl).
pub const BINDING_BUILD_LEVELS: u32 = 12;
/// Build, wide collapse: one word per binary output node (its wide depth, then its
/// wide node or none), then per-block counts of the wide nodes and their prefix sums.
pub const BINDING_BUILD_WIDE: u32 = 13;
/// Build, wide collapse: the wide nodes in the `bvh4` / `bvh8` layout.
pub const BINDING_BUILD_WIDE_NODES: u32 = 14;
/// The binary BVH's child references, as the CPU and GPU builders write them and the
/// trace kernels read them (`accel::bvh::{LEAF_REF, EMPTY_REF}`): a leaf is
/// `BVH_LEAF_REF | first << BVH_LEAF_COUNT_BITS | count - 1` (at most `BVH_MAX_LEAF`
/// primitives), a missing child `BVH_EMPTY_REF`. Bits 0..3 (`BVH_LEAF_COUNT_MASK`) hold
/// count - 1, bits 3..31 the first entry of the primitive-index array, bit 31 the flag;
/// a leaf of 3 primitives at entry 40: 0x8000_0000 | 40 << 3 | 2 = 0x8000_0142.
pub const BVH_LEAF_REF: u32 = 0x8000_0000;
pub const BVH_EMPTY_REF: u32 = 0xffff_ffff;
pub const BVH_MAX_LEAF: u32 = 8;
pub const BVH_LEAF_COUNT_BITS: u32 = 3;
pub const BVH_LEAF_COUNT_MASK: u32 = (1 << BVH_LEAF_COUNT_BITS) - 1;
const _: () = assert!(1 << BVH_LEAF_COUNT_BITS == BVH_MAX_LEAF);
/// Flag of a canonical binary node's left word marking a leaf (`accel::bvh::LEAF_FLAG`;
/// the GPU builders' `LEAF_FLAG`).
pub const BUILD_LEAF_FLAG: u32 = 0x8000_0000;
/// Planes of a `bvh4` / `bvh8` node (lo x, y, z, hi x, y, z, child reference), each
/// one word per child: `WIDE_NODE_PLANES * width / 4` texels a node (`WideBvh::TEXELS`,
/// written by build_wide.comp, read by the trace kernels).
pub const WIDE_NODE_PLANES: u32 = 7;
/// Header words: centroid box min xyz and max xyz as order-preserving uints.
pub const BUILD_HDR_CMIN: u32 = 0;
pub const BUILD_HDR_CMAX: u32 = 3;
/// Header word: deepest output inner node (root = 1).
pub const BUILD_HDR_DEPTH: u32 = 6;
/// Header word: error bits (BUILD_ERR_*).
pub const BUILD_HDR_ERRORS: u32 = 7;
/// Header word: output inner nodes.
pub const BUILD_HDR_NODES: u32 = 8;
/// Header word: nodes of the wide collapse (`build_wide.comp`).
pub const BUILD_HDR_WIDE_NODES: u32 = 9;
/// Header word: deepest wide node (root = 1).
pub const BUILD_HDR_WIDE_DEPTH: u32 = 10;
/// Header words in all.
pub const BUILD_HDR_WORDS: u32 = 16;
/// Error bit: a climb from a leaf (`build_fit.comp`) exceeded BUILD_MAX_WALK steps.
pub const BUILD_ERR_WALK: u32 = 1;
/// Error bit: an inner node is BUILD_MAX_LEVELS or more levels above its deepest leaf.
pub const BUILD_ERR_LEVELS: u32 = 2;
/// Node heights the passes by height schedule (one indirect dispatch each): every
/// height of a tree the traversal kernel accepts (`MAX_BVH_DEPTH` inner nodes on a path).
pub const BUILD_MAX_LEVELS: u32 = 129;
/// Words of the schedule of the passes by height (binding BINDING_BUILD_LEVELS): per
/// height (BUILD_MAX_LEVELS slots plus a spare), counts at BUILD_LV_COUNT, list offsets
/// at BUILD_LV_OFFSET, placed counts at BUILD_LV_CURSOR, indirect dispatch arguments
/// (three words) at BUILD_LV_ARGS; then the node list at BUILD_LV_LIST (n words) and
/// the node heights (2n words). Described in shaders/build/common.glsl.
pub const BUILD_LV_SLOTS: u32 = BUILD_MAX_LEVELS + 1;
pub const BUILD_LV_COUNT: u32 = 0;
pub const BUILD_LV_OFFSET: u32 = BUILD_LV_SLOTS;
pub const BUILD_LV_CURSOR: u32 = 2 * BUILD_LV_SLOTS;
pub const BUILD_LV_ARGS: u32 = 3 * BUILD_LV_SLOTS;
pub const BUILD_LV_LIST: u32 = 6 * BUILD_LV_SLOTS;
/// Longest walk between a node and the root the build kernels take.
pub const BUILD_MAX_WALK: u32 = 1024;
/// Threads per workgroup of the build kernels other than treelet restructuring.
pub const BUILD_GROUP: u32 = 256;
/// Elements per thread of the radix sort (tile = BUILD_GROUP x this).
pub const BUILD_SORT_ITEMS: u32 = 16;
/// Primitives per thread of the bounds pass (`build_bounds.comp`): fewer workgroups,
/// so fewer barriers and atomics.
pub const BUILD_BOUNDS_ITEMS: u32 = 16;
/// Most threads per workgroup of the sort's scatter (its shared bit masks hold one bit
/// per thread; SPEC_SCATTER_GROUP is clamped to this).
pub const BUILD_SCATTER_MAX_GROUP: u32 = 64;
/// Threads per workgroup of the passes by height (restructure, collapse, emit), one
/// node each.
pub const BUILD_LEVEL_GROUP: u32 = 64;
/// Modes (push constant `a`) of `build_levels.comp`: count the listed nodes per
/// height, scan the counts, scatter the nodes into the list.
pub const BUILD_LEVELS_COUNT: u32 = 0;
pub const BUILD_LEVELS_SCAN: u32 = 1;
pub const BUILD_LEVELS_SCATTER: u32 = 2;
/// Mode of `build_finalize.comp`: subtrees cheaper as one leaf become leaves (trbvh;
/// 0 only counts output nodes).
pub const BUILD_FINALIZE_COLLAPSE: u32 = 1;
/// Modes of `build_emit.comp`: seed the root, then one height from the top.
pub const BUILD_EMIT_ROOT: u32 = 0;
pub const BUILD_EMIT_TOP: u32 = 1;
/// build_emit.comp push b: the tree had no finalize pass (the LBVH: nothing collapsed).
pub const BUILD_EMIT_UNFINALIZED: u32 = 1;
/// Modes of `build_wide.comp`: seed the root, mark wide nodes (one height from the
/// top), count them per block, scan the counts, number them, write them.
pub const BUILD_WIDE_SEED: u32 = 0;
pub const BUILD_WIDE_MARK: u32 = 1;
pub const BUILD_WIDE_COUNT: u32 = 2;
pub const BUILD_WIDE_SCAN: u32 = 3;
pub const BUILD_WIDE_NUMBER: u32 = 4;
pub const BUILD_WIDE_WRITE: u32 = 5;
/// Output nodes per thread of the wide collapse's count and number passes (a block is
/// BUILD_GROUP x this).
pub const BUILD_WIDE_ITEMS: u32 = 16;

/// Threads per workgroup of the trace kernel (1D).
pub const WORKGROUP_SIZE: u32 = 64;
/// Upper bound on path depth (camera ray + bounces) the kernel will ever follow.
pub const MAX_PATH_DEPTH: u32 = 16;
/// Unroll factors the brute-force kernel offers (shaders/accel/none.glsl: plain
/// loop, UNROLLED_8, UNROLLED), smallest first. Each is its own kernel, compiled by
/// build.rs with `BRUTE_UNROLL` defined (`trace_none_tris`, `trace_none_tris_x8`, ...):
/// as one module specialised at run time, the unrolled loops the render does not use
/// made every brute-force pipeline compile about 15 times longer on lavapipe.
pub const BRUTE_UNROLL_FACTORS: [u32; 3] = [1, 8, 32];
/// Loop iterations one invocation may run in total on llvmpipe (its hard limit is
/// 65535; beyond it the invocation silently stops); the host keeps dispatches under it.
pub const LLVMPIPE_LOOP_BUDGET: u64 = 60_000;
/// Most storage buffers any pipeline may bind per shader stage.
pub const MAX_STORAGE_BUFFERS_PER_STAGE: u32 = 8;

/// Specialization constant ids.
/// Lights the trace kernel shades with (0: no shadow rays). A constant, not the
/// uniform `light_count`: a loop bounded by a uniform makes lavapipe compile the kernel
/// again at every dispatch (docs/kernels.md, "Per-dispatch values live in storage").
pub const SPEC_LIGHTS: u32 = 0;
pub const SPEC_MAX_DEPTH: u32 = 1;
/// Traversal stack entries (tree depth + 1).
pub const SPEC_STACK_SIZE: u32 = 2;
// 3 was SPEC_TREE_STEPS, now in the dispatch header (`GpuDispatch::trace_steps`).
// 4 was SPEC_BRUTE_UNROLL, now a define per kernel (BRUTE_UNROLL_FACTORS).
/// Ray/triangle test: 0 watertight (Woop et al. 2013), 1 fast (Moller-Trumbore).
pub const SPEC_INTERSECT: u32 = 5;
/// Trace one cosine-distributed ray from each camera hit instead of shading.
pub const SPEC_DIFFUSE_PROBE: u32 = 6;
/// Threads per workgroup of the bottom-up fit (`build_fit.comp`): one subgroup, so its
/// barriers stay cheap (on lavapipe 8 threads took half the time of 256 at 1M).
pub const SPEC_FIT_GROUP: u32 = 7;
/// Threads per workgroup of the radix sort's scatter (`build_sort_scatter.comp`): one
/// subgroup, at most BUILD_SCATTER_MAX_GROUP.
pub const SPEC_SCATTER_GROUP: u32 = 8;
/// Triangles and spheres of the scene, the bounds of the brute-force loops (constants
/// for the reason given at SPEC_LIGHTS).
pub const SPEC_TRIANGLE_COUNT: u32 = 9;
pub const SPEC_SPHERE_COUNT: u32 = 10;
/// Children per node of the wide collapse (`build_wide.comp`): 4 or 8.
pub const SPEC_WIDE_WIDTH: u32 = 20;
/// Integrator of the trace kernel: 0 Whitted, 1 path tracing, 2 the benchmark's probe
/// (camera rays and, with `SPEC_DIFFUSE_PROBE`, one bounce; no shading).
pub const SPEC_INTEGRATOR: u32 = 11;
/// Values of SPEC_INTEGRATOR: the trace kernel's entry points. Each is compiled into a
/// module of its own (`trace_<family>_<geometry>.<entry>`, TRACE_ENTRY in
/// shaders/trace.comp), so a driver compiles only the integrator it runs: on lavapipe
/// that halves a trace pipeline's creation. Ray batches run as the probe.
pub const INTEGRATOR_WHITTED: u32 = 0;
pub const INTEGRATOR_PATH: u32 = 1;
pub const INTEGRATOR_PROBE: u32 = 2;
/// Stochastic progressive photon mapping (common/sppm.glsl): its camera, photon and
/// update passes (`SPPM_PASS_*`, the constant `SPEC_SPPM_PASS`) in one module.
pub const INTEGRATOR_SPPM: u32 = 3;
/// The entry points' module suffixes, by SPEC_INTEGRATOR value.
pub const TRACE_ENTRIES: [(&str, u32); 4] = [
    ("whitted", INTEGRATOR_WHITTED),
    ("path", INTEGRATOR_PATH),
    ("probe", INTEGRATOR_PROBE),
    ("sppm", INTEGRATOR_SPPM),
];
/// Path integrator: emissive primitives in the emitter table (0: no area-light code).
pub const SPEC_EMITTERS: u32 = 12;
/// Path integrator: environment map width and height in texels (width 0: no map).
pub const SPEC_ENV_WIDTH: u32 = 13;
pub const SPEC_ENV_HEIGHT: u32 = 14;
/// Path integrator: whether any material has a texture.
pub const SPEC_TEXTURES: u32 = 15;
/// The scene's cut-outs and blended panes (glTF's alphaMode MASK or BLEND), as
/// `ALPHA_*` bits: with any, the primitive test of every traversal asks
/// common/alpha.glsl whether the ray meets the surface where it hits it; other scenes
/// compile the test out, and the texture read and the blend hash are compiled only
/// where used (llvmpipe runs both sides of a branch).
pub const SPEC_ALPHA: u32 = 25;
/// `SPEC_ALPHA` bits: some material has alpha; some reads a texture's alpha; some is
/// a blended pane.
pub const ALPHA_ON: u32 = 1;
pub const ALPHA_TEXTURES: u32 = 2;
pub const ALPHA_BLEND: u32 = 4;
/// Whether the scene has vertex colours (glTF's COLOR_0, PLY's red/green/blue): the
/// kernels then multiply a triangle hit's base colour, and its alpha where a material
/// has alpha, by the colour interpolated from the section at
/// `GpuParams::vertex_color_table` (common/colors.glsl).
pub const SPEC_VERTEX_COLORS: u32 = 26;
/// Path integrator: 0 multiple importance sampling, 1 light sampling only, 2 BSDF
/// sampling only (the last two for tests and the benchmark).
pub const SPEC_MIS: u32 = 16;
/// Path integrator: the depth from which Russian roulette may end a path.
pub const SPEC_RR_DEPTH: u32 = 17;
/// The material kinds the scene has, a bit per `MaterialKind` (1 << kind): the shading
/// code of absent kinds compiles away.
pub const SPEC_MATERIAL_KINDS: u32 = 18;
/// Packet traversal (a subgroup walks one node sequence) for coherent rays: camera
/// rays of the probe kernel and shadow rays toward point and directional lights. BVHs.
pub const SPEC_PACKET: u32 = 19;
/// Whitted: a glass hit within this many splits of the camera ray follows both the
/// reflected and the refracted ray (the refracted one waits on a branch stack); past
/// it, the stronger of the two by weight. 0 without glass. At most WHITTED_SPLIT_MAX.
pub const SPEC_WHITTED_SPLIT: u32 = 21;
/// The deepest glass split Whitted's kernel has room for, and its default.
pub const WHITTED_SPLIT_MAX: u32 = 3;
/// Resumed traces: 1 in the resume kernel (its restore, replay and save code), 0 in
/// the trace kernel, which only stops a sample whose trace ran out of steps.
pub const SPEC_RESUME_PASS: u32 = 40;
/// Resume kernel: trace results a record logs (the traces one sample may run), trace
/// records per half of the pool, jobs per list.
pub const SPEC_RESUME_LOG: u32 = 41;
pub const SPEC_RESUME_RECORDS: u32 = 42;
pub const SPEC_RESUME_JOBS: u32 = 43;
/// Material kind codes (the kind word `MAT_W_KIND`, below MAT_MAP_SHIFT; the emission
/// texture's index + 1 is above it; `scene::MaterialKind` takes its values from these).
pub const MAT_LAMBERT: u32 = 0;
pub const MAT_PHONG: u32 = 1;
pub const MAT_MIRROR: u32 = 2;
pub const MAT_GLASS: u32 = 3;
pub const MAT_EMISSIVE: u32 = 4;
pub const MAT_CONDUCTOR: u32 = 5;
pub const MAT_DIELECTRIC: u32 = 6;
/// glTF 2.0's metallic-roughness material (docs/materials.md; its record's words are
/// in the table at `MAT_W_COLOR_RGB`).
pub const MAT_PBR: u32 = 7;
/// Bit of a material's flags word (`MAT_W_FLAGS`): emits on both sides.
pub const MAT_FLAG_TWO_SIDED: u32 = 1;
/// Bit of a material's flags word: a conductor's Fresnel is Schlick's from its colour
/// (the reflectance at normal incidence), not from its complex index (eta, k).
pub const MAT_FLAG_SCHLICK: u32 = 2;
/// Shift of the texture index + 1 (0: no texture) in a material's flags word.
pub const MAT_TEXTURE_SHIFT: u32 = 8;
/// A texture's wrap along u and v (glTF's sampler: 0 repeat, 1 clamp to edge, 2
/// mirrored repeat), in its table row's width word (y) from these bits up; the width
/// is below TEXTURE_WRAP_U_SHIFT.
pub const TEXTURE_WRAP_U_SHIFT: u32 = 24;
pub const TEXTURE_WRAP_V_SHIFT: u32 = 26;
/// Shift of the normal texture index + 1 in a metallic-roughness material's map word
/// (`MAT_W_MAPS`), the metallic-roughness texture's index + 1 below it; and of the
/// emission texture index + 1 in any material's kind word (`MAT_W_KIND`), the kind below.
pub const MAT_MAP_SHIFT: u32 = 16;
/// Shading rows (16-byte texels) of one material record, and of one light record (the
/// lights follow every material).
pub const MATERIAL_ROWS: u32 = 4;
pub const LIGHT_ROWS: u32 = 2;
/// The words of a material record, `row * 4 + lane` (`material_record` in
/// src/render/dispatch/upload.rs writes them into a `GpuMaterial`, `material_at` in
/// shaders/common/bsdf.glsl reads them). A `_RGB` word opens three (a row's lanes 0..2). Which kind uses which:
///
/// | word | every kind        | plain (Lambert, Phong, mirror, glass, emissive) | conductor  | dielectric  | metallic-roughness (PBR) |
/// |------|-------------------|--------------------|------------|-------------|--------------------------|
/// | 0..3 | colour            |                    |            |             |                          |
/// | 3    | kind word         |                    |            |             |                          |
/// | 4..7 |                   | specular (Phong)   | eta        | 0           | metallic, specular weight, normal scale |
/// | 7    |                   | shininess (Phong)  | GGX alpha  | GGX alpha   | roughness                |
/// | 8..11| emitted radiance  |                    |            |             |                          |
/// | 11   |                   | ior                | ior        | ior         | map word                 |
/// | 12..15|                  | absorption (glass) | k          | absorption  | the dielectric F0        |
/// | 15   | flags word        |                    |            |             |                          |
///
/// The kind word is the kind (`MAT_*`) | emission texture + 1 << MAT_MAP_SHIFT, the map
/// word metallic-roughness texture + 1 | normal texture + 1 << MAT_MAP_SHIFT, the flags
/// word MAT_FLAG_* | texture + 1 << MAT_TEXTURE_SHIFT, all as uint bits (0: none).
pub const MAT_W_COLOR_RGB: u32 = 0;
pub const MAT_W_KIND: u32 = 3;
pub const MAT_W_SPECULAR_RGB: u32 = 4;
pub const MAT_W_SHININESS: u32 = 7;
pub const MAT_W_ETA_RGB: u32 = 4;
pub const MAT_W_ALPHA: u32 = 7;
pub const MAT_W_METALLIC: u32 = 4;
pub const MAT_W_SPEC_WEIGHT: u32 = 5;
pub const MAT_W_NORMAL_SCALE: u32 = 6;
pub const MAT_W_ROUGHNESS: u32 = 7;
pub const MAT_W_EMISSION_RGB: u32 = 8;
pub const MAT_W_IOR: u32 = 11;
pub const MAT_W_MAPS: u32 = 11;
pub const MAT_W_ABSORPTION_RGB: u32 = 12;
pub const MAT_W_K_RGB: u32 = 12;
pub const MAT_W_F0_RGB: u32 = 12;
pub const MAT_W_FLAGS: u32 = 15;
/// The words of a light record: the position (a point light) or the direction the
/// light travels (directional, unit), 1.0 for a point light and 0.0 for a directional
/// one, the intensity (point) or radiance (directional).
pub const LIGHT_W_POSITION_RGB: u32 = 0;
pub const LIGHT_W_IS_POINT: u32 = 3;
pub const LIGHT_W_RADIANCE_RGB: u32 = 4;
/// GGX alpha below which a conductor or dielectric is smooth (a delta lobe), as its
/// f32 bits (shaders read `uintBitsToFloat(SMOOTH_ALPHA_BITS)`): 0.001, roughness
/// 0.0316.
pub const SMOOTH_ALPHA_BITS: u32 = 0x3a83_126f;
/// Values of SPEC_MIS.
pub const MIS_BOTH: u32 = 0;
pub const MIS_LIGHT: u32 = 1;
pub const MIS_BSDF: u32 = 2;
/// Bit of `GpuPixel::prim_cost[3]` set when a trace ran out of steps.
pub const OVERFLOW_FLAG: u32 = 0x8000_0000;
/// Resumed traces (docs/kernels.md, "Resumed traces"): words of a trace record's head
/// (trace, log entries, counters, best hit so far), of one logged trace result, and of
/// one traversal level's state besides its stack (which takes 2 x SPEC_STACK_SIZE
/// words more).
pub const RESUME_HEAD_WORDS: u32 = 16;
pub const RESUME_LOG_WORDS: u32 = 8;
pub const RESUME_LEVEL_WORDS: u32 = 32;
/// Loop iterations the resume kernel may add to one trace (its restore, save and log
/// loops, at two levels in instanced scenes), beyond the traversal's steps.
pub const RESUME_LOOPS_PER_TRACE: u64 = 8;
/// The smallest per-trace step budget a render may force (`RenderSettings::trace_steps`):
/// the grid's first-cell search (3 x 12 steps at most, `grid::MAX_RES` = 4096 cells an
/// axis) after the step into an instance (INST_ENTRY_STEPS) must fit, or its traces
/// could not advance.
pub const MIN_FORCED_TRACE_STEPS: u32 = 48;
/// Passes of the trace kernel (`DispatchChunk::pass`): the samples of a pixel range;
/// the resume kernel over that range, for pixels behind (job list 0 out); over job
/// list 0 (list 1 out); over list 1 (list 0 out).
pub const PASS_TRACE: u32 = 0;
pub const PASS_SWEEP: u32 = 1;
pub const PASS_LIST0: u32 = 2;
pub const PASS_LIST1: u32 = 3;
/// Instanced scenes (src/accel/instance.rs): 16-byte texels of one entry record in
/// the node buffer, and the record's flag for the scene's own primitives.
pub const INST_ENTRY_TEXELS: u32 = 9;
pub const INST_ENTRY_OWN: u32 = 1;
/// Steps of the trace's budget an entry of the top level costs before its structure's
/// own: about the loop passes a bottom-level traversal makes when it has nothing to do
/// (llvmpipe counts them), the resume kernel's restore and save loops included.
pub const INST_ENTRY_STEPS: u32 = 8;

/// SPPM's hash grid built on the device (src/photon/device.rs, shaders/photon_grid.comp):
/// its bindings (the header of `PHOTON_HDR_*` words; the visible points as vec4
/// position + radius; the buckets' starts, buckets + 1 words; a cursor per bucket; the
/// entries), its passes (push constant `mode`), and the header's words.
pub const BINDING_PHOTON_HEADER: u32 = 0;
pub const BINDING_PHOTON_POINTS: u32 = 1;
pub const BINDING_PHOTON_STARTS: u32 = 2;
pub const BINDING_PHOTON_CURSOR: u32 = 3;
pub const BINDING_PHOTON_ENTRIES: u32 = 4;
/// The query photons (vec4 position) and what each found (uvec2: points, sum of their
/// indices + 1) of the grid's test pass, `PHOTON_GRID_PROBE`.
pub const BINDING_PHOTON_QUERIES: u32 = 5;
pub const BINDING_PHOTON_FOUND: u32 = 6;
/// The kd-tree over visible points (`photon::PointTree`'s nodes, two vec4 each), read
/// by common/photon_tree.glsl; and the deepest tree it searches (a balanced tree of
/// `photon::device::MAX_POINTS` points: floor(log2 n) + 1 = 23 levels).
pub const BINDING_PHOTON_TREE: u32 = 7;
pub const PHOTON_TREE_MAX_DEPTH: u32 = 23;
pub const PHOTON_GRID_BOUNDS: u32 = 0;
pub const PHOTON_GRID_FRAME: u32 = 1;
pub const PHOTON_GRID_COUNT: u32 = 2;
pub const PHOTON_GRID_SCAN: u32 = 3;
pub const PHOTON_GRID_SCATTER: u32 = 4;
pub const PHOTON_GRID_PROBE: u32 = 5;
/// The pass a photon-grid pipeline runs (`PHOTON_GRID_*`): one pipeline a pass, so
/// that each holds only its own code (llvmpipe runs both sides of a branch, so a
/// kernel of every pass costs every pass's time).
pub const SPEC_GRID_MODE: u32 = 23;
/// The pass before the others: the header back to its start (an empty box) and the
/// buckets' counts to zero, so that a build is one submission.
pub const PHOTON_GRID_CLEAR: u32 = 6;
/// Header words: the spheres' box (min, max: order-preserving uints), the largest
/// radius (float bits), cells per axis, the cell edge (float bits), the entries.
pub const PHOTON_HDR_MIN: u32 = 0;
pub const PHOTON_HDR_MAX: u32 = 3;
pub const PHOTON_HDR_RADIUS: u32 = 6;
pub const PHOTON_HDR_RES: u32 = 7;
pub const PHOTON_HDR_EDGE: u32 = 10;
pub const PHOTON_HDR_TOTAL: u32 = 11;
pub const PHOTON_HDR_WORDS: u32 = 16;
/// Most cells along one axis of the photon hash grid (`photon::hashgrid::MAX_RES`).
pub const PHOTON_GRID_MAX_RES: u32 = 1 << 20;
/// Threads per workgroup of the grid's passes (the scan is one workgroup).
pub const PHOTON_GROUP: u32 = 256;

/// SPPM (src/render/integrators/sppm.rs, shaders/common/sppm.glsl): the trace kernel's
/// extra bindings in its `sppm` module, each over the window's pixels (slots):
/// the visible points as the photon lookups read them (vec4 position + radius; radius 0
/// where a pixel has none this iteration).
pub const BINDING_SPPM_POINTS: u32 = 11;
/// Per slot `SPPM_RECORD_ROWS` vec4 rows (`SPPM_REC_*`): the visible point and the
/// pixel's running estimate.
pub const BINDING_SPPM_RECORDS: u32 = 12;
/// `SPPM_COUNTERS` counters of the whole render (`SPPM_COUNT_*`), then per slot
/// `SPPM_FLUX_WORDS` uints of the iteration's photons (fixed point, summed by integer
/// atomics so that the sum does not depend on order).
pub const BINDING_SPPM_FLUX: u32 = 13;
/// Texel: the hash grid's header (`PHOTON_HDR_*` words) and bucket starts
/// (src/photon/device.rs builds them, as storage).
pub const BINDING_SPPM_GRID_HEADER: u32 = 14;
pub const BINDING_SPPM_GRID_STARTS: u32 = 15;
/// Texel: the photon map itself: the grid's entries (uint), or the kd-tree's nodes (two
/// vec4 each) with `--photon-map kdtree`.
pub const BINDING_SPPM_MAP: u32 = 16;
/// Texel views of the points and the records, which the photon pass reads (the camera
/// and update passes write them through the storage bindings above).
pub const BINDING_SPPM_POINT_TEXELS: u32 = 17;
pub const BINDING_SPPM_RECORD_TEXELS: u32 = 18;
/// Which lookup the photon pass makes (`SPPM_MAP_HASHGRID`, `SPPM_MAP_KDTREE`).
pub const SPEC_PHOTON_MAP: u32 = 22;
pub const SPPM_MAP_HASHGRID: u32 = 0;
pub const SPPM_MAP_KDTREE: u32 = 1;
/// The pass an `sppm` pipeline runs (`SPPM_PASS_*`): one pipeline a pass, so that each
/// holds only its own code (llvmpipe runs both sides of a branch).
pub const SPEC_SPPM_PASS: u32 = 24;
/// The passes of one iteration, in order: camera paths to their visible points, photons
/// from the lights into them, and each pixel's radius and flux update.
pub const SPPM_PASS_CAMERA: u32 = 0;
pub const SPPM_PASS_PHOTON: u32 = 1;
pub const SPPM_PASS_UPDATE: u32 = 2;
/// A slot's record rows: the visible point (position, material | front flag, or
/// `SPPM_NO_POINT`), its shading normal + u, direction to the camera + v, path
/// throughput + the camera path's segments, the sum of its direct light + the radius,
/// tau (the flux kept, pbrt's) + N (the photons it counts), and the vertex colour at
/// the point (with `SPEC_VERTEX_COLORS`; its base colour's factor). A Lambert point's
/// throughput is times its BSDF (`SPPM_DIFFUSE_BIT`).
pub const SPPM_REC_POINT: u32 = 0;
pub const SPPM_REC_NORMAL: u32 = 1;
pub const SPPM_REC_WO: u32 = 2;
pub const SPPM_REC_BETA: u32 = 3;
pub const SPPM_REC_DIRECT: u32 = 4;
pub const SPPM_REC_TAU: u32 = 5;
pub const SPPM_REC_TINT: u32 = 6;
pub const SPPM_RECORD_ROWS: u32 = 7;
/// The record's material word when the pixel has no visible point this iteration, and
/// the bit of it that says the camera came from the front of the surface.
pub const SPPM_NO_POINT: u32 = 0xffff_ffff;
pub const SPPM_FRONT_BIT: u32 = 0x8000_0000;
/// The bit that says the visible point is Lambert: its record's throughput is then
/// already times the BSDF (albedo / pi), and a deposit needs no material.
pub const SPPM_DIFFUSE_BIT: u32 = 0x4000_0000;
/// A slot's flux words: red, green, blue as 64-bit fixed point (low word, high word),
/// then the photons found (M), then one unused.
pub const SPPM_FLUX_WORDS: u32 = 8;
pub const SPPM_FLUX_COUNT: u32 = 6;
/// The counters before the slots' flux words: rays the photons traced, paths cut short by the
/// traversal's step budget (camera and photon), lookups that met more than
/// `SPPM_BUCKET_MOST` candidates (the rest were not tested), photons deposited.
pub const SPPM_COUNT_PHOTON_RAYS: u32 = 0;
pub const SPPM_COUNT_CUT: u32 = 1;
pub const SPPM_COUNT_TRUNCATED: u32 = 2;
pub const SPPM_COUNT_DEPOSITS: u32 = 3;
pub const SPPM_COUNTERS: u32 = 4;
/// Most candidates one photon tests in a hash-grid bucket (a bound on the loop).
pub const SPPM_BUCKET_MOST: u32 = 4096;
/// The light table of the photon pass (shading rows from `GpuParams::photon_light_table`,
/// one a light: CDF start, probability, kind bits, index bits, then one row: the photon
/// guide, center and radius): the kinds.
pub const SPPM_LIGHT_DELTA: u32 = 0;
pub const SPPM_LIGHT_AREA: u32 = 1;
pub const SPPM_LIGHT_ENV: u32 = 2;
/// The share of a light's photons sent toward the photon guide (the sphere bounding the
/// scene's delta surfaces, the shading row after the light table), in percent; the rest
/// as the light sends them. Each photon's power is divided by the pdf of the mixture.
pub const SPPM_GUIDE_PERCENT: u32 = 50;
/// The default initial radius: this many pixel footprints at the visible point's
/// distance along the camera path.
pub const SPPM_FOOTPRINT_PIXELS: u32 = 3;

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
    ("BINDING_TLAS", BINDING_TLAS),
    ("BINDING_RESUME", BINDING_RESUME),
    ("BINDING_RAYS", BINDING_RAYS),
    ("WORKGROUP_SIZE", WORKGROUP_SIZE),
    ("MAX_PATH_DEPTH", MAX_PATH_DEPTH),
    ("SPEC_LIGHTS", SPEC_LIGHTS),
    ("SPEC_MAX_DEPTH", SPEC_MAX_DEPTH),
    ("SPEC_STACK_SIZE", SPEC_STACK_SIZE),
    ("SPEC_INTERSECT", SPEC_INTERSECT),
    ("SPEC_DIFFUSE_PROBE", SPEC_DIFFUSE_PROBE),
    ("SPEC_FIT_GROUP", SPEC_FIT_GROUP),
    ("SPEC_SCATTER_GROUP", SPEC_SCATTER_GROUP),
    ("SPEC_WIDE_WIDTH", SPEC_WIDE_WIDTH),
    ("SPEC_TRIANGLE_COUNT", SPEC_TRIANGLE_COUNT),
    ("SPEC_SPHERE_COUNT", SPEC_SPHERE_COUNT),
    ("SPEC_INTEGRATOR", SPEC_INTEGRATOR),
    ("INTEGRATOR_WHITTED", INTEGRATOR_WHITTED),
    ("INTEGRATOR_PATH", INTEGRATOR_PATH),
    ("INTEGRATOR_PROBE", INTEGRATOR_PROBE),
    ("INTEGRATOR_SPPM", INTEGRATOR_SPPM),
    ("SPEC_EMITTERS", SPEC_EMITTERS),
    ("SPEC_ENV_WIDTH", SPEC_ENV_WIDTH),
    ("SPEC_ENV_HEIGHT", SPEC_ENV_HEIGHT),
    ("SPEC_TEXTURES", SPEC_TEXTURES),
    ("SPEC_ALPHA", SPEC_ALPHA),
    ("ALPHA_ON", ALPHA_ON),
    ("ALPHA_TEXTURES", ALPHA_TEXTURES),
    ("ALPHA_BLEND", ALPHA_BLEND),
    ("SPEC_VERTEX_COLORS", SPEC_VERTEX_COLORS),
    ("SPEC_MIS", SPEC_MIS),
    ("SPEC_RR_DEPTH", SPEC_RR_DEPTH),
    ("SPEC_MATERIAL_KINDS", SPEC_MATERIAL_KINDS),
    ("SPEC_PACKET", SPEC_PACKET),
    ("SPEC_WHITTED_SPLIT", SPEC_WHITTED_SPLIT),
    ("WHITTED_SPLIT_MAX", WHITTED_SPLIT_MAX),
    ("SPEC_RESUME_PASS", SPEC_RESUME_PASS),
    ("SPEC_RESUME_LOG", SPEC_RESUME_LOG),
    ("SPEC_RESUME_RECORDS", SPEC_RESUME_RECORDS),
    ("SPEC_RESUME_JOBS", SPEC_RESUME_JOBS),
    ("RESUME_HEAD_WORDS", RESUME_HEAD_WORDS),
    ("RESUME_LOG_WORDS", RESUME_LOG_WORDS),
    ("RESUME_LEVEL_WORDS", RESUME_LEVEL_WORDS),
    ("PASS_TRACE", PASS_TRACE),
    ("PASS_SWEEP", PASS_SWEEP),
    ("PASS_LIST0", PASS_LIST0),
    ("PASS_LIST1", PASS_LIST1),
    ("OVERFLOW_FLAG", OVERFLOW_FLAG),
    ("BVH_LEAF_REF", BVH_LEAF_REF),
    ("BVH_EMPTY_REF", BVH_EMPTY_REF),
    ("BVH_MAX_LEAF", BVH_MAX_LEAF),
    ("BVH_LEAF_COUNT_BITS", BVH_LEAF_COUNT_BITS),
    ("BVH_LEAF_COUNT_MASK", BVH_LEAF_COUNT_MASK),
    ("BUILD_LEAF_FLAG", BUILD_LEAF_FLAG),
    ("WIDE_NODE_PLANES", WIDE_NODE_PLANES),
    ("INST_ENTRY_TEXELS", INST_ENTRY_TEXELS),
    ("INST_ENTRY_OWN", INST_ENTRY_OWN),
    ("INST_ENTRY_STEPS", INST_ENTRY_STEPS),
    ("MAT_LAMBERT", MAT_LAMBERT),
    ("MAT_PHONG", MAT_PHONG),
    ("MAT_MIRROR", MAT_MIRROR),
    ("MAT_GLASS", MAT_GLASS),
    ("MAT_EMISSIVE", MAT_EMISSIVE),
    ("MAT_CONDUCTOR", MAT_CONDUCTOR),
    ("MAT_DIELECTRIC", MAT_DIELECTRIC),
    ("MAT_PBR", MAT_PBR),
    ("MAT_FLAG_TWO_SIDED", MAT_FLAG_TWO_SIDED),
    ("MAT_FLAG_SCHLICK", MAT_FLAG_SCHLICK),
    ("SMOOTH_ALPHA_BITS", SMOOTH_ALPHA_BITS),
    ("MAT_TEXTURE_SHIFT", MAT_TEXTURE_SHIFT),
    ("MAT_MAP_SHIFT", MAT_MAP_SHIFT),
    ("MATERIAL_ROWS", MATERIAL_ROWS),
    ("LIGHT_ROWS", LIGHT_ROWS),
    ("MAT_W_COLOR_RGB", MAT_W_COLOR_RGB),
    ("MAT_W_KIND", MAT_W_KIND),
    ("MAT_W_SPECULAR_RGB", MAT_W_SPECULAR_RGB),
    ("MAT_W_SHININESS", MAT_W_SHININESS),
    ("MAT_W_ETA_RGB", MAT_W_ETA_RGB),
    ("MAT_W_ALPHA", MAT_W_ALPHA),
    ("MAT_W_METALLIC", MAT_W_METALLIC),
    ("MAT_W_SPEC_WEIGHT", MAT_W_SPEC_WEIGHT),
    ("MAT_W_NORMAL_SCALE", MAT_W_NORMAL_SCALE),
    ("MAT_W_ROUGHNESS", MAT_W_ROUGHNESS),
    ("MAT_W_EMISSION_RGB", MAT_W_EMISSION_RGB),
    ("MAT_W_IOR", MAT_W_IOR),
    ("MAT_W_MAPS", MAT_W_MAPS),
    ("MAT_W_ABSORPTION_RGB", MAT_W_ABSORPTION_RGB),
    ("MAT_W_K_RGB", MAT_W_K_RGB),
    ("MAT_W_F0_RGB", MAT_W_F0_RGB),
    ("MAT_W_FLAGS", MAT_W_FLAGS),
    ("LIGHT_W_POSITION_RGB", LIGHT_W_POSITION_RGB),
    ("LIGHT_W_IS_POINT", LIGHT_W_IS_POINT),
    ("LIGHT_W_RADIANCE_RGB", LIGHT_W_RADIANCE_RGB),
    ("TEXTURE_WRAP_U_SHIFT", TEXTURE_WRAP_U_SHIFT),
    ("TEXTURE_WRAP_V_SHIFT", TEXTURE_WRAP_V_SHIFT),
    ("MIS_BOTH", MIS_BOTH),
    ("MIS_LIGHT", MIS_LIGHT),
    ("MIS_BSDF", MIS_BSDF),
    ("BINDING_BUILD_HEADER", BINDING_BUILD_HEADER),
    ("BINDING_BUILD_PRIM_BOUNDS", BINDING_BUILD_PRIM_BOUNDS),
    ("BINDING_BUILD_PAIRS", BINDING_BUILD_PAIRS),
    ("BINDING_BUILD_PAIRS_OUT", BINDING_BUILD_PAIRS_OUT),
    ("BINDING_BUILD_HIST", BINDING_BUILD_HIST),
    ("BINDING_BUILD_NODES", BINDING_BUILD_NODES),
    ("BINDING_BUILD_AUX", BINDING_BUILD_AUX),
    ("BINDING_BUILD_OUT_NODES", BINDING_BUILD_OUT_NODES),
    ("BINDING_BUILD_OUT_INDICES", BINDING_BUILD_OUT_INDICES),
    ("BINDING_BUILD_LEVELS", BINDING_BUILD_LEVELS),
    ("BINDING_BUILD_WIDE", BINDING_BUILD_WIDE),
    ("BINDING_BUILD_WIDE_NODES", BINDING_BUILD_WIDE_NODES),
    ("BUILD_HDR_CMIN", BUILD_HDR_CMIN),
    ("BUILD_HDR_CMAX", BUILD_HDR_CMAX),
    ("BUILD_HDR_DEPTH", BUILD_HDR_DEPTH),
    ("BUILD_HDR_ERRORS", BUILD_HDR_ERRORS),
    ("BUILD_HDR_NODES", BUILD_HDR_NODES),
    ("BUILD_HDR_WIDE_NODES", BUILD_HDR_WIDE_NODES),
    ("BUILD_HDR_WIDE_DEPTH", BUILD_HDR_WIDE_DEPTH),
    ("BUILD_ERR_WALK", BUILD_ERR_WALK),
    ("BUILD_ERR_LEVELS", BUILD_ERR_LEVELS),
    ("BUILD_MAX_LEVELS", BUILD_MAX_LEVELS),
    ("BUILD_LV_SLOTS", BUILD_LV_SLOTS),
    ("BUILD_LV_COUNT", BUILD_LV_COUNT),
    ("BUILD_LV_OFFSET", BUILD_LV_OFFSET),
    ("BUILD_LV_CURSOR", BUILD_LV_CURSOR),
    ("BUILD_LV_ARGS", BUILD_LV_ARGS),
    ("BUILD_LV_LIST", BUILD_LV_LIST),
    ("BUILD_MAX_WALK", BUILD_MAX_WALK),
    ("BUILD_GROUP", BUILD_GROUP),
    ("BUILD_SORT_ITEMS", BUILD_SORT_ITEMS),
    ("BUILD_BOUNDS_ITEMS", BUILD_BOUNDS_ITEMS),
    ("BUILD_SCATTER_MAX_GROUP", BUILD_SCATTER_MAX_GROUP),
    ("BUILD_LEVEL_GROUP", BUILD_LEVEL_GROUP),
    ("BUILD_LEVELS_COUNT", BUILD_LEVELS_COUNT),
    ("BUILD_LEVELS_SCAN", BUILD_LEVELS_SCAN),
    ("BUILD_LEVELS_SCATTER", BUILD_LEVELS_SCATTER),
    ("BUILD_FINALIZE_COLLAPSE", BUILD_FINALIZE_COLLAPSE),
    ("BUILD_EMIT_ROOT", BUILD_EMIT_ROOT),
    ("BUILD_EMIT_TOP", BUILD_EMIT_TOP),
    ("BUILD_EMIT_UNFINALIZED", BUILD_EMIT_UNFINALIZED),
    ("BUILD_WIDE_SEED", BUILD_WIDE_SEED),
    ("BUILD_WIDE_MARK", BUILD_WIDE_MARK),
    ("BUILD_WIDE_COUNT", BUILD_WIDE_COUNT),
    ("BUILD_WIDE_SCAN", BUILD_WIDE_SCAN),
    ("BUILD_WIDE_NUMBER", BUILD_WIDE_NUMBER),
    ("BUILD_WIDE_WRITE", BUILD_WIDE_WRITE),
    ("BUILD_WIDE_ITEMS", BUILD_WIDE_ITEMS),
    ("BINDING_PHOTON_HEADER", BINDING_PHOTON_HEADER),
    ("BINDING_PHOTON_POINTS", BINDING_PHOTON_POINTS),
    ("BINDING_PHOTON_STARTS", BINDING_PHOTON_STARTS),
    ("BINDING_PHOTON_CURSOR", BINDING_PHOTON_CURSOR),
    ("BINDING_PHOTON_ENTRIES", BINDING_PHOTON_ENTRIES),
    ("BINDING_PHOTON_QUERIES", BINDING_PHOTON_QUERIES),
    ("BINDING_PHOTON_FOUND", BINDING_PHOTON_FOUND),
    ("BINDING_PHOTON_TREE", BINDING_PHOTON_TREE),
    ("PHOTON_TREE_MAX_DEPTH", PHOTON_TREE_MAX_DEPTH),
    ("PHOTON_GRID_BOUNDS", PHOTON_GRID_BOUNDS),
    ("PHOTON_GRID_FRAME", PHOTON_GRID_FRAME),
    ("PHOTON_GRID_COUNT", PHOTON_GRID_COUNT),
    ("PHOTON_GRID_SCAN", PHOTON_GRID_SCAN),
    ("PHOTON_GRID_SCATTER", PHOTON_GRID_SCATTER),
    ("PHOTON_GRID_PROBE", PHOTON_GRID_PROBE),
    ("PHOTON_GRID_CLEAR", PHOTON_GRID_CLEAR),
    ("SPEC_GRID_MODE", SPEC_GRID_MODE),
    ("PHOTON_HDR_MIN", PHOTON_HDR_MIN),
    ("PHOTON_HDR_MAX", PHOTON_HDR_MAX),
    ("PHOTON_HDR_RADIUS", PHOTON_HDR_RADIUS),
    ("PHOTON_HDR_RES", PHOTON_HDR_RES),
    ("PHOTON_HDR_EDGE", PHOTON_HDR_EDGE),
    ("PHOTON_HDR_TOTAL", PHOTON_HDR_TOTAL),
    ("PHOTON_HDR_WORDS", PHOTON_HDR_WORDS),
    ("PHOTON_GRID_MAX_RES", PHOTON_GRID_MAX_RES),
    ("PHOTON_GROUP", PHOTON_GROUP),
    ("BINDING_SPPM_POINTS", BINDING_SPPM_POINTS),
    ("BINDING_SPPM_RECORDS", BINDING_SPPM_RECORDS),
    ("BINDING_SPPM_FLUX", BINDING_SPPM_FLUX),
    ("BINDING_SPPM_GRID_HEADER", BINDING_SPPM_GRID_HEADER),
    ("BINDING_SPPM_GRID_STARTS", BINDING_SPPM_GRID_STARTS),
    ("BINDING_SPPM_MAP", BINDING_SPPM_MAP),
    ("BINDING_SPPM_POINT_TEXELS", BINDING_SPPM_POINT_TEXELS),
    ("BINDING_SPPM_RECORD_TEXELS", BINDING_SPPM_RECORD_TEXELS),
    ("SPEC_PHOTON_MAP", SPEC_PHOTON_MAP),
    ("SPPM_MAP_HASHGRID", SPPM_MAP_HASHGRID),
    ("SPPM_MAP_KDTREE", SPPM_MAP_KDTREE),
    ("SPEC_SPPM_PASS", SPEC_SPPM_PASS),
    ("SPPM_PASS_CAMERA", SPPM_PASS_CAMERA),
    ("SPPM_PASS_PHOTON", SPPM_PASS_PHOTON),
    ("SPPM_PASS_UPDATE", SPPM_PASS_UPDATE),
    ("SPPM_REC_POINT", SPPM_REC_POINT),
    ("SPPM_REC_NORMAL", SPPM_REC_NORMAL),
    ("SPPM_REC_WO", SPPM_REC_WO),
    ("SPPM_REC_BETA", SPPM_REC_BETA),
    ("SPPM_REC_DIRECT", SPPM_REC_DIRECT),
    ("SPPM_REC_TAU", SPPM_REC_TAU),
    ("SPPM_REC_TINT", SPPM_REC_TINT),
    ("SPPM_RECORD_ROWS", SPPM_RECORD_ROWS),
    ("SPPM_NO_POINT", SPPM_NO_POINT),
    ("SPPM_FRONT_BIT", SPPM_FRONT_BIT),
    ("SPPM_DIFFUSE_BIT", SPPM_DIFFUSE_BIT),
    ("SPPM_FLUX_WORDS", SPPM_FLUX_WORDS),
    ("SPPM_FLUX_COUNT", SPPM_FLUX_COUNT),
    ("SPPM_COUNT_PHOTON_RAYS", SPPM_COUNT_PHOTON_RAYS),
    ("SPPM_COUNT_CUT", SPPM_COUNT_CUT),
    ("SPPM_COUNT_TRUNCATED", SPPM_COUNT_TRUNCATED),
    ("SPPM_COUNT_DEPOSITS", SPPM_COUNT_DEPOSITS),
    ("SPPM_COUNTERS", SPPM_COUNTERS),
    ("SPPM_BUCKET_MOST", SPPM_BUCKET_MOST),
    ("SPPM_LIGHT_DELTA", SPPM_LIGHT_DELTA),
    ("SPPM_LIGHT_AREA", SPPM_LIGHT_AREA),
    ("SPPM_LIGHT_ENV", SPPM_LIGHT_ENV),
    ("SPPM_FOOTPRINT_PIXELS", SPPM_FOOTPRINT_PIXELS),
    ("SPPM_GUIDE_PERCENT", SPPM_GUIDE_PERCENT),
];
