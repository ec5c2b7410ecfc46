//! The pipelines a context compiled, kept for kernels created again: [`Pipeline`]
//! (shader module, layouts, compute pipeline), what makes two of them the same
//! ([`PipelineKey`]) and the cache ([`KernelCache`]). Imports device.rs and descriptor.rs.

use std::ffi::CString;
use std::sync::{Arc, Mutex};

use ash::vk;

use super::descriptor::{BindingDesc, BindingKind};
use super::device::{vk_err, Shared};
use crate::error::{Error, Result};

/// The compiled part of a kernel: its shader module, layouts and pipeline. Every
/// `Kernel` made on one context from the same SPIR-V, bindings, specialization
/// constants and push-constant size shares one (see [`KernelCache`]); destroyed when
/// the last of them and the cache let go.
pub(crate) struct Pipeline {
    shared: Arc<Shared>,
    module: vk::ShaderModule,
    pub set_layout: vk::DescriptorSetLayout,
    pub layout: vk::PipelineLayout,
    pub pipeline: vk::Pipeline,
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        // SAFETY: every kernel using these objects holds this Arc, and submissions
        // complete before their kernels can drop, so nothing uses them now. Null
        // handles (an error part way through creation) are ignored by Vulkan.
        unsafe {
            let d = &self.shared.device;
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
            d.destroy_shader_module(self.module, None);
        }
    }
}

/// What makes two pipelines the same: the SPIR-V (hashed, with its length), the
/// kinds and numbers of the bindings, the specialization constants and the
/// push-constant size. The name is only a label and does not count.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
struct PipelineKey {
    spirv_hash: u64,
    spirv_len: usize,
    bindings: Vec<(u32, BindingKind)>,
    spec: Vec<(u32, u32)>,
    push_size: u32,
}

impl PipelineKey {
    fn new(spirv: &[u8], bindings: &[BindingDesc], spec: &[(u32, u32)], push_size: u32) -> PipelineKey {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        spirv.hash(&mut h);
        PipelineKey {
            spirv_hash: h.finish(),
            spirv_len: spirv.len(),
            bindings: bindings.iter().map(|b| (b.binding, b.kind)).collect(),
            spec: spec.to_vec(),
            push_size,
        }
    }
}

/// Pipelines a context has compiled, so that a kernel created again (the same render
/// twice, a bench's repeats, a test suite's renders) skips the driver's compile: on
/// lavapipe that compile is most of a small render's time. At most
/// [`KernelCache::CAPACITY`] are kept; the least recently used goes first.
#[derive(Default)]
pub(crate) struct KernelCache {
    lru: Mutex<Lru>,
}

/// The cache's entries, least recently used first out.
#[derive(Default)]
struct Lru {
    entries: Vec<(PipelineKey, Arc<Pipeline>, u64)>,
    clock: u64,
    hits: u64,
    misses: u64,
}

impl KernelCache {
    /// Pipelines kept at most (each trace variant is a few hundred kilobytes of
    /// driver code on lavapipe).
    pub const CAPACITY: usize = 48;

    /// The pipeline of kernel `name`: from the cache where one with the same key was
    /// compiled on this device, else compiled now and kept.
    pub fn pipeline(
        &self,
        shared: &Arc<Shared>,
        name: &str,
        spirv: &[u8],
        bindings: &[BindingDesc],
        spec: &[(u32, u32)],
        push_size: u32,
    ) -> Result<Arc<Pipeline>> {
        // Constants the module does not declare change nothing (Vulkan ignores them);
        // left in, they would part pipelines that are the same.
        let declared = declared_spec_ids(spirv);
        let spec: Vec<(u32, u32)> = spec.iter().copied().filter(|(id, _)| declared.contains(id)).collect();
        let spec = spec.as_slice();
        let key = PipelineKey::new(spirv, bindings, spec, push_size);
        let cached = self.lru.lock().ok().and_then(|mut c| c.get(&key));
        if let Some(p) = cached {
            let _span = crate::timeline::span("kernel", || format!("create kernel {name} (cached)"));
            return Ok(p);
        }
        let _span = crate::timeline::span("kernel", || format!("create kernel {name}"));
        let p = Arc::new(Pipeline::compile(shared, name, spirv, bindings, spec, push_size)?);
        if let Ok(mut c) = self.lru.lock() {
            c.insert(key, Arc::clone(&p));
        }
        Ok(p)
    }

    /// How often [`KernelCache::pipeline`] found its pipeline already compiled.
    pub fn stats(&self) -> KernelCacheStats {
        match self.lru.lock() {
            Ok(c) => KernelCacheStats { hits: c.hits, misses: c.misses, held: c.entries.len() },
            Err(_) => KernelCacheStats::default(),
        }
    }
}

impl Lru {
    fn get(&mut self, key: &PipelineKey) -> Option<Arc<Pipeline>> {
        self.clock += 1;
        let now = self.clock;
        match self.entries.iter_mut().find(|(k, _, _)| k == key) {
            Some((_, p, used)) => {
                *used = now;
                self.hits += 1;
                Some(Arc::clone(p))
            }
            None => {
                self.misses += 1;
                None
            }
        }
    }

    fn insert(&mut self, key: PipelineKey, pipeline: Arc<Pipeline>) {
        if self.entries.len() >= KernelCache::CAPACITY {
            if let Some(oldest) = self.entries.iter().enumerate().min_by_key(|(_, e)| e.2).map(|(i, _)| i) {
                self.entries.swap_remove(oldest);
            }
        }
        self.entries.push((key, pipeline, self.clock));
    }
}

/// The specialization-constant ids a SPIR-V module declares: the `SpecId` decorations
/// (`OpDecorate %target SpecId N`: opcode 71, decoration 1). Empty for bytes that are
/// not SPIR-V (the pipeline's creation reports those).
fn declared_spec_ids(spirv: &[u8]) -> Vec<u32> {
    const OP_DECORATE: u32 = 71;
    const SPEC_ID: u32 = 1;
    if spirv.len() % 4 != 0 || spirv.len() < 20 {
        return Vec::new();
    }
    let words: Vec<u32> = spirv.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    if words[0] != 0x0723_0203 {
        return Vec::new();
    }
    let mut ids = Vec::new();
    let mut i = 5; // past the header: magic, version, generator, bound, schema
    while i < words.len() {
        let (count, op) = ((words[i] >> 16) as usize, words[i] & 0xffff);
        if count == 0 {
            break;
        }
        if op == OP_DECORATE && count == 4 && i + 3 < words.len() && words[i + 2] == SPEC_ID {
            ids.push(words[i + 3]);
        }
        i += count;
    }
    ids
}

/// How often `Context::create_kernel` found its pipeline already compiled.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct KernelCacheStats {
    /// Kernels whose pipeline came from the cache.
    pub hits: u64,
    /// Kernels whose pipeline was compiled.
    pub misses: u64,
    /// Pipelines held now.
    pub held: usize,
}

impl Pipeline {
    /// Compiles the shader module, layouts and pipeline of kernel `name`.
    fn compile(
        shared: &Arc<Shared>,
        name: &str,
        spirv: &[u8],
        bindings: &[BindingDesc],
        spec: &[(u32, u32)],
        push_size: u32,
    ) -> Result<Pipeline> {
        let words = ash::util::read_spv(&mut std::io::Cursor::new(spirv))
            .map_err(|e| Error::Vulkan { what: format!("read SPIR-V of '{name}'"), result: e.to_string() })?;
        let dev = &*shared.device;
        // Objects are created in order and wrapped immediately so that an error part
        // way through destroys what exists.
        let mut p = Pipeline {
            shared: Arc::clone(shared),
            module: vk::ShaderModule::null(),
            set_layout: vk::DescriptorSetLayout::null(),
            layout: vk::PipelineLayout::null(),
            pipeline: vk::Pipeline::null(),
        };
        // SAFETY: `words` is SPIR-V produced by shaderc at build time.
        p.module = unsafe { dev.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None) }
            .map_err(vk_err("vkCreateShaderModule"))?;
        shared.set_name(p.module, name);
        let vk_bindings: Vec<vk::DescriptorSetLayoutBinding> = bindings
            .iter()
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b.binding)
                    .descriptor_type(b.kind.descriptor_type())
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        // SAFETY: valid create infos on a live device (same for the calls below).
        p.set_layout = unsafe {
            dev.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&vk_bindings), None)
        }
        .map_err(vk_err("vkCreateDescriptorSetLayout"))?;
        shared.set_name(p.set_layout, name);
        let set_layouts = [p.set_layout];
        let ranges =
            [vk::PushConstantRange::default().stage_flags(vk::ShaderStageFlags::COMPUTE).offset(0).size(push_size)];
        let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
        if push_size > 0 {
            layout_info = layout_info.push_constant_ranges(&ranges);
        }
        // SAFETY: as above.
        p.layout =
            unsafe { dev.create_pipeline_layout(&layout_info, None) }.map_err(vk_err("vkCreatePipelineLayout"))?;
        shared.set_name(p.layout, name);
        let entries: Vec<vk::SpecializationMapEntry> = spec
            .iter()
            .enumerate()
            .map(|(i, (id, _))| vk::SpecializationMapEntry { constant_id: *id, offset: (i * 4) as u32, size: 4 })
            .collect();
        let data: Vec<u8> = spec.iter().flat_map(|(_, v)| v.to_ne_bytes()).collect();
        let spec_info = vk::SpecializationInfo::default().map_entries(&entries).data(&data);
        let entry = CString::new("main").unwrap_or_default();
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(p.module)
            .name(&entry)
            .specialization_info(&spec_info);
        let pinfo = [vk::ComputePipelineCreateInfo::default().stage(stage).layout(p.layout)];
        // SAFETY: as above.
        let created = unsafe { dev.create_compute_pipelines(vk::PipelineCache::null(), &pinfo, None) };
        if let Ok(c) = &created {
            p.pipeline = c[0];
        }
        // A pipeline the validation layer rejected was never created: report its message.
        shared.check_validation()?;
        created.map_err(|(_, e)| vk_err("vkCreateComputePipelines")(e))?;
        shared.set_name(p.pipeline, name);
        Ok(p)
    }
}

#[cfg(test)]
mod tests {
    use super::declared_spec_ids;

    #[test]
    fn spec_ids_are_read_from_the_module() {
        let spv = crate::gpu::spirv::get("sample_probe").expect("sample_probe is compiled");
        let ids = declared_spec_ids(spv);
        assert!(!ids.is_empty(), "sample_probe declares specialization constants");
        let trace = crate::gpu::spirv::get("trace_bvh_tris.path").expect("trace_bvh_tris.path is compiled");
        let ids = declared_spec_ids(trace);
        use crate::gpu::bindings::{SPEC_STACK_SIZE, SPEC_TRIANGLE_COUNT};
        assert!(ids.contains(&SPEC_STACK_SIZE), "a BVH kernel has a stack: {ids:?}");
        assert!(!ids.contains(&SPEC_TRIANGLE_COUNT), "only brute force counts triangles: {ids:?}");
        let brute = crate::gpu::spirv::get("trace_none_tris.path").expect("trace_none_tris.path is compiled");
        assert!(declared_spec_ids(brute).contains(&SPEC_TRIANGLE_COUNT));
        assert!(declared_spec_ids(b"not spir-v at all!!!").is_empty());
    }
}
