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
    let params: GpuParams = bytemuck::pod_read_unaligned(bytemuck::cast_slice(&fill(48)));
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

/// Each material kind and both light kinds go through their encoder
/// (`render::dispatch::upload::{material_record, light_record}`) and come back through the
/// kernels' decoders (`material_at`, `light_at`) as the fields they were made from.
#[test]
fn material_and_light_records_decode_as_encoded() {
    use arbor::render::dispatch::upload::{light_record, material_record};
    use arbor::scene::{ComplexIor, Light, Material, MaterialKind};
    use glam::Vec3;
    let Some(ctx) = common::gpu() else { return };
    let base = Material {
        specular: Vec3::new(0.1, 0.2, 0.3),
        shininess: 17.0,
        ior: 1.33,
        emission: Vec3::new(4.0, 5.0, 6.0),
        two_sided: true,
        absorption: Vec3::new(0.5, 0.25, 0.125),
        roughness: 0.4,
        texture: Some(5),
        metallic: 0.75,
        dielectric_f0: Vec3::new(0.04, 0.05, 0.06),
        specular_weight: 0.6,
        ..Material::lambert("base", Vec3::new(0.3, 0.2, 0.1))
    };
    let mut maps = base.maps;
    maps.emission = Some(3);
    maps.metal_rough = Some(1);
    maps.normal = Some(2);
    maps.normal_scale = 0.9;
    let kinds = [
        MaterialKind::Lambert,
        MaterialKind::Phong,
        MaterialKind::Mirror,
        MaterialKind::Glass,
        MaterialKind::Emissive,
        MaterialKind::Conductor,
        MaterialKind::Dielectric,
        MaterialKind::Pbr,
    ];
    let mut materials: Vec<Material> = kinds.iter().map(|&kind| Material { kind, maps, ..base.clone() }).collect();
    // A conductor with its complex index (the one above has none: Schlick's Fresnel).
    let ior = ComplexIor { eta: Vec3::new(0.2, 0.9, 1.1), k: Vec3::new(3.9, 2.4, 2.2) };
    materials.push(Material { kind: MaterialKind::Conductor, complex_ior: Some(ior), maps, ..base.clone() });
    let lights = [
        Light::Point { position: Vec3::new(1.0, 2.0, 3.0), intensity: Vec3::new(7.0, 8.0, 9.0) },
        Light::Directional { direction: Vec3::new(0.0, -1.0, 0.0), radiance: Vec3::new(0.5, 0.6, 0.7) },
    ];
    let mut shading: Vec<[f32; 4]> =
        materials.iter().flat_map(|m| material_record(m).rows().collect::<Vec<_>>()).collect();
    shading.extend(lights.iter().flat_map(|l| light_record(l).rows().collect::<Vec<_>>()));
    let params = GpuParams { material_count: materials.len() as u32, ..Default::default() };

    let mut input = Vec::new();
    for k in 0..materials.len() {
        for part in 0..3 {
            input.push([part as f32, 0.0, 0.0, k as f32]);
            input.push([0.0; 4]);
        }
    }
    let out = crate::sampling::probe(&ctx, 3, &input, &shading, &params, (0, 0));
    let bits = |f: f32| f.to_bits();
    let rgb = |v: [f32; 4]| Vec3::new(v[0], v[1], v[2]);
    for (k, m) in materials.iter().enumerate() {
        let o = &out[9 * k..9 * k + 9];
        let what = format!("material {k} ({:?})", m.kind);
        let smooth = f32::from_bits(SMOOTH_ALPHA_BITS);
        let plain = matches!(
            m.kind,
            MaterialKind::Lambert
                | MaterialKind::Phong
                | MaterialKind::Mirror
                | MaterialKind::Glass
                | MaterialKind::Emissive
        );
        // Phong scales diffuse + specular down to at most 1 a channel: 0.3 + 0.1 and so on
        // are, so its albedo comes back as made.
        assert_eq!(rgb(o[0]), m.color, "{what}: albedo");
        assert_eq!(bits(o[0][3]), m.kind as u32, "{what}: kind");
        assert_eq!(rgb(o[1]), if plain { m.specular } else { Vec3::ZERO }, "{what}: specular");
        assert_eq!(o[1][3], if plain { m.shininess } else { 0.0 }, "{what}: shininess");
        assert_eq!(rgb(o[2]), m.emission, "{what}: emission");
        assert_eq!(bits(o[2][3]), 4, "{what}: emission map (texture 3 + 1)");
        let absorbs = plain || m.kind == MaterialKind::Dielectric;
        assert_eq!(rgb(o[3]), if absorbs { m.absorption } else { Vec3::ZERO }, "{what}: absorption");
        assert_eq!(o[3][3], if m.kind == MaterialKind::Pbr { 1.5 } else { m.ior }, "{what}: ior");
        let (eta, kk) = match (m.kind, m.complex_ior) {
            (MaterialKind::Conductor, Some(c)) => (c.eta, c.k),
            _ => (Vec3::ONE, Vec3::ZERO),
        };
        assert_eq!(rgb(o[4]), eta, "{what}: eta");
        assert_eq!(rgb(o[5]), kk, "{what}: k");
        let alpha = match m.kind {
            MaterialKind::Conductor | MaterialKind::Dielectric => m.alpha(),
            MaterialKind::Pbr => m.alpha().max(smooth),
            _ => 0.0,
        };
        assert_eq!(o[4][3], alpha, "{what}: alpha");
        let schlick = if m.kind == MaterialKind::Conductor && m.complex_ior.is_none() { MAT_FLAG_SCHLICK } else { 0 };
        assert_eq!(bits(o[5][3]), MAT_FLAG_TWO_SIDED | schlick | 6 << MAT_TEXTURE_SHIFT, "{what}: flags");
        let pbr = m.kind == MaterialKind::Pbr;
        assert_eq!(rgb(o[6]), if pbr { m.dielectric_f0 } else { Vec3::ZERO }, "{what}: f0");
        assert_eq!(o[6][3], if pbr { m.metallic } else { 0.0 }, "{what}: metallic");
        assert_eq!(o[7][0], if pbr { m.specular_weight } else { 0.0 }, "{what}: specular weight");
    }

    let input: Vec<[f32; 4]> = (0..lights.len()).flat_map(|l| [[0.0, 0.0, 0.0, l as f32], [0.0; 4]]).collect();
    let out = crate::sampling::probe(&ctx, 4, &input, &shading, &params, (0, 0));
    for (l, light) in lights.iter().enumerate() {
        let (at, point, radiance) = match *light {
            Light::Point { position, intensity } => (position, 1.0, intensity),
            Light::Directional { direction, radiance } => (direction, 0.0, radiance),
        };
        assert_eq!(rgb(out[3 * l]), at, "light {l}: position or direction");
        assert_eq!(out[3 * l][3], point, "light {l}: point or directional");
        assert_eq!(rgb(out[3 * l + 1]), radiance, "light {l}: radiance");
    }
}
