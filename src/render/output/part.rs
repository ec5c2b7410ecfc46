//! Render parts: the EXR files a shard, a checkpoint or any EXR render writes, which
//! `arbor merge` assembles and `--resume` continues.
//!
//! A part is one OpenEXR layer whose data window is the rendered window inside the
//! display window of the whole image. Its channels hold the kernel's state of every
//! pixel, bit for bit, so that merging and resuming are exact:
//!
//! | channel | type | what |
//! |---|---|---|
//! | `R`, `G`, `B` | f32 | mean radiance (what a viewer shows) |
//! | `arbor.sum.R`, `.G`, `.B` | f32 | radiance summed over the samples |
//! | `arbor.sumY2` | f32 | squared luminance summed over the samples |
//! | `arbor.samples` | u32 | samples the pixel holds |
//! | `variance` | f32 | variance of the mean luminance |
//! | `Z` | f32 | depth of sample 0's camera ray (+inf on a miss) |
//! | `N.X`, `N.Y`, `N.Z` | f32 | shading normal there |
//! | `albedo.R`, `.G`, `.B` | f32 | albedo there |
//! | `arbor.prim`, `arbor.nodes`, `arbor.tests` | u32 | primitive hit (u32::MAX: none), nodes visited, primitives tested |
//! | `arbor.rays` | u32 | rays traced for the pixel |
//!
//! The header attribute `arbor.part` (text) holds `key=value` lines: `version`, `hash`
//! (of the scene and every setting that changes pixels: [`settings_hash`]), `scene`,
//! `integrator`, `seed`, `sampleFirst`, `sampleCount`, `sppTotal` (the samples per
//! pixel a sample shard is part of, else 0) and `shard` (for example `3/8 tiles`, empty when not a
//! shard). One attribute, because the EXR library keeps attributes in a hash map,
//! whose order would make the bytes of a rerun differ.

#![forbid(unsafe_code)]

use std::collections::HashMap;
use std::path::Path;

use exr::prelude::*;

use crate::error::{Error, Result};
use crate::render::{Crop, Frame, RenderSettings};
use crate::scene::{Light, Scene};

/// What a part is: its place in the image and the samples it holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PartInfo {
    /// Size of the whole image (the EXR display window).
    pub width: u32,
    pub height: u32,
    /// The window the part holds (the EXR data window).
    pub crop: Crop,
    /// The sample range the part was asked for: `first_sample..first_sample + samples`.
    pub first_sample: u32,
    pub samples: u32,
    /// Samples per pixel of the whole render a sample shard is part of (0: not a
    /// sample shard).
    pub spp_total: u32,
    pub seed: u32,
    pub integrator: String,
    /// [`settings_hash`] as 16 hex digits.
    pub hash: String,
    pub version: String,
    pub scene: String,
    /// `I/N tiles` or `I/N samples`; empty when not a shard.
    pub shard: String,
}

impl PartInfo {
    /// The part a render of `scene` with `settings` writes.
    pub fn new(scene: &Scene, settings: &RenderSettings, spp_total: u32, shard: String) -> PartInfo {
        PartInfo {
            width: settings.width,
            height: settings.height,
            crop: settings.window(),
            first_sample: settings.first_sample,
            samples: settings.spp,
            spp_total,
            seed: settings.seed,
            integrator: settings.integrator.name().to_string(),
            hash: format!("{:016x}", settings_hash(scene, settings)),
            version: env!("CARGO_PKG_VERSION").to_string(),
            scene: scene.name.clone(),
            shard,
        }
    }

    /// The `key=value` lines of the header attribute [`PART_ATTR`].
    pub fn header_text(&self) -> String {
        let one_line = |s: &str| s.replace(['\n', '\r'], " ");
        format!(
            "version={}\nhash={}\nscene={}\nintegrator={}\nseed={}\nsampleFirst={}\nsampleCount={}\nsppTotal={}\nshard={}\n",
            one_line(&self.version),
            self.hash,
            one_line(&self.scene),
            self.integrator,
            self.seed,
            self.first_sample,
            self.samples,
            self.spp_total,
            one_line(&self.shard)
        )
    }

    /// `first..end` of the samples asked for.
    pub fn sample_range(&self) -> std::ops::Range<u32> {
        self.first_sample..self.first_sample.saturating_add(self.samples)
    }
}

/// FNV-1a, 64 bits: a hash that is the same on every machine and every build, unlike
/// the standard library's.
#[derive(Debug, Clone, Copy)]
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 ^= u64::from(x);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.u32(v.to_bits());
    }
    fn vec3(&mut self, v: glam::Vec3) {
        v.to_array().into_iter().for_each(|x| self.f32(x));
    }
    fn str(&mut self, s: &str) {
        self.u32(s.len() as u32);
        self.bytes(s.as_bytes());
    }
}

/// A scene's (or a prototype's) triangle geometry: positions, normals, UVs, colours, triangles
/// and their materials, each list after its length.
fn hash_geometry(h: &mut Fnv, g: &Scene) {
    h.u32(g.positions.len() as u32);
    g.positions.iter().for_each(|&p| h.vec3(p));
    h.u32(g.normals.len() as u32);
    g.normals.iter().for_each(|&n| h.vec3(n));
    h.u32(g.uvs.len() as u32);
    g.uvs.iter().for_each(|uv| {
        h.f32(uv.x);
        h.f32(uv.y)
    });
    h.u32(g.colors.len() as u32);
    g.colors.iter().for_each(|c| c.to_array().iter().for_each(|&x| h.f32(x)));
    h.u32(g.triangles.len() as u32);
    g.triangles.iter().flatten().for_each(|&i| h.u32(i));
    g.tri_material.iter().for_each(|&m| h.u32(m));
}

/// A hash of everything that decides a pixel's value: the program version, the
/// scene's geometry, materials, textures, lights, environment and camera, and the
/// settings (image size, integrator, seed, depth, MIS, ray test, structure). Not the
/// window, the sample range, the traversal or the kernel variant: parts that differ
/// only in those belong to one image.
pub fn settings_hash(scene: &Scene, s: &RenderSettings) -> u64 {
    let mut h = Fnv::new();
    h.str(env!("CARGO_PKG_VERSION"));
    hash_geometry(&mut h, scene);
    if let Some(inst) = &scene.instancing {
        h.str("instancing");
        for p in &inst.prototypes {
            hash_geometry(&mut h, &p.geometry);
        }
        h.u32(inst.instances.len() as u32);
        for i in &inst.instances {
            h.u32(i.prototype);
            i.transform.to_cols_array().iter().for_each(|&v| h.f32(v));
        }
    }
    h.u32(scene.spheres.len() as u32);
    for sp in &scene.spheres {
        h.vec3(sp.center);
        h.f32(sp.radius);
        h.u32(sp.material);
    }
    h.u32(scene.materials.len() as u32);
    for m in &scene.materials {
        h.str(&format!("{:?}", m.kind));
        for v in [m.color, m.specular, m.emission, m.absorption] {
            h.vec3(v);
        }
        h.f32(m.shininess);
        h.f32(m.ior);
        h.u32(u32::from(m.two_sided));
        h.u32(m.texture.map_or(u32::MAX, |t| t));
        let c = m.complex_ior.unwrap_or(crate::scene::ComplexIor { eta: glam::Vec3::ZERO, k: glam::Vec3::ZERO });
        for v in [c.eta, c.k, m.dielectric_f0] {
            h.vec3(v);
        }
        for v in [m.roughness, m.metallic, m.specular_weight, m.maps.normal_scale] {
            h.f32(v);
        }
        for t in [m.maps.metal_rough, m.maps.normal, m.maps.emission] {
            h.u32(t.map_or(u32::MAX, |t| t));
        }
    }
    h.u32(scene.textures.len() as u32);
    for t in &scene.textures {
        h.u32(t.width);
        h.u32(t.height);
        t.wrap.iter().for_each(|w| h.u32(*w as u32));
        t.texels.iter().for_each(|px| h.bytes(px));
    }
    h.u32(scene.lights.len() as u32);
    for l in &scene.lights {
        match *l {
            Light::Directional { direction, radiance } => {
                h.u32(0);
                h.vec3(direction);
                h.vec3(radiance);
            }
            Light::Point { position, intensity } => {
                h.u32(1);
                h.vec3(position);
                h.vec3(intensity);
            }
        }
    }
    match &scene.environment {
        None => h.u32(0),
        Some(e) => {
            h.u32(1);
            h.u32(e.width);
            h.u32(e.height);
            h.f32(e.rotation);
            h.f32(e.intensity);
            e.texels.iter().flatten().for_each(|&x| h.f32(x));
        }
    }
    let c = &scene.camera;
    for v in [c.eye, c.look_at, c.up] {
        h.vec3(v);
    }
    h.f32(c.vfov);
    h.vec3(scene.background);
    h.f32(scene.ambient);
    h.u32(scene.max_depth);
    h.u32(s.width);
    h.u32(s.height);
    h.str(s.integrator.name());
    h.u32(s.seed);
    h.u32(s.max_depth.unwrap_or(0));
    h.u32(s.mis.spec());
    h.u32(s.intersect.spec());
    h.str(s.accel.name());
    if s.integrator == crate::render::Integrator::Sppm {
        // Tiles of one sppm image share photons and radii only with the same settings
        h.u32(s.sppm.photons_for(s.width, s.height));
        h.f32(s.sppm.radius.unwrap_or(0.0));
        h.str(s.sppm.map.name());
    }
    h.0
}

/// The header attribute that holds a part's description.
pub const PART_ATTR: &str = "arbor.part";

fn text(s: &str) -> Text {
    // Text holds bytes; anything but printable ASCII and line ends becomes '?'.
    let clean: String =
        s.chars().map(|c| if c == '\n' || (c.is_ascii() && !c.is_ascii_control()) { c } else { '?' }).collect();
    Text::new_or_none(&clean).unwrap_or_else(|| Text::new_or_none("?").expect("ascii text"))
}

/// The EXR bytes of a part: `frame` (of the part's window) with `info`'s header.
pub fn encode(info: &PartInfo, frame: &Frame) -> Result<Vec<u8>> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    debug_assert_eq!((frame.width, frame.height), (info.crop.width(), info.crop.height()));
    let f32s = |name: &str, v: Vec<f32>| AnyChannel::new(name, FlatSamples::F32(v));
    let u32s = |name: &str, v: Vec<u32>| AnyChannel::new(name, FlatSamples::U32(v));
    let rgb = |k: usize, v: &[[f32; 3]]| v.iter().map(|p| p[k]).collect::<Vec<f32>>();
    let mut list: exr::prelude::SmallVec<[AnyChannel<FlatSamples>; 4]> = Default::default();
    for (k, c) in ["R", "G", "B"].into_iter().enumerate() {
        list.push(f32s(c, rgb(k, &frame.radiance)));
        list.push(f32s(&format!("arbor.sum.{c}"), rgb(k, &frame.sum)));
        list.push(f32s(&format!("albedo.{c}"), rgb(k, &frame.albedo)));
    }
    for (k, c) in ["X", "Y", "Z"].into_iter().enumerate() {
        list.push(f32s(&format!("N.{c}"), rgb(k, &frame.normal)));
    }
    list.push(f32s("arbor.sumY2", frame.sum_y2.clone()));
    list.push(f32s("variance", frame.variance.clone()));
    list.push(f32s("Z", frame.depth.clone()));
    list.push(u32s("arbor.samples", frame.samples.clone()));
    list.push(u32s("arbor.prim", frame.prim.clone()));
    list.push(u32s("arbor.nodes", frame.nodes.clone()));
    list.push(u32s("arbor.tests", frame.tests.clone()));
    list.push(u32s("arbor.rays", frame.rays.clone()));

    let mut attrs = LayerAttributes {
        layer_position: Vec2(info.crop.x0 as i32, info.crop.y0 as i32),
        software_name: Some(text(&format!("arbor {}", info.version))),
        ..Default::default()
    };
    // One text attribute of `key=value` lines: the decoder's attribute map is a
    // HashMap, whose order (and so the file's bytes) would change from run to run.
    let mut other: HashMap<Text, AttributeValue> = HashMap::new();
    other.insert(text(PART_ATTR), AttributeValue::Text(text(&info.header_text())));
    attrs.other = other;
    let layer = Layer::new((w, h), attrs, Encoding::SMALL_LOSSLESS, AnyChannels::sort(list));
    let mut image = Image::from_layer(layer);
    image.attributes.display_window = IntegerBounds::new(Vec2(0, 0), Vec2(info.width as usize, info.height as usize));
    let mut out = std::io::Cursor::new(Vec::new());
    image.write().to_buffered(&mut out).map_err(|e| Error::Failed(format!("cannot encode the EXR part: {e}")))?;
    Ok(out.into_inner())
}

/// Reads a part written by [`encode`]: its header and its pixels as a frame of its
/// window. Any other EXR, a truncated or corrupt file, or a missing channel or
/// attribute is an error naming the file.
pub fn read(path: &Path) -> Result<(PartInfo, Frame)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    decode(&bytes).map_err(|why| Error::invalid(path, why))
}

fn decode(bytes: &[u8]) -> std::result::Result<(PartInfo, Frame), String> {
    // The decoder is not trusted to stay calm on every corrupt file: a panic in it is a
    // corrupt part too.
    let image = std::panic::catch_unwind(|| {
        exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .non_parallel()
            .from_buffered(std::io::Cursor::new(bytes))
    })
    .map_err(|_| "not a readable EXR file (the decoder failed)".to_string())?
    .map_err(|e| format!("not a readable EXR file ({e})"))?;
    if image.layer_data.len() != 1 {
        return Err(format!("an arbor part has one layer, this file has {}", image.layer_data.len()));
    }
    let layer = &image.layer_data[0];
    let lines = match layer.attributes.other.get(&text(PART_ATTR)) {
        Some(AttributeValue::Text(t)) => t.to_string(),
        _ => return Err(format!("not an arbor part (no text attribute {PART_ATTR})")),
    };
    let fields: HashMap<&str, &str> = lines.lines().filter_map(|l| l.split_once('=')).collect();
    let text_attr = |k: &str| {
        fields.get(k).map(|v| v.to_string()).ok_or_else(|| format!("not an arbor part (no {k} in {PART_ATTR})"))
    };
    let int_attr = |k: &str| {
        fields
            .get(k)
            .and_then(|v| v.parse::<u32>().ok())
            .ok_or_else(|| format!("not an arbor part (no number {k} in {PART_ATTR})"))
    };
    let display = image.attributes.display_window;
    let pos = layer.attributes.layer_position;
    let (w, h) = (layer.size.0, layer.size.1);
    if display.position != Vec2(0, 0) || pos.0 < 0 || pos.1 < 0 {
        return Err("the data window is not inside a display window at the origin".into());
    }
    let crop = Crop { x0: pos.0 as u32, x1: pos.0 as u32 + w as u32, y0: pos.1 as u32, y1: pos.1 as u32 + h as u32 };
    let (dw, dh) = (display.size.0 as u32, display.size.1 as u32);
    crop.check(dw, dh).map_err(|_| "the data window is not inside the display window".to_string())?;
    let info = PartInfo {
        width: dw,
        height: dh,
        crop,
        first_sample: int_attr("sampleFirst")?,
        samples: int_attr("sampleCount")?,
        spp_total: int_attr("sppTotal")?,
        seed: int_attr("seed")?,
        integrator: text_attr("integrator")?,
        hash: text_attr("hash")?,
        version: text_attr("version")?,
        scene: text_attr("scene")?,
        shard: text_attr("shard")?,
    };
    let n = w * h;
    let channel = |name: &str| {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name == text(name))
            .ok_or_else(|| format!("not an arbor part (no channel {name})"))
    };
    let f32s = |name: &str| -> std::result::Result<Vec<f32>, String> {
        match &channel(name)?.sample_data {
            FlatSamples::F32(v) if v.len() == n => Ok(v.clone()),
            _ => Err(format!("channel {name} is not {n} f32 samples")),
        }
    };
    let u32s = |name: &str| -> std::result::Result<Vec<u32>, String> {
        match &channel(name)?.sample_data {
            FlatSamples::U32(v) if v.len() == n => Ok(v.clone()),
            _ => Err(format!("channel {name} is not {n} u32 samples")),
        }
    };
    let rgb = |names: [&str; 3]| -> std::result::Result<Vec<[f32; 3]>, String> {
        let [a, b, c] = [f32s(names[0])?, f32s(names[1])?, f32s(names[2])?];
        Ok((0..n).map(|k| [a[k], b[k], c[k]]).collect())
    };
    let frame = Frame {
        width: w as u32,
        height: h as u32,
        radiance: rgb(["R", "G", "B"])?,
        depth: f32s("Z")?,
        normal: rgb(["N.X", "N.Y", "N.Z"])?,
        prim: u32s("arbor.prim")?,
        nodes: u32s("arbor.nodes")?,
        tests: u32s("arbor.tests")?,
        rays: u32s("arbor.rays")?,
        albedo: rgb(["albedo.R", "albedo.G", "albedo.B"])?,
        variance: f32s("variance")?,
        samples: u32s("arbor.samples")?,
        sum: rgb(["arbor.sum.R", "arbor.sum.G", "arbor.sum.B"])?,
        sum_y2: f32s("arbor.sumY2")?,
    };
    if let Some(k) = frame.samples.iter().position(|&s| s > info.samples) {
        return Err(format!("pixel {k} holds {} samples, more than the part's {}", frame.samples[k], info.samples));
    }
    Ok((info, frame))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(w: u32, h: u32) -> Frame {
        let mut f = Frame::new(w, h).expect("frame");
        for k in 0..(w * h) as usize {
            f.sum[k] = [k as f32 * 0.5, 1.0 / (k as f32 + 1.0), 3.0];
            f.samples[k] = 3;
            f.sum_y2[k] = 2.0 + k as f32;
            f.prim[k] = if k % 2 == 0 { k as u32 } else { u32::MAX };
            f.depth[k] = if k % 2 == 0 { 1.5 } else { f32::INFINITY };
            f.rays[k] = 7 * k as u32;
            f.finish_pixel(k);
        }
        f
    }

    fn info() -> PartInfo {
        PartInfo {
            width: 10,
            height: 8,
            crop: Crop { x0: 2, x1: 7, y0: 1, y1: 5 },
            first_sample: 4,
            samples: 3,
            spp_total: 12,
            seed: 9,
            integrator: "path".into(),
            hash: "0123456789abcdef".into(),
            version: "0.1.0".into(),
            scene: "test".into(),
            shard: "2/4 samples".into(),
        }
    }

    #[test]
    fn parts_round_trip_bit_for_bit() {
        let (i, f) = (info(), frame(5, 4));
        let bytes = encode(&i, &f).expect("encode");
        assert_eq!(bytes, encode(&i, &f).expect("encode"), "the same part gives the same bytes");
        let (i2, f2) = decode(&bytes).expect("decode");
        assert_eq!(i, i2);
        assert_eq!(f.sum, f2.sum);
        assert_eq!(f.radiance, f2.radiance);
        assert_eq!(f.samples, f2.samples);
        assert_eq!(f.prim, f2.prim);
        assert_eq!(f.rays, f2.rays);
        assert_eq!(f.depth, f2.depth);
        assert_eq!(f.variance, f2.variance);
    }

    #[test]
    fn truncated_and_foreign_files_are_errors() {
        let bytes = encode(&info(), &frame(5, 4)).expect("encode");
        for cut in [0, 4, 40, bytes.len() / 2, bytes.len() - 1] {
            assert!(decode(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        let mut flipped = bytes.clone();
        let k = flipped.len() - 20;
        flipped[k] ^= 0xff;
        let _ = decode(&flipped); // an error or other values, never a panic
        let mut png = Vec::new();
        crate::render::output::encode_image(crate::render::output::Format::Exr, 2, 2, &[[0.0; 3]; 4])
            .map(|b| png = b)
            .expect("plain exr");
        let err = decode(&png).expect_err("a plain EXR is no part");
        assert!(err.contains("not an arbor part"), "{err}");
    }

    #[test]
    fn the_hash_follows_pixels_not_windows() {
        let scene = Scene::load("builtin:spheres").expect("scene");
        let base = RenderSettings::for_size(64, 48);
        let h = settings_hash(&scene, &base);
        let mut s = base.clone();
        s.crop = Some(Crop { x0: 0, x1: 10, y0: 0, y1: 10 });
        s.first_sample = 5;
        s.spp = 9;
        assert_eq!(settings_hash(&scene, &s), h);
        let mut s = base.clone();
        s.seed = 1;
        assert_ne!(settings_hash(&scene, &s), h);
        let mut s = base;
        s.width = 65;
        assert_ne!(settings_hash(&scene, &s), h);
    }
}
