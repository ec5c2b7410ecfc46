//! Proves on the device that src/accel/gpu_layout.rs and shaders/common/layout.glsl
//! agree: a probe kernel reads every struct through its GLSL declaration and writes
//! the words back in Rust declaration order.

use crate::common;

use arbor::accel::gpu_layout::*;
use arbor::gpu::bindings::*;
use arbor::gpu::{spirv, BindingDesc, BindingKind, BufferKind};

fn words<T: bytemuck::Pod>(v: &T) -> Vec<u32> {
    bytemuck::cast_slice::<u8, u32>(bytemuck::bytes_of(v)).to_vec()
}

#[test]
fn rust_and_glsl_layouts_agree_on_the_device() {
    let Some(ctx) = common::gpu() else { return };
    // Distinct bit patterns everywhere.
    let mut next = 1u32;
    let mut fill = |n: usize| -> Vec<u32> {
        (0..n)
            .map(|_| {
                next += 1;
                0x3f80_0000 + next // small positive floats, never NaN
            })
            .collect()
    };
    let params: GpuParams = bytemuck::pod_read_unaligned(bytemuck::cast_slice(&fill(44)));
    let dispatch: GpuDispatch = bytemuck::pod_read_unaligned(bytemuck::cast_slice(&fill(16)));
    let vertices: Vec<GpuVertex> =
        (0..2).map(|_| bytemuck::pod_read_unaligned(bytemuck::cast_slice(&fill(8)))).collect();
    let triangles: Vec<GpuTriangle> =
        (0..2).map(|_| bytemuck::pod_read_unaligned(bytemuck::cast_slice(&fill(4)))).collect();
    let spheres: Vec<GpuSphere> =
        (0..2).map(|_| bytemuck::pod_read_unaligned(bytemuck::cast_slice(&fill(8)))).collect();
    let material: GpuMaterial = bytemuck::pod_read_unaligned(bytemuck::cast_slice(&fill(16)));
    let light: GpuLight = bytemuck::pod_read_unaligned(bytemuck::cast_slice(&fill(8)));
    let pixels: Vec<GpuPixel> = (0..2).map(|_| bytemuck::pod_read_unaligned(bytemuck::cast_slice(&fill(16)))).collect();
    let rays: Vec<GpuRay> = (0..2).map(|_| bytemuck::pod_read_unaligned(bytemuck::cast_slice(&fill(8)))).collect();

    let mut expected = words(&params);
    expected.extend(words(&dispatch));
    for v in &vertices {
        expected.extend(words(v));
    }
    for t in &triangles {
        expected.extend(words(t));
    }
    for s in &spheres {
        expected.extend(words(s));
    }
    expected.extend(words(&material));
    expected.extend(words(&light));
    for p in &pixels {
        expected.extend(words(p));
    }
    for r in &rays {
        expected.extend(words(r));
    }

    let bindings = [
        BindingDesc { binding: BINDING_PARAMS, kind: BindingKind::Uniform, name: "params" },
        BindingDesc { binding: BINDING_VERTICES, kind: BindingKind::Texel, name: "vertices" },
        BindingDesc { binding: BINDING_TRIANGLES, kind: BindingKind::Texel, name: "triangles" },
        BindingDesc { binding: BINDING_SPHERES, kind: BindingKind::Texel, name: "spheres" },
        BindingDesc { binding: BINDING_SHADING, kind: BindingKind::Texel, name: "shading" },
        BindingDesc { binding: BINDING_PIXELS, kind: BindingKind::Storage, name: "pixels" },
        BindingDesc { binding: BINDING_ACCEL_NODES, kind: BindingKind::Storage, name: "probe_out" },
        BindingDesc { binding: BINDING_RAYS, kind: BindingKind::Texel, name: "rays" },
    ];
    let spv = spirv::get("layout_probe").expect("probe kernel compiled");
    let mut k = ctx.create_kernel("layout_probe", spv, &bindings, &[], 0).expect("kernel");
    let u = ctx.upload_uniform("params", bytemuck::bytes_of(&params)).expect("u");
    let vb = ctx.upload_storage("vertices", bytemuck::cast_slice(&vertices)).expect("v");
    let tb = ctx.upload_storage("triangles", bytemuck::cast_slice(&triangles)).expect("t");
    let sb = ctx.upload_storage("spheres", bytemuck::cast_slice(&spheres)).expect("s");
    let mut shading = bytemuck::bytes_of(&material).to_vec();
    shading.extend_from_slice(bytemuck::bytes_of(&light));
    let shb = ctx.upload_storage("shading", &shading).expect("sh");
    // The pixel buffer opens with the dispatch header.
    let mut pixel_bytes = bytemuck::bytes_of(&dispatch).to_vec();
    pixel_bytes.extend_from_slice(bytemuck::cast_slice(&pixels));
    let pb = ctx.upload_storage("pixels", &pixel_bytes).expect("p");
    let rb = ctx.upload_storage("rays", bytemuck::cast_slice(&rays)).expect("r");
    let out = ctx.create_buffer("probe_out", (expected.len() * 4) as u64, BufferKind::Storage).expect("out");
    ctx.fill_zero(&out).expect("clear");
    ctx.bind(&mut k, BINDING_PARAMS, &u).expect("bind");
    ctx.bind(&mut k, BINDING_VERTICES, &vb).expect("bind");
    ctx.bind(&mut k, BINDING_TRIANGLES, &tb).expect("bind");
    ctx.bind(&mut k, BINDING_SPHERES, &sb).expect("bind");
    ctx.bind(&mut k, BINDING_SHADING, &shb).expect("bind");
    ctx.bind(&mut k, BINDING_PIXELS, &pb).expect("bind");
    ctx.bind(&mut k, BINDING_ACCEL_NODES, &out).expect("bind");
    ctx.bind(&mut k, BINDING_RAYS, &rb).expect("bind");
    ctx.dispatch(&k, &[], [1, 1, 1], "layout probe").expect("dispatch");
    let back = ctx.read_storage(&out, 0, (expected.len() * 4) as u64).expect("read");
    let got: &[u32] = bytemuck::cast_slice(&back);
    for (i, (g, e)) in got.iter().zip(&expected).enumerate() {
        assert_eq!(g, e, "word {i} differs: the GLSL and Rust layouts disagree");
    }
    ctx.check_validation().expect("no validation errors");
}
