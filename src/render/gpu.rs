//! GPU rendering: upload the scene once, then trace in short dispatches (pixel
//! ranges x sample waves). Each pixel sums its samples in index order inside the
//! kernel, so the image is bit-identical whatever the split.

use std::time::Instant;

use super::{Frame, KernelChoice, RenderSettings, RenderStats};
use crate::accel::gpu_layout::*;
use crate::accel::Accel;
use crate::error::{Error, Result};
use crate::gpu::bindings::*;
use crate::gpu::{spirv, BindingDesc, BindingKind, Buffer, Context};
use crate::scene::{Light, Scene};

/// Most pixels held on the device at once (48 bytes each).
const MAX_CHUNK_PIXELS: u64 = 1 << 20;

/// Which geometry a kernel variant handles.
pub fn geometry_suffix(scene: &Scene, choice: KernelChoice) -> &'static str {
    match (choice, scene.triangles.is_empty(), scene.spheres.is_empty()) {
        (KernelChoice::General, _, _) => "all",
        (_, false, true) => "tris",
        (_, true, false) => "spheres",
        _ => "all",
    }
}

/// The descriptor bindings of a trace variant: structure kernel family (`none`,
/// `kdtree`) and geometry (`tris`, `spheres` or `all`).
pub fn trace_bindings(family: &str, geometry: &str) -> Vec<BindingDesc> {
    let mut b = vec![BindingDesc { binding: BINDING_PARAMS, kind: BindingKind::Uniform, name: "params" }];
    if geometry != "spheres" {
        b.push(BindingDesc { binding: BINDING_VERTICES, kind: BindingKind::Storage, name: "vertices" });
        b.push(BindingDesc { binding: BINDING_TRIANGLES, kind: BindingKind::Storage, name: "triangles" });
    }
    if geometry != "tris" {
        b.push(BindingDesc { binding: BINDING_SPHERES, kind: BindingKind::Storage, name: "spheres" });
    }
    b.push(BindingDesc { binding: BINDING_SHADING, kind: BindingKind::Storage, name: "shading" });
    b.push(BindingDesc { binding: BINDING_PIXELS, kind: BindingKind::Storage, name: "pixels" });
    if family != "none" {
        b.push(BindingDesc { binding: BINDING_ACCEL_NODES, kind: BindingKind::Storage, name: "accel_nodes" });
        b.push(BindingDesc { binding: BINDING_ACCEL_INDICES, kind: BindingKind::Storage, name: "accel_indices" });
    }
    b
}

/// Scene data in GPU layout.
#[derive(Debug, Clone)]
pub struct GpuScene {
    pub vertices: Vec<GpuVertex>,
    pub triangles: Vec<GpuTriangle>,
    pub spheres: Vec<GpuSphere>,
    /// Materials (4 rows each) then lights (2 rows each).
    pub shading: Vec<[f32; 4]>,
}

impl GpuScene {
    /// Converts a validated scene.
    pub fn new(scene: &Scene) -> GpuScene {
        let vertices = scene
            .positions
            .iter()
            .zip(&scene.normals)
            .map(|(p, n)| GpuVertex {
                position: [p.x, p.y, p.z, 0.0],
                normal: [n.x, n.y, n.z, if *n == glam::Vec3::ZERO { 0.0 } else { 1.0 }],
            })
            .collect();
        let triangles = scene
            .triangles
            .iter()
            .zip(&scene.tri_material)
            .map(|(t, m)| GpuTriangle { v: [t[0], t[1], t[2], *m] })
            .collect();
        let spheres = scene
            .spheres
            .iter()
            .map(|s| GpuSphere {
                center_radius: [s.center.x, s.center.y, s.center.z, s.radius],
                material: [s.material, 0, 0, 0],
            })
            .collect();
        let mut shading = Vec::with_capacity(scene.materials.len() * 4 + scene.lights.len() * 2);
        for m in &scene.materials {
            let g = GpuMaterial {
                color_kind: [m.color.x, m.color.y, m.color.z, f32::from_bits(m.kind as u32)],
                specular: [m.specular.x, m.specular.y, m.specular.z, m.shininess],
                emission_ior: [m.emission.x, m.emission.y, m.emission.z, m.ior],
                pad: [0.0; 4],
            };
            shading.extend([g.color_kind, g.specular, g.emission_ior, g.pad]);
        }
        for l in &scene.lights {
            let g = match *l {
                Light::Directional { direction: d, radiance: r } => {
                    GpuLight { position_or_direction: [d.x, d.y, d.z, 0.0], radiance: [r.x, r.y, r.z, 0.0] }
                }
                Light::Point { position: p, intensity: i } => {
                    GpuLight { position_or_direction: [p.x, p.y, p.z, 1.0], radiance: [i.x, i.y, i.z, 0.0] }
                }
            };
            shading.extend([g.position_or_direction, g.radiance]);
        }
        GpuScene { vertices, triangles, spheres, shading }
    }
}

/// Estimated primitive tests one sample of one pixel costs.
/// Estimated work (primitive tests or traversal steps) of one sample of one pixel,
/// used to size dispatches: every primitive for brute force; for a tree, a few
/// steps per level (the measured mean is about one step per level plus a few tests).
fn tests_per_sample(scene: &Scene, settings: &RenderSettings, accel: &Accel) -> u64 {
    let per_ray = match accel {
        Accel::None(_) => scene.prim_count().max(1) as u64,
        Accel::Kd(t) => 4 * (u64::from(t.depth) + 8),
        Accel::Bvh(t) => 4 * (u64::from(t.depth) + 8),
        // About half the cells along the diagonal, a few primitives each.
        Accel::Grid(g) => g.res.iter().map(|&r| u64::from(r)).sum::<u64>() + 16,
        // A descent from the root per cell visited.
        Accel::Octree(t) => 8 * (u64::from(t.depth) + 4),
    };
    let rays = if settings.diffuse_probe {
        2
    } else if settings.primary_only {
        1
    } else {
        1 + scene.lights.len() as u64 + 1
    };
    per_ray * rays
}

/// Traces one sample may run: at most `max_depth` closest-hit rays and one shadow
/// ray per light.
pub fn traces_per_sample(scene: &Scene, settings: &RenderSettings) -> u64 {
    if settings.diffuse_probe {
        2
    } else if settings.primary_only {
        1
    } else {
        u64::from(scene.max_depth) + scene.lights.len() as u64
    }
}

/// Upper bound on the loop iterations one invocation runs for one sample when each
/// trace runs at most `per_trace` iterations, plus the path and light loops.
pub fn loop_iterations_per_sample(scene: &Scene, settings: &RenderSettings, per_trace: u64) -> u64 {
    traces_per_sample(scene, settings) * (per_trace + 1) + 1
}

/// Loop iterations of one brute-force trace with the loops unrolled `unroll` times.
fn brute_iterations(scene: &Scene, unroll: u32) -> u64 {
    let step = u64::from(unroll);
    (scene.triangles.len() as u64).div_ceil(step) + (scene.spheres.len() as u64).div_ceil(step) + 2
}

/// Smallest per-trace step budget a tree traversal is given (nodes + primitive tests).
const MIN_TREE_STEPS: u64 = 256;
/// Per-trace step budget of tree traversal where the driver sets no loop limit.
const TREE_STEPS_UNLIMITED: u64 = 1 << 22;

/// Splits `pixels` x `spp` into dispatches of about `budget` primitive tests:
/// returns (pixels per dispatch, samples per dispatch).
pub fn dispatch_shape(pixels: u64, spp: u32, cost_per_sample: u64, budget: u64) -> (u64, u32) {
    let per_pixel_all = cost_per_sample.saturating_mul(u64::from(spp)).max(1);
    if pixels.saturating_mul(per_pixel_all) <= budget {
        return (pixels, spp);
    }
    let px = (budget / cost_per_sample.max(1)).max(u64::from(WORKGROUP_SIZE));
    if px >= pixels {
        let samples = (budget / (pixels.max(1) * cost_per_sample.max(1))).clamp(1, u64::from(spp)) as u32;
        return (pixels, samples);
    }
    (px / u64::from(WORKGROUP_SIZE) * u64::from(WORKGROUP_SIZE), 1)
}

/// Renders `scene` on `ctx`. `progress(done, total)` is called after each dispatch.
pub fn render(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    progress: impl FnMut(u64, u64),
) -> Result<(Frame, RenderStats)> {
    // validate() is for tests and `arbor info`: on a 1M-triangle tree it costs more
    // than the build, and render_with checks what the kernel depends on (depth).
    let accel = Accel::build_on(ctx, settings.accel, scene, &settings.params)?;
    render_with(ctx, scene, settings, &accel, progress)
}

/// Renders `scene` with an already built structure.
pub fn render_with(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    accel: &Accel,
    mut progress: impl FnMut(u64, u64),
) -> Result<(Frame, RenderStats)> {
    let (w, h) = (settings.width, settings.height);
    if w == 0 || h == 0 || w > crate::scene::MAX_FILM_SIDE || h > crate::scene::MAX_FILM_SIDE {
        return Err(Error::Usage(format!("image size {w}x{h} is invalid")));
    }
    if settings.spp == 0 || settings.spp > 1 << 20 {
        return Err(Error::Usage(format!("--spp must be 1..=1048576, got {}", settings.spp)));
    }
    let build = accel.stats(scene);
    let family = settings.accel.kernel();
    if let Accel::Bvh(t) = accel {
        if t.depth > crate::accel::bvh::MAX_BVH_DEPTH {
            return Err(Error::scene(
                scene.name.clone(),
                format!("BVH depth {} exceeds the kernel's stack of {}", t.depth, crate::accel::bvh::MAX_BVH_DEPTH),
            ));
        }
        if t.prims > crate::accel::bvh::MAX_BVH_PRIMS {
            return Err(Error::scene(
                scene.name.clone(),
                format!("{} primitives exceed the BVH layout's {}", t.prims, crate::accel::bvh::MAX_BVH_PRIMS),
            ));
        }
    }
    if let Accel::Kd(t) = accel {
        if t.depth > crate::accel::kdtree::MAX_KD_DEPTH {
            return Err(Error::scene(
                scene.name.clone(),
                format!(
                    "kd-tree depth {} exceeds the kernel's stack of {}",
                    t.depth,
                    crate::accel::kdtree::MAX_KD_DEPTH
                ),
            ));
        }
    }
    let geometry = geometry_suffix(scene, settings.kernel);
    let kernel_name = format!("trace_{family}_{geometry}");
    let spv =
        spirv::get(&kernel_name).ok_or_else(|| Error::Usage(format!("no kernel '{kernel_name}' was compiled")))?;
    let bindings = trace_bindings(family, geometry);
    let probe = settings.primary_only || settings.diffuse_probe;
    let use_lights = !probe && !scene.lights.is_empty();
    let max_depth = if probe { 1 } else { scene.max_depth };
    // Loop iterations per trace: fixed for brute force; a step budget for trees, which
    // the kernel enforces (flagging the pixel) so llvmpipe's limit is never crossed.
    let traces = traces_per_sample(scene, settings);
    // The smallest unroll factor whose loops fit the driver's limit for one sample.
    let unroll = match ctx.loop_budget() {
        None => 1,
        Some(budget) => BRUTE_UNROLL_FACTORS
            .into_iter()
            .find(|&u| loop_iterations_per_sample(scene, settings, brute_iterations(scene, u)) <= budget)
            .unwrap_or(BRUTE_UNROLL_FACTORS[BRUTE_UNROLL_FACTORS.len() - 1]),
    };
    let (per_trace, tree_steps) = match accel {
        Accel::None(_) => (brute_iterations(scene, unroll), 0u64),
        Accel::Kd(_) | Accel::Bvh(_) | Accel::Grid(_) | Accel::Octree(_) => {
            let steps = match ctx.loop_budget() {
                Some(budget) => (budget / traces.max(1)).saturating_sub(2).min(TREE_STEPS_UNLIMITED),
                None => TREE_STEPS_UNLIMITED,
            };
            if steps < MIN_TREE_STEPS {
                return Err(Error::Usage(format!(
                    "{}: {traces} traces per sample leave only {steps} traversal steps each within {}'s loop limit; lower [render] max_depth",
                    scene.name,
                    ctx.info().name
                )));
            }
            (steps, steps)
        }
    };
    let stack = accel.stack_size();
    let spec = [
        (SPEC_LIGHTS, if use_lights { scene.lights.len() as u32 } else { 0 }),
        (SPEC_MAX_DEPTH, max_depth),
        (SPEC_STACK_SIZE, stack),
        (SPEC_TREE_STEPS, tree_steps as u32),
        (SPEC_BRUTE_UNROLL, unroll),
        (SPEC_INTERSECT, scene.intersect.spec()),
        (SPEC_DIFFUSE_PROBE, u32::from(settings.diffuse_probe)),
        (SPEC_TRIANGLE_COUNT, scene.triangles.len() as u32),
        (SPEC_SPHERE_COUNT, scene.spheres.len() as u32),
    ];
    let mut kernel = ctx.create_kernel(&kernel_name, spv, &bindings, &spec, 0)?;

    let start = Instant::now();
    let gs = GpuScene::new(scene);
    let basis = scene.camera.basis(w, h);
    let bounds = accel.bounds();
    let params = GpuParams {
        cam_eye: [basis.eye.x, basis.eye.y, basis.eye.z, basis.tan_half],
        cam_right: [basis.right.x, basis.right.y, basis.right.z, basis.aspect],
        cam_up: [basis.up.x, basis.up.y, basis.up.z, 0.0],
        cam_forward: [basis.forward.x, basis.forward.y, basis.forward.z, 0.0],
        scene_min: [bounds.min.x, bounds.min.y, bounds.min.z, 0.0],
        scene_max: [bounds.max.x, bounds.max.y, bounds.max.z, 0.0],
        dims: [w, h, scene.triangles.len() as u32, scene.spheres.len() as u32],
        counts: [
            if use_lights { scene.lights.len() as u32 } else { 0 },
            scene.materials.len() as u32,
            settings.seed,
            0,
        ],
        background: [scene.background.x, scene.background.y, scene.background.z, scene.ambient],
    };
    let total_pixels = u64::from(w) * u64::from(h);
    let chunk_pixels = total_pixels.min(MAX_CHUNK_PIXELS).min(
        (ctx.max_storage_range().saturating_sub(PIXEL_HEADER_BYTES) / std::mem::size_of::<GpuPixel>() as u64).max(1),
    );

    // Buffers: only those the kernel declares are created and bound.
    let uniform = ctx.upload_uniform("params", bytemuck::bytes_of(&params))?;
    let mut keep: Vec<Buffer> = Vec::new();
    let mut bound_names = Vec::new();
    for b in &bindings {
        let buf = match b.binding {
            BINDING_PARAMS => {
                ctx.bind(&mut kernel, b.binding, &uniform)?;
                bound_names.push("params".to_string());
                continue;
            }
            BINDING_VERTICES => upload_checked(ctx, "vertices", bytemuck::cast_slice(&gs.vertices))?,
            BINDING_TRIANGLES => upload_checked(ctx, "triangles", bytemuck::cast_slice(&gs.triangles))?,
            BINDING_SPHERES => upload_checked(ctx, "spheres", bytemuck::cast_slice(&gs.spheres))?,
            BINDING_SHADING => upload_checked(ctx, "shading", bytemuck::cast_slice(&gs.shading))?,
            BINDING_ACCEL_NODES => match accel.gpu_buffers() {
                Some((nodes, _)) => upload_checked(ctx, "accel_nodes", &nodes)?,
                None => return Err(Error::Usage("brute force has no nodes".into())),
            },
            BINDING_ACCEL_INDICES => match accel.gpu_buffers() {
                Some((_, indices)) => upload_checked(ctx, "accel_indices", bytemuck::cast_slice(indices))?,
                None => return Err(Error::Usage("brute force has no indices".into())),
            },
            BINDING_PIXELS => {
                let size = PIXEL_HEADER_BYTES + chunk_pixels * std::mem::size_of::<GpuPixel>() as u64;
                check_range(ctx, "pixels", size)?;
                ctx.create_buffer("pixels", size, crate::gpu::BufferKind::Storage)?
            }
            other => return Err(Error::Usage(format!("trace kernel has unexpected binding {other}"))),
        };
        ctx.bind(&mut kernel, b.binding, &buf)?;
        bound_names.push(b.name.to_string());
        keep.push(buf);
    }
    let pixel_buf_index =
        bindings.iter().filter(|b| b.kind == BindingKind::Storage).position(|b| b.binding == BINDING_PIXELS);
    let pixel_buf = pixel_buf_index.and_then(|i| keep.get(i)).ok_or_else(|| Error::Usage("no pixel buffer".into()))?;

    let (px_per, mut spp_per) =
        dispatch_shape(chunk_pixels, settings.spp, tests_per_sample(scene, settings, accel), settings.dispatch_budget);
    if let Some(budget) = ctx.loop_budget() {
        let per_sample = loop_iterations_per_sample(scene, settings, per_trace);
        if per_sample > budget {
            return Err(Error::Usage(format!(
                "{}: one sample needs up to {per_sample} loop iterations per pixel, more than the {budget} that {} runs per invocation; use fewer primitives, a lower [render] max_depth, or an acceleration structure",
                scene.name,
                ctx.info().name
            )));
        }
        spp_per = spp_per.min((budget / per_sample) as u32).max(1);
    }
    let mut frame = Frame {
        width: w,
        height: h,
        radiance: vec![[0.0; 3]; total_pixels as usize],
        depth: vec![f32::INFINITY; total_pixels as usize],
        normal: vec![[0.0; 3]; total_pixels as usize],
        prim: vec![u32::MAX; total_pixels as usize],
        nodes: vec![0; total_pixels as usize],
        tests: vec![0; total_pixels as usize],
        rays: vec![0; total_pixels as usize],
    };
    let total_work = total_pixels * u64::from(settings.spp);
    let mut done = 0u64;
    let mut gpu_ms = Some(0.0f64);
    let mut dispatches = 0u32;
    let mut chunk_start = 0u64;
    let mut overflow = 0u64;
    while chunk_start < total_pixels {
        let chunk_len = chunk_pixels.min(total_pixels - chunk_start);
        let mut p = 0u64;
        while p < chunk_len {
            let n = px_per.min(chunk_len - p);
            let mut s = 0u32;
            while s < settings.spp {
                let s_end = (s + spp_per).min(settings.spp);
                let push = GpuDispatch {
                    range: [(chunk_start + p) as u32, n as u32, s, s_end],
                    chunk: [chunk_start as u32, 0, 0, 0],
                };
                let groups = n.div_ceil(u64::from(WORKGROUP_SIZE)) as u32;
                let label = format!("trace pixels {}+{n} samples {s}..{s_end}", chunk_start + p);
                let ms =
                    ctx.dispatch_after_write(&kernel, pixel_buf, 0, bytemuck::bytes_of(&push), [groups, 1, 1], &label)?;
                gpu_ms = match (gpu_ms, ms) {
                    (Some(a), Some(b)) => Some(a + b),
                    _ => None,
                };
                dispatches += 1;
                done += n * u64::from(s_end - s);
                progress(done, total_work);
                s = s_end;
            }
            p += n;
        }
        let bytes =
            ctx.read_storage(pixel_buf, PIXEL_HEADER_BYTES, chunk_len * std::mem::size_of::<GpuPixel>() as u64)?;
        let px: Vec<GpuPixel> =
            bytes.chunks_exact(std::mem::size_of::<GpuPixel>()).map(bytemuck::pod_read_unaligned::<GpuPixel>).collect();
        for (k, g) in px.iter().enumerate() {
            let idx = (chunk_start as usize) + k;
            let inv = 1.0 / settings.spp as f32;
            frame.radiance[idx] = [g.radiance[0] * inv, g.radiance[1] * inv, g.radiance[2] * inv];
            frame.normal[idx] = [g.normal_depth[0], g.normal_depth[1], g.normal_depth[2]];
            frame.depth[idx] = g.normal_depth[3];
            frame.prim[idx] = g.prim_cost[0];
            frame.nodes[idx] = g.prim_cost[1];
            frame.tests[idx] = g.prim_cost[2];
            frame.rays[idx] = g.prim_cost[3] & !OVERFLOW_FLAG;
            if g.prim_cost[3] & OVERFLOW_FLAG != 0 {
                overflow += 1;
            }
        }
        chunk_start += chunk_len;
    }
    ctx.check_validation()?;
    if overflow > 0 {
        return Err(Error::scene(
            scene.name.clone(),
            format!(
                "{overflow} pixels needed more than {tree_steps} traversal steps per ray (the per-trace budget on {}); their results would be wrong, so nothing was written",
                ctx.info().name
            ),
        ));
    }
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    let rays: u64 = frame.rays.iter().map(|&r| u64::from(r)).sum();
    let mrays = gpu_ms.filter(|&ms| ms > 0.0).map(|ms| rays as f64 / (ms * 1e3));
    let mean_tests = frame.tests.iter().map(|&t| t as f64).sum::<f64>() / total_pixels as f64;
    let stats = RenderStats {
        device: ctx.info().name.clone(),
        scene: scene.name.clone(),
        triangles: scene.triangles.len(),
        spheres: scene.spheres.len(),
        width: w,
        height: h,
        spp: settings.spp,
        accel: settings.accel.name().to_string(),
        build: build.clone(),
        kernel: kernel_name,
        bindings: bound_names,
        build_ms: build.build_ms,
        trace_ms: gpu_ms,
        wall_ms,
        dispatches,
        rays,
        mrays_per_s: mrays,
        accel_bytes: build.bytes,
        mean_prims_tested: mean_tests,
        mean_nodes_visited: frame.nodes.iter().map(|&t| t as f64).sum::<f64>() / total_pixels as f64,
    };
    Ok((frame, stats))
}

fn check_range(ctx: &Context, name: &str, size: u64) -> Result<()> {
    if size > ctx.max_storage_range() {
        return Err(Error::BufferTooLarge { name: name.to_string(), size, limit: ctx.max_storage_range() });
    }
    Ok(())
}

fn upload_checked(ctx: &Context, name: &str, data: &[u8]) -> Result<Buffer> {
    check_range(ctx, name, data.len() as u64)?;
    ctx.upload_storage(name, data)
}
