//! GPU against the CPU reference, kernel specialisation and dispatch splitting, on
//! whatever Vulkan device is present (lavapipe in CI) with validation on.

use crate::common;

use arbor::accel::{AccelKind, Geometry, KernelFamily};
use arbor::gpu::bindings::MAX_STORAGE_BUFFERS_PER_STAGE;
use arbor::gpu::{BindingDesc, BindingKind, Context, Kernel};
use arbor::render::{cpu, gpu, Frame, Integrator, KernelChoice, RenderSettings, Traversal};
use arbor::scene::{Camera, Light, Scene, SceneBuilder, Sphere};
use glam::Vec3;

use common::scenes::mixed_scene;

fn render(ctx: &Context, scene: &Scene, w: u32, h: u32, f: impl FnOnce(&mut RenderSettings)) -> Frame {
    let mut s = RenderSettings::for_size(w, h);
    f(&mut s);
    let (frame, _) = gpu::render(ctx, scene, &s, |_, _| {}).expect("render");
    ctx.check_validation().expect("no validation errors");
    frame
}

fn assert_aovs_match(name: &str, gpu: &Frame, cpu: &Frame) {
    let mut prim_bad = Vec::new();
    let mut depth_bad = Vec::new();
    for k in 0..gpu.prim.len() {
        if gpu.prim[k] != cpu.prim[k] {
            prim_bad.push((k, gpu.prim[k], cpu.prim[k]));
        }
        let (g, c) = (gpu.depth[k], cpu.depth[k]);
        let ok = if c.is_infinite() { g.is_infinite() && g > 0.0 } else { (g - c).abs() <= 1e-5 * c.abs() };
        if !ok {
            depth_bad.push((k, g, c));
        }
    }
    assert!(
        prim_bad.is_empty(),
        "{name}: {} pixels with a different prim, first {:?}",
        prim_bad.len(),
        &prim_bad[..prim_bad.len().min(5)]
    );
    assert!(
        depth_bad.is_empty(),
        "{name}: {} pixels with depth off by > 1e-5 relative, first {:?}",
        depth_bad.len(),
        &depth_bad[..depth_bad.len().min(5)]
    );
    let hits = cpu.prim.iter().filter(|&&p| p != u32::MAX).count();
    assert!(hits > 0 && hits < cpu.prim.len(), "{name}: the test image must contain hits and misses ({hits})");
}

#[test]
fn gpu_aovs_equal_cpu_reference() {
    let Some(ctx) = common::gpu() else { return };
    let mut cases: Vec<(String, Scene)> = Vec::new();
    for (k, eye) in
        [Vec3::new(0.0, 0.5, 4.0), Vec3::new(3.0, 2.0, 2.0), Vec3::new(-2.5, 0.1, -3.0), Vec3::new(0.01, 4.5, 0.01)]
            .into_iter()
            .enumerate()
    {
        cases.push((format!("mixed camera {k}"), mixed_scene(eye)));
    }
    cases.push(("builtin:cornell".into(), Scene::load("builtin:cornell").expect("cornell")));
    cases.push(("builtin:spheres".into(), Scene::load("builtin:spheres").expect("spheres")));
    let obj = "/usr/share/assimp/models/OBJ/spider.obj";
    if std::path::Path::new(obj).exists() {
        cases.push(("spider.obj".into(), Scene::load(obj).expect("spider")));
    }
    for (name, scene) in &cases {
        let (w, h) = (64, 48);
        let g = render(&ctx, scene, w, h, |_| {});
        let c = cpu::reference_aovs(scene, w, h);
        assert_aovs_match(name, &g, &c);
    }
}

#[test]
fn specialised_kernels_bind_only_what_the_scene_needs() {
    let Some(ctx) = common::gpu() else { return };
    let tris = Scene::load("builtin:blob:500").expect("blob");
    let spheres = Scene::load("builtin:spheres").expect("spheres");
    let both = mixed_scene(Vec3::new(0.0, 0.5, 4.0));
    let cases = [
        (&tris, "trace_none_tris", vec!["params", "vertices", "triangles", "shading", "pixels"]),
        (&spheres, "trace_none_spheres", vec!["params", "spheres", "shading", "pixels"]),
        (&both, "trace_none_all", vec!["params", "vertices", "triangles", "spheres", "shading", "pixels"]),
    ];
    for (scene, kernel, bound) in cases {
        let s = RenderSettings::for_size(16, 12);
        let (_, stats) = gpu::render(&ctx, scene, &s, |_, _| {}).expect("render");
        // The mixed scene's glass splits: more traces a sample, so lavapipe's loop
        // limit may need brute force's unrolled loops (`_x8`).
        let unrolled = stats.kernel.strip_prefix(kernel).is_some_and(|u| u.is_empty() || u.starts_with("_x"));
        assert!(unrolled, "{}: kernel {}, want {kernel}", scene.name, stats.kernel);
        assert_eq!(stats.bindings, bound, "{}", scene.name);
    }
    // Specialised and general kernels render the same image, bit for bit.
    for scene in [&tris, &spheres] {
        let a = render(&ctx, scene, 40, 30, |s| s.spp = 2);
        let b = render(&ctx, scene, 40, 30, |s| {
            s.spp = 2;
            s.kernel = KernelChoice::General;
        });
        assert_eq!(a.radiance, b.radiance, "{}: specialised and general radiance differ", scene.name);
        assert_eq!(a.prim, b.prim);
        assert_eq!(a.depth, b.depth);
    }
    // The path integrator on a scene of Lambert and emissive materials only: the
    // specialised kernel compiles the other kinds' shading away (SPEC_MATERIAL_KINDS),
    // and the image stays the same, bit for bit.
    let cornell = Scene::load("builtin:cornell").expect("cornell");
    let path = |s: &mut RenderSettings| {
        s.integrator = Integrator::Path;
        s.spp = 3;
    };
    let a = render(&ctx, &cornell, 24, 24, path);
    let b = render(&ctx, &cornell, 24, 24, |s| {
        path(s);
        s.kernel = KernelChoice::General;
    });
    assert!(a.radiance.iter().any(|p| p[0] > 0.0), "the box is lit");
    assert_eq!(a.radiance, b.radiance, "cornell: specialised and general path radiance differ");
}

#[test]
fn packet_traversal_gives_the_single_ray_image() {
    let Some(ctx) = common::gpu() else { return };
    // Camera rays (the probe kernel), bounce rays and shadow rays toward a point and a
    // directional light: packets change the work, never the image.
    let scene = mixed_scene(Vec3::new(0.2, 0.6, 3.5));
    for kind in [AccelKind::BvhSah, AccelKind::Trbvh, AccelKind::Kdtree] {
        for mode in ["primary", "diffuse", "whitted"] {
            let run = |traversal: Traversal| {
                render(&ctx, &scene, 61, 47, |s| {
                    s.accel = kind;
                    s.traversal = traversal;
                    s.primary_only = mode == "primary";
                    s.diffuse_probe = mode == "diffuse";
                })
            };
            let a = run(Traversal::Single);
            let b = run(Traversal::Packet);
            assert_eq!(a.prim, b.prim, "{kind} {mode}: primitives differ");
            assert_eq!(a.depth, b.depth, "{kind} {mode}: depths differ");
            assert_eq!(a.radiance, b.radiance, "{kind} {mode}: radiance differs");
            assert!(a.prim.iter().any(|&p| p != u32::MAX), "{kind} {mode}: something is hit");
        }
    }
}

#[test]
fn output_is_identical_whatever_the_dispatch_split() {
    let Some(ctx) = common::gpu() else { return };
    let scene = mixed_scene(Vec3::new(0.3, 0.8, 4.0));
    let whole = render(&ctx, &scene, 37, 23, |s| {
        s.spp = 3;
        s.seed = 9;
        s.pacing.budget = Some(u64::MAX / 4);
    });
    let split = render(&ctx, &scene, 37, 23, |s| {
        s.spp = 3;
        s.seed = 9;
        s.pacing.budget = Some(1);
    });
    assert_eq!(whole.radiance, split.radiance);
    assert_eq!(whole.depth, split.depth);
    assert_eq!(whole.prim, split.prim);
    // A different seed changes the jittered samples.
    let other = render(&ctx, &scene, 37, 23, |s| {
        s.spp = 3;
        s.seed = 10;
    });
    assert_ne!(whole.radiance, other.radiance);
}

#[test]
fn every_pipeline_respects_the_storage_buffer_limit() {
    for kind in AccelKind::ALL {
        for geometry in Geometry::ALL {
            let b = gpu::trace_bindings(kind.kernel(), geometry);
            let storage = b.iter().filter(|d| d.kind == BindingKind::Storage).count();
            assert!(storage <= MAX_STORAGE_BUFFERS_PER_STAGE as usize, "{kind} {geometry}: {storage}");
            Kernel::check_storage_limit(geometry.name(), &b).expect("within limit");
            for (entry, _) in arbor::gpu::bindings::TRACE_ENTRIES {
                let name = format!("trace_{}_{geometry}.{entry}", kind.kernel());
                assert!(arbor::gpu::spirv::get(&name).is_some(), "{name} was not compiled");
            }
        }
    }
    let nine: Vec<BindingDesc> =
        (0..9).map(|i| BindingDesc { binding: i, kind: BindingKind::Storage, name: "x" }).collect();
    let err = Kernel::check_storage_limit("nine", &nine).expect_err("nine storage buffers must be refused");
    assert!(err.to_string().contains("9 storage buffers"), "{err}");
    // And on the device: creating such a kernel fails before any Vulkan call.
    let Some(ctx) = common::gpu() else { return };
    let spv = arbor::gpu::spirv::get("trace_none_all.path").expect("kernel");
    assert!(ctx.create_kernel("nine", spv, &nine, &[], 0).is_err());
}

/// Storage classes of the module-scope variables a SPIR-V module declares.
fn variable_storage_classes(spv: &[u8]) -> Vec<u32> {
    const OP_VARIABLE: u32 = 59;
    let words: Vec<u32> = spv.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    assert_eq!(words[0], 0x0723_0203, "not SPIR-V");
    let (mut i, mut out) = (5, Vec::new());
    while i < words.len() {
        let (count, op) = ((words[i] >> 16) as usize, words[i] & 0xffff);
        assert!(count > 0, "malformed instruction at word {i}");
        if op == OP_VARIABLE {
            out.push(words[i + 3]);
        }
        i += count;
    }
    out
}

#[test]
fn trace_kernels_take_no_push_constants() {
    // lavapipe compiles a kernel again at every dispatch for the push-constant values
    // its branches and loops depend on (6-7 ms a dispatch, measured): the trace kernels
    // read what changes per dispatch from the pixel buffer's header instead.
    const PUSH_CONSTANT: u32 = 9;
    let probe = arbor::gpu::spirv::get("math_probe").expect("kernel");
    assert!(variable_storage_classes(probe).contains(&PUSH_CONSTANT), "the scan must see math_probe's push constants");
    for kind in AccelKind::ALL {
        for geometry in Geometry::ALL {
            for (entry, _) in arbor::gpu::bindings::TRACE_ENTRIES {
                let name = format!("trace_{}_{geometry}.{entry}", kind.kernel());
                let spv = arbor::gpu::spirv::get(&name).expect("compiled");
                assert!(!variable_storage_classes(spv).contains(&PUSH_CONSTANT), "{name} declares push constants");
            }
        }
    }
}

#[test]
fn storage_range_limit_names_the_buffer() {
    if !common::has_gpu() {
        return;
    }
    let ctx =
        Context::new(&arbor::gpu::ContextOptions { max_storage_range: Some(4096), ..Default::default() }).expect("ctx");
    let scene = Scene::load("builtin:blob:2000").expect("blob");
    let err = gpu::render(&ctx, &scene, &RenderSettings::for_size(8, 8), |_, _| {}).expect_err("too large");
    let msg = err.to_string();
    assert!(msg.contains("'vertices'") && msg.contains("4096") && msg.contains("maxStorageBufferRange"), "{msg}");
}

#[test]
fn images_have_the_expected_content() {
    let Some(ctx) = common::gpu() else { return };
    // A lone Lambert sphere lit head-on by a directional light of radiance pi: the
    // centre pixel's radiance is albedo * (1 + ambient * background) within rounding.
    let mut b = SceneBuilder::new("analytic");
    b.scene.spheres.push(Sphere { center: Vec3::ZERO, radius: 1.0, material: 0 });
    b.scene
        .lights
        .push(Light::Directional { direction: Vec3::new(0.0, 0.0, -1.0), radiance: Vec3::splat(std::f32::consts::PI) });
    b.scene.camera = Camera { eye: Vec3::new(0.0, 0.0, 5.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov: 30.0 };
    b.scene.background = Vec3::new(0.2, 0.3, 0.4);
    b.scene.ambient = 0.0;
    let scene = b.finish().expect("scene");
    let f = render(&ctx, &scene, 33, 33, |_| {});
    let centre = f.radiance[16 * 33 + 16];
    for c in centre {
        assert!((c - 0.7).abs() < 1e-3, "centre radiance {centre:?}, expected albedo 0.7");
    }
    assert!((f.depth[16 * 33 + 16] - 4.0).abs() < 1e-5);
    assert_eq!(f.radiance[0], [0.2, 0.3, 0.4], "corner shows the background");
}

#[test]
fn validation_errors_fail_the_operation() {
    // A pipeline layout that leaves out a binding the shader uses is invalid; with the
    // validation layer on, arbor must turn the layer's message into an error.
    let ctx = match Context::new(&arbor::gpu::ContextOptions { validation: true, ..Default::default() }) {
        Ok(c) => c,
        Err(e) if common::gpu_required() => panic!("validation layer required: {e}"),
        Err(e) => {
            eprintln!("skipped: no Vulkan device with the validation layer ({e})");
            return;
        }
    };
    let spv = arbor::gpu::spirv::get("trace_none_spheres.whitted").expect("kernel");
    let short: Vec<BindingDesc> =
        gpu::trace_bindings(KernelFamily::None, Geometry::Spheres).into_iter().filter(|d| d.name != "pixels").collect();
    let err = ctx.create_kernel("missing_pixels", spv, &short, &[], 0).expect_err("validation must fail this");
    let msg = err.to_string();
    assert!(msg.contains("validation") && msg.contains("missing_pixels"), "{msg}");
}

/// The context's kernel cache: the same SPIR-V, bindings and declared constants reuse
/// one pipeline (each kernel still has its own bindings, and both run); another value
/// of a declared constant compiles again; a constant the module does not declare
/// changes nothing.
#[test]
fn kernels_created_again_reuse_the_compiled_pipeline() {
    use arbor::gpu::bindings::{
        BINDING_ACCEL_INDICES, BINDING_ACCEL_NODES, BINDING_PARAMS, BINDING_SHADING, SPEC_ENV_WIDTH,
        SPEC_TRIANGLE_COUNT,
    };
    use arbor::gpu::BufferKind;
    let Some(ctx) = common::private_gpu() else { return };
    let bindings = [
        BindingDesc { binding: BINDING_PARAMS, kind: BindingKind::Uniform, name: "params" },
        BindingDesc { binding: BINDING_SHADING, kind: BindingKind::Texel, name: "shading" },
        BindingDesc { binding: BINDING_ACCEL_NODES, kind: BindingKind::Storage, name: "probe_in" },
        BindingDesc { binding: BINDING_ACCEL_INDICES, kind: BindingKind::Storage, name: "probe_out" },
    ];
    let spv = arbor::gpu::spirv::get("sample_probe").expect("probe kernel compiled");
    let before = ctx.kernel_cache_stats();
    let a = ctx.create_kernel("probe_a", spv, &bindings, &[(SPEC_ENV_WIDTH, 1)], 32).expect("kernel a");
    let b = ctx
        .create_kernel("probe_b", spv, &bindings, &[(SPEC_ENV_WIDTH, 1), (SPEC_TRIANGLE_COUNT, 77)], 32)
        .expect("kernel b");
    let st = ctx.kernel_cache_stats();
    assert_eq!((st.misses - before.misses, st.hits - before.hits), (1, 1), "b reuses a's pipeline: {st:?}");
    let _c = ctx.create_kernel("probe_c", spv, &bindings, &[(SPEC_ENV_WIDTH, 2)], 32).expect("kernel c");
    let st = ctx.kernel_cache_stats();
    assert_eq!((st.misses - before.misses, st.hits - before.hits), (2, 1), "another width compiles: {st:?}");
    assert_eq!(st.held, 2);
    // Both kernels of the shared pipeline bind and run on their own descriptor sets.
    let params = ctx
        .upload_uniform("params", &vec![0u8; std::mem::size_of::<arbor::accel::gpu_layout::GpuParams>()])
        .expect("uniform");
    let shading = ctx.upload_storage("shading", &[0u8; 64]).expect("shading");
    for (mut k, label) in [(a, "a"), (b, "b")] {
        let input = ctx.upload_storage("probe_in", &[0u8; 64]).expect("in");
        let out = ctx.create_buffer("probe_out", 96, BufferKind::Storage).expect("out");
        ctx.bind(&mut k, BINDING_PARAMS, &params).expect("bind");
        ctx.bind(&mut k, BINDING_SHADING, &shading).expect("bind");
        ctx.bind(&mut k, BINDING_ACCEL_NODES, &input).expect("bind");
        ctx.bind(&mut k, BINDING_ACCEL_INDICES, &out).expect("bind");
        ctx.dispatch(&k, &[0u8; 32], [1, 1, 1], label).expect("dispatch");
    }
    ctx.check_validation().expect("no validation errors");
}
