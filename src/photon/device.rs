//! The hash grid built on the device (shaders/photon_grid.comp): the passes of
//! [`HashGrid::build`] as kernels over visible points already in a device buffer, so
//! an SPPM iteration builds its grid without reading the points back. The grid stays
//! on the device; [`DeviceGrid::read_back`] brings it to the host for tests.

use glam::Vec3;

use super::{HashGrid, PointTree};
use crate::error::{Error, Result};
use crate::gpu::bindings::*;
use crate::gpu::{spirv, BindingDesc, BindingKind, Buffer, BufferKind, Context, Step};

/// Most distinct buckets one visible point enters (3 cells an axis).
pub const MAX_BUCKETS_A_POINT: u64 = 27;

/// Most visible points one build takes (a 2048 x 2048 image's): the one-workgroup
/// scan's threads each run through buckets / PHOTON_GROUP counts twice, which must stay
/// within llvmpipe's loop budget (`LLVMPIPE_LOOP_BUDGET`), and the per-point passes are
/// one-dimensional dispatches.
pub const MAX_POINTS: u32 = 16_384 * PHOTON_GROUP;

const _: () = assert!(2 * (MAX_POINTS / PHOTON_GROUP) as u64 + PHOTON_GROUP as u64 <= LLVMPIPE_LOOP_BUDGET);

/// A hash grid on the device, in [`HashGrid`]'s layout.
#[derive(Debug)]
pub struct DeviceGrid {
    /// `PHOTON_HDR_WORDS` words: the box, the largest radius, cells per axis, the edge,
    /// the entries.
    pub header: Buffer,
    /// Buckets + 1 words.
    pub starts: Buffer,
    /// The entries, as many as the count pass found (the header's total; at most
    /// [`MAX_BUCKETS_A_POINT`] a point).
    pub entries: Buffer,
    /// The number of buckets (the points, at least 1).
    pub buckets: u32,
    /// The visible points.
    pub points: u32,
}

/// The visible points as the kernel reads them: position and radius, a vec4 each.
pub fn upload_points(ctx: &Context, positions: &[Vec3], radii: &[f32]) -> Result<Buffer> {
    super::check_points(positions, radii).map_err(Error::Failed)?;
    let words: Vec<[f32; 4]> = positions.iter().zip(radii).map(|(p, &r)| [p.x, p.y, p.z, r]).collect();
    // A buffer may not be empty; an empty set binds one unused point.
    let words = if words.is_empty() { vec![[0.0; 4]] } else { words };
    ctx.upload_storage("visible points", bytemuck::cast_slice(&words))
}

/// Builds the grid over the `n` visible points of `points` ([`upload_points`]'s layout)
/// with the passes of shaders/photon_grid.comp, one submission each.
pub fn build_grid(ctx: &Context, points: &Buffer, n: u32) -> Result<DeviceGrid> {
    let buckets = n.max(1);
    let header = ctx.create_buffer("photon grid header", u64::from(PHOTON_HDR_WORDS) * 4, BufferKind::Storage)?;
    let starts = ctx.create_buffer("photon grid starts", (u64::from(buckets) + 1) * 4, BufferKind::Storage)?;
    let mut build = GridBuild::new(ctx, &header, points, &starts, n)?;
    build.run(ctx, &header, n)?;
    Ok(DeviceGrid { header, starts, entries: build.entries, buckets, points: n })
}

/// The grid's build passes over visible points already on the device, into a header
/// and bucket starts the caller owns (SPPM's photon pass binds the same buffers) and
/// entries this build owns and grows as a build needs.
pub struct GridBuild {
    /// One kernel a pass, by `PHOTON_GRID_*` (the test pass's stands in its place).
    kernels: Vec<crate::gpu::Kernel>,
    /// One word a bucket: where the scatter puts a bucket's next entry.
    _cursor: Buffer,
    /// The test pass's buffers, unused by a build.
    _queries: Buffer,
    _found: Buffer,
    /// The entries; at least as many words as the last build counted.
    pub entries: Buffer,
    /// Most points a build over these buffers takes (the starts' buckets).
    most: u32,
}

impl std::fmt::Debug for GridBuild {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GridBuild").field("most", &self.most).field("entries", &self.entries.size()).finish()
    }
}

impl GridBuild {
    /// The build's kernel over `points`, `header` (`PHOTON_HDR_WORDS` words) and `starts`
    /// (most + 1 words), for builds over at most `most` points.
    pub fn new(ctx: &Context, header: &Buffer, points: &Buffer, starts: &Buffer, most: u32) -> Result<GridBuild> {
        if most > MAX_POINTS {
            return Err(Error::Failed(format!(
                "{most} visible points; one photon grid build takes at most {MAX_POINTS}"
            )));
        }
        let bindings = grid_bindings();
        let mut kernels = Vec::new();
        for mode in 0..=PHOTON_GRID_CLEAR {
            // The test pass is not a build's: the clear pass stands in its place.
            let pass = if mode == PHOTON_GRID_PROBE { PHOTON_GRID_CLEAR } else { mode };
            kernels.push(grid_kernel(ctx, &bindings, pass)?);
        }
        let cursor = ctx.create_buffer("photon grid cursor", u64::from(most.max(1)) * 4, BufferKind::Storage)?;
        // Eight a point at first (a sphere's box overlaps 8 cells or fewer unless its
        // radius is near the largest); grown when a build counts more.
        let entries = ctx.create_buffer("photon grid entries", u64::from(most.max(1)) * 8 * 4, BufferKind::Storage)?;
        let queries = ctx.create_buffer("photon grid queries", 16, BufferKind::Storage)?;
        let found = ctx.create_buffer("photon grid found", 16, BufferKind::Storage)?;
        for (binding, buffer) in [
            (BINDING_PHOTON_HEADER, header),
            (BINDING_PHOTON_POINTS, points),
            (BINDING_PHOTON_STARTS, starts),
            (BINDING_PHOTON_CURSOR, &cursor),
            (BINDING_PHOTON_ENTRIES, &entries),
            (BINDING_PHOTON_QUERIES, &queries),
            (BINDING_PHOTON_FOUND, &found),
        ] {
            for k in &mut kernels {
                ctx.bind(k, binding, buffer)?;
            }
        }
        Ok(GridBuild { kernels, _cursor: cursor, _queries: queries, _found: found, entries, most })
    }

    /// Builds the grid over the first `n` points (radius 0: none this time, skipped),
    /// with `n` buckets (at least 1): the six passes in one submission, then the scan's
    /// total read back; where the entries were too few for it, they grow (by a quarter
    /// more than needed) and the grid is built again. True when `entries` was replaced,
    /// which the caller binds again where it bound the old one.
    pub fn run(&mut self, ctx: &Context, header: &Buffer, n: u32) -> Result<bool> {
        if n > self.most {
            return Err(Error::Failed(format!("{n} visible points; this grid build takes at most {}", self.most)));
        }
        let buckets = n.max(1);
        let groups = n.div_ceil(PHOTON_GROUP).max(1);
        let clear = (buckets + 1).max(PHOTON_HDR_WORDS).div_ceil(PHOTON_GROUP);
        let mut grown = false;
        loop {
            let capacity = (self.entries.size() / 4) as u32;
            let push = || bytemuck::cast_slice(&[0, n, buckets, capacity]).to_vec();
            let clear_pass = &self.kernels[PHOTON_GRID_CLEAR as usize];
            let mut steps = vec![Step::Dispatch { kernel: clear_pass, push: push(), groups: [clear, 1, 1] }];
            if n > 0 {
                for (mode, groups) in [
                    (PHOTON_GRID_BOUNDS, groups),
                    (PHOTON_GRID_FRAME, 1),
                    (PHOTON_GRID_COUNT, groups),
                    (PHOTON_GRID_SCAN, 1),
                    (PHOTON_GRID_SCATTER, groups),
                ] {
                    let kernel = &self.kernels[mode as usize];
                    steps.push(Step::Dispatch { kernel, push: push(), groups: [groups, 1, 1] });
                }
            }
            ctx.run_steps("photon grid: build", &steps)?;
            let total: Vec<u32> = ctx.read_storage_pod(header, u64::from(PHOTON_HDR_TOTAL) * 4, 1)?;
            let needed = u64::from(total[0]);
            if needed <= u64::from(capacity) {
                break;
            }
            // Whole 16-byte texels: the photon pass reads the entries as a texel buffer.
            let bytes = ((needed + needed / 4).min(u64::from(self.most.max(1)) * MAX_BUCKETS_A_POINT).max(needed) * 4)
                .next_multiple_of(16);
            ctx.check_binding(BindingKind::Storage, "photon grid entries", bytes)?;
            self.entries = ctx.create_buffer("photon grid entries", bytes, BufferKind::Storage)?;
            for k in &mut self.kernels {
                ctx.bind(k, BINDING_PHOTON_ENTRIES, &self.entries)?;
            }
            grown = true;
        }
        ctx.check_validation()?;
        Ok(grown)
    }
}

/// The grid kernel's bindings: the build's five and the test pass's two.
fn grid_bindings() -> [BindingDesc; 7] {
    let storage = |binding, name| BindingDesc { binding, kind: BindingKind::Storage, name };
    [
        storage(BINDING_PHOTON_HEADER, "photon grid header"),
        storage(BINDING_PHOTON_POINTS, "visible points"),
        storage(BINDING_PHOTON_STARTS, "photon grid starts"),
        storage(BINDING_PHOTON_CURSOR, "photon grid cursor"),
        storage(BINDING_PHOTON_ENTRIES, "photon grid entries"),
        storage(BINDING_PHOTON_QUERIES, "photon grid queries"),
        storage(BINDING_PHOTON_FOUND, "photon grid found"),
    ]
}

/// The grid's kernel of pass `mode` (`PHOTON_GRID_*`).
fn grid_kernel(ctx: &Context, bindings: &[BindingDesc], mode: u32) -> Result<crate::gpu::Kernel> {
    let spv = spirv::get("photon_grid").ok_or_else(|| Error::Failed("kernel photon_grid is not compiled in".into()))?;
    ctx.create_kernel(&format!("photon_grid.{mode}"), spv, bindings, &[(SPEC_GRID_MODE, mode)], 16)
}

impl DeviceGrid {
    /// Looks up photons at `queries` on the device, as the photon pass will
    /// (`grid_lookup_begin` in shaders/common/photon_grid.glsl and `photon_holds`): per
    /// photon, the visible points of `points` (the buffer the grid was built over) that
    /// hold it, and the sum of their indices + 1. For tests and the benchmark.
    pub fn lookup_counts(&self, ctx: &Context, points: &Buffer, queries: &[Vec3]) -> Result<Vec<[u32; 2]>> {
        if queries.is_empty() {
            return Ok(Vec::new());
        }
        let q = u32::try_from(queries.len())
            .ok()
            .filter(|&q| q <= MAX_POINTS)
            .ok_or_else(|| Error::Failed(format!("{} query photons; at most {MAX_POINTS} a call", queries.len())))?;
        let bindings = grid_bindings();
        let mut kernel = grid_kernel(ctx, &bindings, PHOTON_GRID_PROBE)?;
        let words: Vec<[f32; 4]> = queries.iter().map(|p| [p.x, p.y, p.z, 0.0]).collect();
        let qbuf = ctx.upload_storage("photon grid queries", bytemuck::cast_slice(&words))?;
        let fbuf = ctx.create_buffer("photon grid found", u64::from(q) * 8, BufferKind::Storage)?;
        let cursor = ctx.create_buffer("photon grid cursor", 4, BufferKind::Storage)?;
        for (binding, buffer) in [
            (BINDING_PHOTON_HEADER, &self.header),
            (BINDING_PHOTON_POINTS, points),
            (BINDING_PHOTON_STARTS, &self.starts),
            (BINDING_PHOTON_CURSOR, &cursor),
            (BINDING_PHOTON_ENTRIES, &self.entries),
            (BINDING_PHOTON_QUERIES, &qbuf),
            (BINDING_PHOTON_FOUND, &fbuf),
        ] {
            ctx.bind(&mut kernel, binding, buffer)?;
        }
        let push = [0, self.points, self.buckets, q];
        ctx.dispatch(&kernel, bytemuck::cast_slice(&push), [q.div_ceil(PHOTON_GROUP), 1, 1], "photon grid: lookups")?;
        ctx.check_validation()?;
        ctx.read_storage_pod(&fbuf, 0, queries.len())
    }

    /// The grid as the host's [`HashGrid`] (each bucket's entries in index order, as
    /// the host build lists them).
    pub fn read_back(&self, ctx: &Context) -> Result<HashGrid> {
        let head: Vec<u32> = ctx.read_storage_pod(&self.header, 0, PHOTON_HDR_WORDS as usize)?;
        let mut starts: Vec<u32> = ctx.read_storage_pod(&self.starts, 0, self.buckets as usize + 1)?;
        let total = head[PHOTON_HDR_TOTAL as usize] as usize;
        let mut entries: Vec<u32> =
            if total == 0 { Vec::new() } else { ctx.read_storage_pod(&self.entries, 0, total)? };
        for b in 0..self.buckets as usize {
            entries[starts[b] as usize..starts[b + 1] as usize].sort_unstable();
        }
        let unorder = |u: u32| f32::from_bits(if u & 0x8000_0000 != 0 { u & 0x7fff_ffff } else { !u });
        let corner = |w: u32| Vec3::from_array([0, 1, 2].map(|a| unorder(head[(w + a) as usize])));
        if self.points == 0 {
            starts = vec![0; 2];
            return Ok(HashGrid { min: Vec3::ZERO, max: Vec3::ZERO, edge: 0.0, res: [1; 3], starts, entries });
        }
        Ok(HashGrid {
            min: corner(PHOTON_HDR_MIN),
            max: corner(PHOTON_HDR_MAX),
            edge: f32::from_bits(head[PHOTON_HDR_EDGE as usize]),
            res: [0, 1, 2].map(|a| head[(PHOTON_HDR_RES + a) as usize]),
            starts,
            entries,
        })
    }
}

// The deepest balanced tree of MAX_POINTS points is the kernel's stack.
const _: () = assert!(usize::BITS - (MAX_POINTS as usize).leading_zeros() == PHOTON_TREE_MAX_DEPTH);

/// Looks up photons at `queries` in `tree` on the device, as the photon pass will
/// (`tree_lookup` in shaders/common/photon_tree.glsl): per photon, the visible points
/// of `points` (the buffer of the points the tree was built over, [`upload_points`])
/// that hold it, and the sum of their indices + 1. For tests and the benchmark.
pub fn tree_lookup_counts(ctx: &Context, tree: &PointTree, points: &Buffer, queries: &[Vec3]) -> Result<Vec<[u32; 2]>> {
    if queries.is_empty() {
        return Ok(Vec::new());
    }
    let nodes = u32::try_from(tree.nodes.len()).ok().filter(|&n| n <= MAX_POINTS);
    let nodes = nodes.ok_or_else(|| Error::Failed(format!("{} tree nodes; at most {MAX_POINTS}", tree.nodes.len())))?;
    let q = u32::try_from(queries.len())
        .ok()
        .filter(|&q| q <= MAX_POINTS)
        .ok_or_else(|| Error::Failed(format!("{} query photons; at most {MAX_POINTS} a call", queries.len())))?;
    let storage = |binding, name| BindingDesc { binding, kind: BindingKind::Storage, name };
    let bindings = [
        storage(BINDING_PHOTON_TREE, "photon tree"),
        storage(BINDING_PHOTON_POINTS, "visible points"),
        storage(BINDING_PHOTON_QUERIES, "photon tree queries"),
        storage(BINDING_PHOTON_FOUND, "photon tree found"),
    ];
    let spv = spirv::get("photon_tree").ok_or_else(|| Error::Failed("kernel photon_tree is not compiled in".into()))?;
    let mut kernel = ctx.create_kernel("photon_tree", spv, &bindings, &[], 16)?;
    let node_bytes: &[u8] = if tree.nodes.is_empty() { &[0; 32] } else { bytemuck::cast_slice(&tree.nodes) };
    let tbuf = ctx.upload_storage("photon tree", node_bytes)?;
    let words: Vec<[f32; 4]> = queries.iter().map(|p| [p.x, p.y, p.z, 0.0]).collect();
    let qbuf = ctx.upload_storage("photon tree queries", bytemuck::cast_slice(&words))?;
    let fbuf = ctx.create_buffer("photon tree found", u64::from(q) * 8, BufferKind::Storage)?;
    for (binding, buffer) in [
        (BINDING_PHOTON_TREE, &tbuf),
        (BINDING_PHOTON_POINTS, points),
        (BINDING_PHOTON_QUERIES, &qbuf),
        (BINDING_PHOTON_FOUND, &fbuf),
    ] {
        ctx.bind(&mut kernel, binding, buffer)?;
    }
    let push = [nodes, q, 0, 0];
    ctx.dispatch(&kernel, bytemuck::cast_slice(&push), [q.div_ceil(PHOTON_GROUP), 1, 1], "photon tree: lookups")?;
    ctx.check_validation()?;
    ctx.read_storage_pod(&fbuf, 0, queries.len())
}
