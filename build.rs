//! Compiles every `shaders/*.comp` to SPIR-V with shaderc and embeds it, and generates
//! the straight-line treelet programme (`src/accel/bvh/dp_gen.rs`) for Rust and GLSL.
//!
//! `trace.comp` is compiled once per (structure, geometry) variant, and once more per
//! variant as the ray-batch kernel (`rays_*`, `RAY_BATCH`): a scene without
//! spheres gets a kernel that declares no sphere buffer at all, one without triangles
//! declares no mesh buffers; brute force is compiled once per unroll factor
//! (`trace_none_tris_x8`, ...); `build_bounds.comp` gets the same geometry variants. Every
//! other `.comp` is compiled once. Binding numbers and
//! tunables come from `src/gpu/bindings.rs` as macros. On a shader error the build
//! fails with `file:line: message` from the compiler. Variants compile on every core.
//!
//! Each kernel's compile time goes to `OUT_DIR/compile_ms.tsv`.
//!
//! For kernel experiments only: `ARBOR_DEV_KERNELS=trace_bvh_tris,...` compiles just the
//! kernels whose names contain one of the given strings; the others are then missing
//! at run time (an error naming them), so never build a release or run tests with it.

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

#[allow(dead_code)]
mod bindings {
    include!("src/gpu/bindings.rs");
}

#[path = "src/accel/bvh/dp_gen.rs"]
mod dp_gen;

/// The include name under which kernels get the generated treelet programme.
const DP_INCLUDE: &str = "generated/treelet_dp.glsl";

/// One kernel to compile: (kernel name, file, source, extra macro definitions).
type Job = (String, PathBuf, Arc<String>, Vec<(String, String)>);
/// A compile's outcome: SPIR-V bytes or the compiler's message.
type Compiled = Result<Vec<u8>, String>;

/// Geometry variants of the trace kernel: (suffix, HAS_TRIANGLES, HAS_SPHERES).
const GEOMETRY: &[(&str, u32, u32)] = &[("tris", 1, 0), ("spheres", 0, 1), ("all", 1, 1)];

fn main() {
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let shader_dir = root.join("shaders");
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    println!("cargo:rerun-if-changed=src/gpu/bindings.rs");
    println!("cargo:rerun-if-changed=shaders");
    println!("cargo:rerun-if-changed=src/accel/bvh/dp_gen.rs");
    std::fs::write(out_dir.join("treelet_dp.rs"), dp_gen::rust()).expect("write treelet_dp.rs to OUT_DIR");
    let dp_glsl = dp_gen::glsl();

    let opened: Arc<Mutex<BTreeSet<PathBuf>>> = Arc::default();
    let mut table =
        String::from("/// (name, SPIR-V bytes) of every compiled kernel.\npub const SHADERS: &[(&str, &[u8])] = &[\n");
    let mut failures = Vec::new();
    println!("cargo:rerun-if-env-changed=ARBOR_DEV_KERNELS");
    let only: Vec<String> = std::env::var("ARBOR_DEV_KERNELS")
        .map(|v| v.split(',').filter(|s| !s.is_empty()).map(str::to_string).collect())
        .unwrap_or_default();

    let mut comps: Vec<PathBuf> =
        read_dir_sorted(&shader_dir).into_iter().filter(|p| p.extension().is_some_and(|e| e == "comp")).collect();
    comps.sort();
    let accels: Vec<String> = read_dir_sorted(&shader_dir.join("accel"))
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "glsl"))
        .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .collect();

    // (kernel name, file, source, defines) of every variant, in table order.
    let mut jobs: Vec<Job> = Vec::new();
    for comp in &comps {
        let stem = comp.file_stem().unwrap_or_default().to_string_lossy().into_owned();
        let source = match std::fs::read_to_string(comp) {
            Ok(s) => Arc::new(s),
            Err(e) => {
                failures.push(format!("{}: {e}", comp.display()));
                continue;
            }
        };
        opened.lock().expect("include set").insert(comp.clone());
        let mut variants: Vec<(String, Vec<(String, String)>)> = Vec::new();
        if stem == "trace" {
            for accel in &accels {
                // Brute force once per unroll factor (`_x8`, `_x32`; the plain loop has
                // no suffix), each module holding only its own loop.
                let unrolls: &[u32] = if accel == "none" { &bindings::BRUTE_UNROLL_FACTORS } else { &[1] };
                for &unroll in unrolls {
                    let suffix = if unroll == 1 { String::new() } else { format!("_x{unroll}") };
                    // One module per integrator (bindings::TRACE_ENTRIES).
                    for (geo, tris, spheres) in GEOMETRY {
                        for (entry, value) in bindings::TRACE_ENTRIES {
                            variants.push((
                                format!("trace_{accel}_{geo}{suffix}.{entry}"),
                                vec![
                                    (format!("ACCEL_{}", accel.to_uppercase()), "1".into()),
                                    ("HAS_TRIANGLES".into(), tris.to_string()),
                                    ("HAS_SPHERES".into(), spheres.to_string()),
                                    ("BRUTE_UNROLL".into(), unroll.to_string()),
                                    ("TRACE_ENTRY".into(), value.to_string()),
                                ],
                            ));
                        }
                    }
                    // Ray batches (src/render/rays.rs): the same traversal, rays read
                    // from a buffer; flat scenes only.
                    for (geo, tris, spheres) in GEOMETRY {
                        variants.push((
                            format!("rays_{accel}_{geo}{suffix}"),
                            vec![
                                (format!("ACCEL_{}", accel.to_uppercase()), "1".into()),
                                ("HAS_TRIANGLES".into(), tris.to_string()),
                                ("HAS_SPHERES".into(), spheres.to_string()),
                                ("RAY_BATCH".into(), "1".into()),
                                ("BRUTE_UNROLL".into(), unroll.to_string()),
                            ],
                        ));
                    }
                }
                // Instanced scenes (src/accel/instance.rs): every structure but brute
                // force as the bottom level; instances are meshes, so never spheres only.
                if accel != "none" {
                    for (geo, tris, spheres) in GEOMETRY.iter().filter(|g| g.1 == 1) {
                        for (entry, value) in bindings::TRACE_ENTRIES {
                            variants.push((
                                format!("trace_inst_{accel}_{geo}.{entry}"),
                                vec![
                                    (format!("ACCEL_{}", accel.to_uppercase()), "1".into()),
                                    ("HAS_TRIANGLES".into(), tris.to_string()),
                                    ("HAS_SPHERES".into(), spheres.to_string()),
                                    ("HAS_INSTANCES".into(), "1".into()),
                                    ("TRACE_ENTRY".into(), value.to_string()),
                                ],
                            ));
                        }
                    }
                }
            }
        } else if stem == "build_bounds" {
            for (geo, tris, spheres) in GEOMETRY {
                variants.push((
                    format!("build_bounds_{geo}"),
                    vec![("HAS_TRIANGLES".into(), tris.to_string()), ("HAS_SPHERES".into(), spheres.to_string())],
                ));
            }
        } else {
            variants.push((stem.clone(), Vec::new()));
        }
        for (name, defines) in variants {
            if only.is_empty() || only.iter().any(|o| name.contains(o.as_str())) {
                jobs.push((name, comp.clone(), Arc::clone(&source), defines));
            }
        }
    }

    // Compile on every core, each thread with its own compiler, taking jobs in turn:
    // the longest first (the unrolled brute-force loops, then the trace kernels), so
    // that no long job starts last while the other cores idle.
    let rank = |(name, _, _, defines): &Job| {
        let unroll = defines.iter().find(|(k, _)| k == "BRUTE_UNROLL").map_or(1, |(_, v)| v.parse().unwrap_or(1));
        (unroll, u32::from(name.starts_with("trace_")))
    };
    let mut order: Vec<usize> = (0..jobs.len()).collect();
    order.sort_by_key(|&k| std::cmp::Reverse(rank(&jobs[k])));
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<Mutex<Option<(Compiled, f64)>>> = jobs.iter().map(|_| Mutex::new(None)).collect();
    let threads = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1).min(jobs.len().max(1));
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                let compiler = shaderc::Compiler::new().expect("shaderc compiler");
                while let Some(&k) = order.get(next.fetch_add(1, std::sync::atomic::Ordering::Relaxed)) {
                    let (_, file, source, defines) = &jobs[k];
                    let started = std::time::Instant::now();
                    let r = compile(&compiler, &shader_dir, file, source, defines, &opened, &dp_glsl);
                    *results[k].lock().expect("result slot") = Some((r, started.elapsed().as_secs_f64() * 1e3));
                }
            });
        }
    });
    // How long each kernel took (OUT_DIR/compile_ms.tsv), to see what a build spends.
    let mut times = String::new();
    for ((name, ..), result) in jobs.iter().zip(results) {
        let result = result.into_inner().expect("result slot").map(|(r, ms)| {
            let _ = writeln!(times, "{name}\t{ms:.0}");
            r
        });
        match result {
            Some(Ok(words)) => {
                let path = out_dir.join(format!("{name}.spv"));
                std::fs::write(&path, words).expect("write SPIR-V to OUT_DIR");
                let _ = writeln!(table, "    ({name:?}, include_bytes!({:?})),", path.display().to_string());
            }
            Some(Err(msg)) => failures.push(format!("variant {name}:\n{msg}")),
            None => failures.push(format!("variant {name}: not compiled")),
        }
    }
    table.push_str("];\n");
    for f in opened.lock().expect("include set").iter() {
        println!("cargo:rerun-if-changed={}", f.display());
    }
    if !failures.is_empty() {
        eprintln!("shader compilation failed:\n{}", failures.join("\n"));
        std::process::exit(1);
    }
    std::fs::write(out_dir.join("shaders.rs"), table).expect("write shaders.rs");
    std::fs::write(out_dir.join("compile_ms.tsv"), times).expect("write compile_ms.tsv");
}

fn read_dir_sorted(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> =
        std::fs::read_dir(dir).map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect()).unwrap_or_default();
    v.sort();
    v
}

fn compile(
    compiler: &shaderc::Compiler,
    shader_dir: &Path,
    file: &Path,
    source: &str,
    defines: &[(String, String)],
    opened: &Arc<Mutex<BTreeSet<PathBuf>>>,
    dp_glsl: &str,
) -> Result<Vec<u8>, String> {
    let mut opts = shaderc::CompileOptions::new().ok_or("shaderc options")?;
    opts.set_target_env(shaderc::TargetEnv::Vulkan, shaderc::EnvVersion::Vulkan1_2 as u32);
    opts.set_target_spirv(shaderc::SpirvVersion::V1_5);
    // The unrolled brute-force loops (lavapipe only: a driver without a loop limit
    // always gets the plain loop) unoptimised: optimised, they were 12 of the 29 MB of
    // SPIR-V and half of this script's run (123 s cold, 66 s without); unoptimised,
    // lavapipe creates their pipelines sooner and traces them as fast.
    let unrolled = defines.iter().any(|(k, v)| k == "BRUTE_UNROLL" && v != "1");
    opts.set_optimization_level(if unrolled {
        shaderc::OptimizationLevel::Zero
    } else {
        shaderc::OptimizationLevel::Performance
    });
    opts.set_warnings_as_errors();
    for (k, v) in bindings::SHADER_DEFINES {
        // Past i32::MAX a decimal literal needs its `u` (0xffffffff is no int).
        let text = if *v > i32::MAX as u32 { format!("{v}u") } else { v.to_string() };
        opts.add_macro_definition(k, Some(&text));
    }
    for (k, v) in defines {
        opts.add_macro_definition(k, Some(v));
    }
    let dir = shader_dir.to_path_buf();
    let opened_cb = Arc::clone(opened);
    let dp_glsl = dp_glsl.to_string();
    opts.set_include_callback(move |requested, _ty, requester, _depth| {
        if requested == DP_INCLUDE {
            return Ok(shaderc::ResolvedInclude { resolved_name: DP_INCLUDE.into(), content: dp_glsl.clone() });
        }
        // Includes resolve against shaders/ first, then against the including file.
        let candidates = [dir.join(requested), Path::new(requester).parent().unwrap_or(&dir).join(requested)];
        for c in candidates {
            if let Ok(content) = std::fs::read_to_string(&c) {
                if let Ok(mut set) = opened_cb.lock() {
                    set.insert(c.clone());
                }
                return Ok(shaderc::ResolvedInclude { resolved_name: c.display().to_string(), content });
            }
        }
        Err(format!("cannot find include \"{requested}\" (looked in {})", dir.display()))
    });
    let name = file.display().to_string();
    compiler
        .compile_into_spirv(source, shaderc::ShaderKind::Compute, &name, "main", Some(&opts))
        .map(|a| a.as_binary_u8().to_vec())
        .map_err(|e| e.to_string())
}
