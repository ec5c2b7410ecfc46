//! Stochastic progressive photon mapping (`--integrator sppm`; Hachisuka & Jensen
//! 2009, as pbrt-v4 defines it; docs/caustics.md): the light the path tracer cannot
//! find, from a point light through glass or off a mirror onto a diffuse surface.
//!
//! Each iteration runs four steps on the device, over the window's pixels, all held at
//! once (`shaders/common/sppm.glsl` has the kernel's side):
//! 1. the camera pass: one path a pixel to its visible point, with the direct light
//!    there;
//! 2. the photon map over the visible points: the hash grid, built on the device
//!    ([`crate::photon::device::GridBuild`]), or the lecture's kd-tree, built on the
//!    host from the points read back ([`crate::photon::PointTree`]);
//! 3. the photon pass: `--photons` photons from the lights, each deposited into the
//!    visible points that hold it;
//! 4. the update: each pixel's radius shrinks, its flux is kept, and its radiance sum
//!    becomes the estimate so far.
//!
//! Every photon's stream is keyed by its index and the iteration, each pixel's by the
//! pixel and the iteration, and deposits sum as integers: a seed gives one image, and a
//! tile (`--crop`) renders exactly the pixels the whole image has.

use std::time::Instant;

use glam::Vec3;
use serde::Serialize;

use crate::accel::gpu_layout::{DispatchChunk, GpuDispatch, GpuPixel, PIXEL_HEADER_BYTES};
use crate::accel::Accel;
use crate::error::{Error, Result};
use crate::gpu::bindings::*;
use crate::gpu::{BindingDesc, BindingKind, Buffer, Context, Kernel};
use crate::photon::device::GridBuild;
use crate::photon::PointTree;
use crate::render::dispatch::kernel::{Entry, LoopBounds};
use crate::render::dispatch::prepare::{Prepared, Request};
use crate::render::dispatch::tables::{extras, Extras};
use crate::render::dispatch::upload::{bind_again, GpuScene};
use crate::render::dispatch::DispatchTotals;
use crate::render::integrators::path;
use crate::render::{Control, Frame, RenderSettings, RenderStats};
use crate::scene::{Light, Scene};

/// How photons find the visible points that hold them (`--photon-map`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PhotonMap {
    /// A hash grid over the visible points, built on the device each iteration.
    #[default]
    Hashgrid,
    /// The lecture's kd-tree, balanced on the visible points, built on the host.
    Kdtree,
}

impl PhotonMap {
    pub fn name(self) -> &'static str {
        match self {
            PhotonMap::Hashgrid => "hashgrid",
            PhotonMap::Kdtree => "kdtree",
        }
    }

    /// By name (`hashgrid`, `kdtree`).
    pub fn parse(s: &str) -> Option<PhotonMap> {
        match s {
            "hashgrid" => Some(PhotonMap::Hashgrid),
            "kdtree" => Some(PhotonMap::Kdtree),
            _ => None,
        }
    }

    fn spec(self) -> u32 {
        match self {
            PhotonMap::Hashgrid => SPPM_MAP_HASHGRID,
            PhotonMap::Kdtree => SPPM_MAP_KDTREE,
        }
    }
}

/// SPPM's own settings; `RenderSettings::spp` is its iterations.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SppmSettings {
    /// Photons per iteration; `None`: one a pixel of the whole image (pbrt's default).
    pub photons: Option<u32>,
    /// The initial radius in scene units; `None`: a few pixel footprints at each
    /// visible point.
    pub radius: Option<f32>,
    /// The photon lookup.
    pub map: PhotonMap,
}

/// Most photons one iteration traces.
pub const MAX_PHOTONS: u32 = 1 << 26;

impl SppmSettings {
    /// Rejects values no render takes.
    pub fn check(&self) -> Result<()> {
        if let Some(n) = self.photons {
            if n == 0 || n > MAX_PHOTONS {
                return Err(Error::Usage(format!("--photons must be 1..={MAX_PHOTONS}, got {n}")));
            }
        }
        if let Some(r) = self.radius {
            if !(r.is_finite() && r > 0.0) {
                return Err(Error::Usage(format!("--photon-radius must be a positive distance, got {r}")));
            }
        }
        Ok(())
    }

    /// The photons each iteration traces for an image of `width` x `height`.
    pub fn photons_for(&self, width: u32, height: u32) -> u32 {
        self.photons.unwrap_or_else(|| (u64::from(width) * u64::from(height)).min(u64::from(MAX_PHOTONS)) as u32)
    }
}

/// What SPPM adds to a render's figures.
#[derive(Debug, Clone, Default, Serialize)]
pub struct SppmStats {
    /// The photon lookup.
    pub photon_map: String,
    /// Iterations run (fewer than asked after an interruption or with a time budget).
    pub iterations: u32,
    /// Photons emitted per iteration.
    pub photons_per_iteration: u32,
    /// Rays the photons traced.
    pub photon_rays: u64,
    /// Photons deposited into visible points (one photon vertex may deposit into many).
    pub deposits: u64,
    /// Camera paths and photons cut short because a trace ran out of its step budget
    /// (their light is lost; 0 on most scenes).
    pub cut_paths: u64,
    /// Photon lookups that met more candidates in a hash-grid bucket than one lookup
    /// tests (`SPPM_BUCKET_MOST`); the rest were not tested (0 on most scenes).
    pub truncated_lookups: u64,
    /// Host milliseconds building photon maps, summed over iterations (the device's
    /// passes included for the hash grid; readback, build and upload for the kd-tree).
    pub map_ms: f64,
    /// GPU milliseconds of the camera passes and of the photon passes (null without
    /// timestamps): the photon pass's rays per second is `photon_rays / photon_ms`.
    pub camera_ms: Option<f64>,
    pub photon_ms: Option<f64>,
}

/// The bindings of the `sppm` module beyond the trace kernel's.
fn sppm_bindings() -> Vec<BindingDesc> {
    let storage = |binding, name| BindingDesc { binding, kind: BindingKind::Storage, name };
    let texel = |binding, name| BindingDesc { binding, kind: BindingKind::Texel, name };
    vec![
        storage(BINDING_SPPM_POINTS, "sppm points"),
        storage(BINDING_SPPM_RECORDS, "sppm records"),
        storage(BINDING_SPPM_FLUX, "sppm flux"),
        texel(BINDING_SPPM_GRID_HEADER, "photon grid header"),
        texel(BINDING_SPPM_GRID_STARTS, "photon grid starts"),
        texel(BINDING_SPPM_MAP, "photon map"),
        texel(BINDING_SPPM_POINT_TEXELS, "sppm points (texels)"),
        texel(BINDING_SPPM_RECORD_TEXELS, "sppm records (texels)"),
    ]
}

fn luminance(v: Vec3) -> f32 {
    0.2126 * v.x + 0.7152 * v.y + 0.0722 * v.z
}

/// The photon pass's light table (rows: CDF start, probability, kind bits, index
/// bits), lights chosen in proportion to their power, and the total power. Power of a
/// point light 4 pi I; of a directional light and of the environment, what crosses the
/// disk of the scene's bounding sphere; of the area lights, pi times the emitter
/// table's total (its powers are radiance times area).
fn light_table(scene: &Scene, ex: &Extras, sphere_radius: f32) -> (Vec<[f32; 4]>, f32) {
    let disk = std::f32::consts::PI * sphere_radius * sphere_radius;
    let mut powers: Vec<(u32, u32, f32)> = Vec::new();
    for (i, l) in scene.lights.iter().enumerate() {
        let p = match *l {
            Light::Point { intensity, .. } => 4.0 * std::f32::consts::PI * luminance(intensity),
            Light::Directional { radiance, .. } => disk * luminance(radiance),
        };
        powers.push((SPPM_LIGHT_DELTA, i as u32, p));
    }
    if ex.emitter_count > 0 {
        powers.push((SPPM_LIGHT_AREA, 0, std::f32::consts::PI * ex.total_power));
    }
    if let Some(env) = scene.environment.as_ref().filter(|_| ex.env_size.0 > 0) {
        let n = env.texels.len().max(1) as f32;
        let mean = env.texels.iter().map(|t| luminance(Vec3::from_array(*t))).sum::<f32>() / n;
        powers.push((SPPM_LIGHT_ENV, 0, disk * 4.0 * std::f32::consts::PI * env.intensity * mean));
    }
    powers.retain(|p| p.2.is_finite() && p.2 > 0.0);
    let total: f32 = powers.iter().map(|p| p.2).sum();
    let mut rows = Vec::with_capacity(powers.len());
    let mut cdf = 0.0f32;
    for (kind, index, p) in powers {
        let pmf = p / total;
        rows.push([cdf, pmf, f32::from_bits(kind), f32::from_bits(index)]);
        cdf += pmf;
    }
    (rows, total)
}

/// Whether light leaving a surface of `m` goes on in a delta direction (mirror, smooth
/// glass, smooth conductor and dielectric): the surfaces photons are guided toward.
fn is_delta(m: &crate::scene::Material) -> bool {
    use crate::scene::MaterialKind;
    match m.kind {
        MaterialKind::Mirror | MaterialKind::Glass => true,
        MaterialKind::Conductor | MaterialKind::Dielectric => m.is_smooth(),
        _ => false,
    }
}

/// The photon guide: a sphere bounding the scene's delta surfaces (center, radius; 0
/// when there are none), toward which the photon pass sends `SPPM_GUIDE_SHARE` of the
/// photons of the lights outside it. Photons that reach a caustic all go through it.
fn guide_sphere(scene: &Scene) -> [f32; 4] {
    let mut bounds = crate::math::Aabb::EMPTY;
    for s in scene.spheres.iter().filter(|s| is_delta(&scene.materials[s.material as usize])) {
        bounds.grow(s.center - Vec3::splat(s.radius));
        bounds.grow(s.center + Vec3::splat(s.radius));
    }
    for (t, &m) in scene.triangles.iter().zip(&scene.tri_material) {
        if is_delta(&scene.materials[m as usize]) {
            t.iter().for_each(|&v| bounds.grow(scene.positions[v as usize]));
        }
    }
    if bounds.min.cmpgt(bounds.max).any() || bounds.min.is_nan() {
        return [0.0; 4];
    }
    // About the box's center, out to the farthest delta surface (one sphere: itself),
    // a little larger so that rounding never cuts a surface off.
    let c = 0.5 * (bounds.min + bounds.max);
    let mut r = 0.0f32;
    for s in scene.spheres.iter().filter(|s| is_delta(&scene.materials[s.material as usize])) {
        r = r.max((s.center - c).length() + s.radius);
    }
    for (t, &m) in scene.triangles.iter().zip(&scene.tri_material) {
        if is_delta(&scene.materials[m as usize]) {
            t.iter().for_each(|&v| r = r.max((scene.positions[v as usize] - c).length()));
        }
    }
    let r = r * 1.001 + 1e-6;
    if r.is_finite() {
        [c.x, c.y, c.z, r]
    } else {
        [0.0; 4]
    }
}

/// The buffers and state of one SPPM render on the device.
struct Passes<'p, 'a> {
    /// The camera pass's kernel is the prepared one; the photon and update passes are
    /// pipelines of their own from the same module and buffers.
    prep: &'p mut Prepared<'a>,
    photon_kernel: Kernel,
    update_kernel: Kernel,
    /// Pixels of the window, one slot each.
    slots: u32,
    /// The steps one trace may take, by pass: a photon traces fewer rays than a camera
    /// path (no shadow rays), so each of its traces gets a larger share of the loop limit.
    steps: [u32; 3],
    window: [u32; 3],
    /// Dispatches run and their GPU milliseconds (None without timestamps).
    dispatches: u32,
    gpu_ms: Option<f64>,
    /// The kd-tree the kernel's map binding points at, kept until the next one.
    tree_buffer: Option<Buffer>,
    /// Jobs a millisecond each pass ran at in its last dispatch (`SPPM_PASS_*`):
    /// dispatches are sized from it toward the pacing's target length.
    rates: [Option<f64>; 3],
    /// Polled between dispatches: true stops the render within the iteration (whose
    /// update then does not run: the image is the last iteration's).
    interrupted: &'p dyn Fn() -> bool,
    stopped: bool,
}

impl Passes<'_, '_> {
    fn buffer(&self, binding: u32) -> Result<&Buffer> {
        self.prep.bound.at(binding).ok_or_else(|| Error::Failed(format!("sppm: binding {binding} has no buffer")))
    }

    /// Runs pass `pass` of iteration `it` over jobs `0..jobs`, in dispatches sized by
    /// the time the pass's last one took (toward the pacing's target, as the render
    /// loop sizes its waves) and within the device's workgroup limit; its GPU
    /// milliseconds (None without timestamps). Sets `stopped` and returns early when
    /// interrupted.
    fn pass(&mut self, pass: u32, it: u32, jobs: u32, map: (u32, u32), label: &str) -> Result<Option<f64>> {
        let mut total = Some(0.0);
        // Every device dispatches at least 65,535 workgroups along x.
        let most = WORKGROUP_SIZE * 65_535;
        let target_ms = self.prep.pacing.target_ms;
        let mut first = 0u32;
        while first < jobs {
            // The update runs whole: every pixel then holds the same iterations.
            if pass != SPPM_PASS_UPDATE && (self.interrupted)() {
                self.stopped = true;
                return Ok(total);
            }
            let sized = match self.rates[pass as usize] {
                Some(rate) => (rate * target_ms).clamp(f64::from(WORKGROUP_SIZE), f64::from(most)) as u32,
                None => FIRST_DISPATCH_JOBS,
            };
            let count = (jobs - first).min(most).min(sized.max(WORKGROUP_SIZE));
            let [x0, y0, w] = self.window;
            let header = GpuDispatch {
                first,
                count,
                sample_begin: it,
                sample_end: it + 1,
                chunk: DispatchChunk { base: 0, resumed: 0, pass: PASS_TRACE, counter: 0 },
                window_left: x0,
                window_top: y0,
                window_width: w,
                zero_sample: 0,
                trace_steps: self.steps[pass as usize],
                unused: 0,
                map_size: map.0,
                map_buckets: map.1,
            };
            let ctx = self.prep.ctx;
            ctx.write_storage(self.prep.bound.pixels(), 0, bytemuck::bytes_of(&header))?;
            let began = Instant::now();
            let kernel = match pass {
                SPPM_PASS_PHOTON => &self.photon_kernel,
                SPPM_PASS_UPDATE => &self.update_kernel,
                _ => &self.prep.kernel,
            };
            let ms = ctx.dispatch(kernel, &[], [count.div_ceil(WORKGROUP_SIZE), 1, 1], label)?;
            // The GPU's time where there are timestamps, else the host's wait.
            let took = ms.unwrap_or_else(|| began.elapsed().as_secs_f64() * 1e3).max(1e-3);
            self.rates[pass as usize] = Some(f64::from(count) / took);
            self.dispatches += 1;
            self.gpu_ms = match (self.gpu_ms, ms) {
                (Some(a), Some(b)) => Some(a + b),
                (None, Some(b)) if self.dispatches == 1 => Some(b),
                _ => None,
            };
            total = total.zip(ms).map(|(a, b)| a + b);
            first += count;
        }
        Ok(total)
    }
}

/// Jobs of a pass's first dispatch, before its rate is known.
const FIRST_DISPATCH_JOBS: u32 = 16_384;

/// The photon map of one iteration: builds it over the visible points the camera pass
/// left and binds it; its size and buckets for the photon pass.
enum MapBuilder {
    Grid(Box<GridBuild>),
    Tree,
}

impl MapBuilder {
    fn build(&mut self, passes: &mut Passes<'_, '_>) -> Result<(u32, u32)> {
        let ctx = passes.prep.ctx;
        let n = passes.slots;
        match self {
            MapBuilder::Grid(build) => {
                if build.run(ctx, passes.buffer(BINDING_SPPM_GRID_HEADER)?, n)? {
                    ctx.bind(&mut passes.photon_kernel, BINDING_SPPM_MAP, &build.entries)?;
                }
                Ok((n, n.max(1)))
            }
            MapBuilder::Tree => {
                let words: Vec<[f32; 4]> = ctx.read_storage_pod(passes.buffer(BINDING_SPPM_POINTS)?, 0, n as usize)?;
                let mut slots = Vec::new();
                let mut positions = Vec::new();
                let mut radii = Vec::new();
                for (k, w) in words.iter().enumerate() {
                    if w[3] > 0.0 {
                        slots.push(k as u32);
                        positions.push(Vec3::new(w[0], w[1], w[2]));
                        radii.push(w[3]);
                    }
                }
                let mut tree = PointTree::build(&positions, &radii).map_err(Error::Failed)?;
                // The tree numbers its points 0..; the kernel reads them by slot.
                for node in &mut tree.nodes {
                    node.point = slots[node.point as usize];
                }
                let bytes: &[u8] = if tree.nodes.is_empty() { &[0; 32] } else { bytemuck::cast_slice(&tree.nodes) };
                ctx.check_binding(BindingKind::Texel, "photon map", bytes.len() as u64)?;
                let buf = ctx.upload_storage("photon map", bytes)?;
                ctx.bind(&mut passes.photon_kernel, BINDING_SPPM_MAP, &buf)?;
                // The kernel's descriptor points at it until the next iteration's.
                passes.tree_buffer = Some(buf);
                Ok((tree.nodes.len() as u32, 0))
            }
        }
    }
}

/// Renders `scene` with an already built structure.
pub fn render_with(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    accel: &Accel,
    control: Control<'_>,
) -> Result<(Frame, RenderStats)> {
    settings.check()?;
    let sppm = settings.sppm;
    sppm.check()?;
    if settings.resume.is_some() || settings.first_sample > 0 {
        return Err(Error::Usage(
            "sppm cannot resume a render or render a sample shard: each iteration shrinks every pixel's radius from the last, so independent runs do not add up to one long run; shard the image by tiles (--shard with tiles) instead".into(),
        ));
    }
    let start = Instant::now();
    let mut gs = GpuScene::new(scene);
    let ex = extras(scene, gs.shading.len() as u32, true)?;
    gs.shading.extend_from_slice(&ex.rows);
    let bounds = accel.bounds();
    let sphere_radius = (0.5 * (bounds.max - bounds.min).length()).max(1e-6);
    let (lights, power) = light_table(scene, &ex, sphere_radius);
    let light_table_row = gs.shading.len() as u32;
    gs.shading.extend_from_slice(&lights);
    // The row after the light table: the photon guide.
    gs.shading.push(guide_sphere(scene));
    let photons = sppm.photons_for(settings.width, settings.height);
    let mut params = path::params(scene, settings, accel, &ex);
    params.photon_light_table = light_table_row;
    params.photon_lights = lights.len() as u32;
    params.photon_count = photons;
    params.photon_radius = sppm.radius.unwrap_or(0.0);
    // A deposit of a photon of the lights' whole power through a BSDF of 1 is 2^24 units.
    params.photon_unit = if power > 0.0 { power / 16_777_216.0 } else { 1.0 };
    let mut spec = path::specialization(scene, settings, &ex);
    spec.push((SPEC_PHOTON_MAP, sppm.map.spec()));
    spec.push((SPEC_SPPM_PASS, SPPM_PASS_CAMERA));
    let window = settings.window();
    let slots = window.pixels();
    let request = Request {
        entry: Entry::Sppm,
        traces: path::traces_per_sample(scene, settings, &ex),
        rays_per_sample: 1,
        spec,
        params,
        scene: gs,
        extra_bindings: sppm_bindings(),
        chunk_most: slots,
        fit: None,
    };
    let mut prep = Prepared::new(ctx, scene, &settings.loop_settings(), accel, request)?;
    let most = crate::photon::device::MAX_POINTS.min(prep.chunk_pixels as u32);
    if prep.chunk_pixels < slots || slots > u64::from(most) {
        return Err(Error::Usage(format!(
            "sppm holds every pixel of the window on the device at once: at most {most} on {}, and {} has {slots}; render it in tiles (--crop or --shard)",
            ctx.info().name,
            if settings.crop.is_some() { "the window" } else { "the image" },
        )));
    }
    let slots = slots as u32;
    let mut map = match sppm.map {
        PhotonMap::Hashgrid => {
            let (header, starts, points) = (
                prep.bound.at(BINDING_SPPM_GRID_HEADER),
                prep.bound.at(BINDING_SPPM_GRID_STARTS),
                prep.bound.at(BINDING_SPPM_POINTS),
            );
            match (header, starts, points) {
                (Some(h), Some(s), Some(p)) => MapBuilder::Grid(Box::new(GridBuild::new(ctx, h, p, s, slots)?)),
                _ => return Err(Error::Failed("sppm: the photon grid's buffers are not bound".into())),
            }
        }
        PhotonMap::Kdtree => MapBuilder::Tree,
    };
    let kernel_of = |pass: u32| -> Result<Kernel> {
        let spec: Vec<(u32, u32)> =
            prep.spec.iter().map(|&(id, v)| if id == SPEC_SPPM_PASS { (id, pass) } else { (id, v) }).collect();
        let variant = &prep.variant;
        let mut k = ctx.create_kernel(&variant.name, variant.spirv, &variant.bindings, &spec, 0)?;
        let stand_in =
            prep.bound.at(BINDING_SPPM_MAP).ok_or_else(|| Error::Failed("sppm: no photon map binding".into()))?;
        bind_again(
            ctx,
            &mut k,
            &variant.bindings,
            &prep.bound,
            prep.image.ray_structure,
            (BINDING_SPPM_MAP, stand_in),
        )?;
        Ok(k)
    };
    let compile = Instant::now();
    let mut photon_kernel = kernel_of(SPPM_PASS_PHOTON)?;
    let mut update_kernel = kernel_of(SPPM_PASS_UPDATE)?;
    prep.kernel_ms += compile.elapsed().as_secs_f64() * 1e3;
    // The photon pass reads the points and records the camera pass writes, through
    // texel views of the same buffers.
    for (view, of) in
        [(BINDING_SPPM_POINT_TEXELS, BINDING_SPPM_POINTS), (BINDING_SPPM_RECORD_TEXELS, BINDING_SPPM_RECORDS)]
    {
        let buf = prep.bound.at(of).ok_or_else(|| Error::Failed(format!("sppm: binding {of} has no buffer")))?;
        ctx.bind(&mut photon_kernel, view, buf)?;
        ctx.bind(&mut update_kernel, view, buf)?;
        ctx.bind(&mut prep.kernel, view, buf)?;
    }
    if let MapBuilder::Grid(build) = &map {
        // The photon pass reads the entries the build writes.
        ctx.bind(&mut photon_kernel, BINDING_SPPM_MAP, &build.entries)?;
    }
    let photon_traces = u64::from(path::max_depth(scene, settings)) + 1;
    let photon_bounds = LoopBounds::new(ctx, scene, &prep.image, photon_traces, settings.trace_steps)?;
    let camera_steps = prep.bounds.steps as u32;
    let steps = [camera_steps, photon_bounds.steps as u32, camera_steps];
    let Control { mut progress, interrupted, mut checkpoint } = control;
    let mut passes = Passes {
        prep: &mut prep,
        photon_kernel,
        update_kernel,
        slots,
        steps,
        window: [window.x0, window.y0, window.width()],
        dispatches: 0,
        gpu_ms: None,
        tree_buffer: None,
        rates: [None; 3],
        interrupted: &*interrupted,
        stopped: false,
    };
    let mut stats =
        SppmStats { photon_map: sppm.map.name().into(), photons_per_iteration: photons, ..Default::default() };
    let loop_start = Instant::now();
    let mut last_checkpoint = Instant::now();
    let mut stopped = false;
    let add = |sum: &mut Option<f64>, ms: Option<f64>| *sum = sum.zip(ms).map(|(a, b)| a + b);
    stats.camera_ms = Some(0.0);
    stats.photon_ms = Some(0.0);
    for it in 0..settings.spp {
        let ms = passes.pass(SPPM_PASS_CAMERA, it, slots, (0, 0), "sppm: camera")?;
        add(&mut stats.camera_ms, ms);
        if photons > 0 && !lights.is_empty() {
            let built = Instant::now();
            let map_size = map.build(&mut passes)?;
            stats.map_ms += built.elapsed().as_secs_f64() * 1e3;
            if !passes.stopped {
                let ms = passes.pass(SPPM_PASS_PHOTON, it, photons, map_size, "sppm: photons")?;
                add(&mut stats.photon_ms, ms);
            }
        }
        if passes.stopped {
            stopped = true;
            break;
        }
        passes.pass(SPPM_PASS_UPDATE, it, slots, (0, 0), "sppm: update")?;
        stats.iterations = it + 1;
        progress(u64::from(it + 1), u64::from(settings.spp));
        if it + 1 == settings.spp {
            break;
        }
        // An interruption stops the render (the command line exits 130); the time
        // budget ends it early, as path's does.
        if interrupted() {
            stopped = true;
            break;
        }
        if settings.time_budget.is_some_and(|b| start.elapsed().as_secs_f64() >= b) {
            break;
        }
        if let Some((every, write)) = checkpoint.as_mut() {
            if last_checkpoint.elapsed().as_secs_f64() >= *every {
                write(&read_frame(ctx, &passes, window.width(), window.height())?)?;
                last_checkpoint = Instant::now();
            }
        }
    }
    let counters: Vec<u32> = ctx.read_storage_pod(passes.buffer(BINDING_SPPM_FLUX)?, 0, SPPM_COUNTERS as usize)?;
    stats.cut_paths = u64::from(counters[SPPM_COUNT_CUT as usize]);
    stats.truncated_lookups = u64::from(counters[SPPM_COUNT_TRUNCATED as usize]);
    stats.deposits = u64::from(counters[SPPM_COUNT_DEPOSITS as usize]);
    stats.photon_rays = u64::from(counters[SPPM_COUNT_PHOTON_RAYS as usize]);
    let frame = read_frame(ctx, &passes, window.width(), window.height())?;
    ctx.check_validation()?;
    let totals = DispatchTotals {
        gpu_ms: passes.gpu_ms,
        dispatches: passes.dispatches,
        stopped,
        loop_ms: loop_start.elapsed().as_secs_f64() * 1e3,
        in_flight: 1,
        ..Default::default()
    };
    drop(passes);
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    let mut st = RenderStats::new(&prep, settings, accel.stats(scene), &frame, &totals, wall_ms);
    st.rays += stats.photon_rays;
    st.mrays_per_s = totals.gpu_ms.filter(|&ms| ms > 0.0).map(|ms| st.rays as f64 / (ms * 1e3));
    st.sppm = Some(stats);
    Ok((frame, st))
}

/// The window's pixels as the update pass left them.
fn read_frame(ctx: &Context, passes: &Passes<'_, '_>, width: u32, height: u32) -> Result<Frame> {
    let pixels: Vec<GpuPixel> =
        ctx.read_storage_pod(passes.prep.bound.pixels(), PIXEL_HEADER_BYTES, passes.slots as usize)?;
    let mut frame = Frame::new(width, height)?;
    frame.store(0, &pixels);
    Ok(frame)
}
