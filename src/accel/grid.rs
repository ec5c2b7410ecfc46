//! Uniform grid with 3D-DDA traversal (Amanatides & Woo, "A fast voxel traversal
//! algorithm for ray tracing", Eurographics 1987).
//!
//! # Resolution
//!
//! The grid spans the scene box with about `lambda * N` cells (N primitives), shaped
//! to the box: `res[a] = round(extent[a] * k)` with `k = (lambda N / volume)^(1/d)`,
//! where `d` counts the axes that are not flat (an axis shorter than 1e-3 of the
//! longest gets one cell). Each side is capped at [`MAX_RES`], the total at
//! [`GridParams::max_cells`], and a cell is never smaller than 4e-6 of the largest
//! coordinate (about 64 ulps), four times the padding of [`prim::grow`], so that far
//! from the origin cells stay well above float resolution.
//!
//! Degenerate input (co-located or heavily overlapping primitives) would make every
//! primitive reach a share of a grid that grows with N: quadratic references. The
//! (cell, primitive) candidate pairs are capped at [`CANDIDATES_PER_ITEM`] x (N +
//! cells); a grid over it is rebuilt with lambda x 0.7 per step, down to one cell
//! (docs/limits.md, "Builders on degenerate input"). Ordinary scenes stay far below and keep their grid.
//!
//! # Layout (words of `u32`, read by shaders/accel/grid.glsl)
//!
//! ```text
//! words 0..4   res.x, res.y, res.z, number of cells
//! words 4..8   cell size x, y, z (f32 bits), 0
//! words 8..    cell c's primitives are indices[start[c] .. start[c + 1]], where
//!              start = words[8 ..], ncells + 1 entries; c = x + res.x (y + res.y z)
//! ```
//!
//! Worked example: a 2x1x1 grid over [0, 4] x [0, 1] x [0, 1] whose cell 0 holds
//! primitives 3 and 5 and cell 1 holds 5 is `[2, 1, 1, 2, 2.0, 1.0, 1.0, 0, 0, 2, 3]`
//! (floats as their bits) with indices `[3, 5, 5]`. The grid's origin is the scene box
//! minimum (`params.scene_min` in the kernel); boundary `i` of axis `a` is
//! `min[a] + i * size[a]`, computed the same way here and in the kernel.
//!
//! # Insertion and traversal
//!
//! A primitive goes into every cell whose box, grown by [`prim::grow`], it overlaps
//! (exact triangle/box and sphere/box tests). Traversal works in ray parameter t only:
//! the first cell is found by binary search over the boundaries' t values (never from
//! a rounded entry point), and each step moves to the neighbour across the boundary
//! with the smallest t. A hit ends traversal only when it lies before the current
//! cell's exit (by the kd-tree's relative margin); a hit further on is kept as the best
//! so far, which is correct because it is a real hit, and cells after it are skipped.

use super::validate::ValidateError;
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use super::kdtree::{before, shrink};
use super::params::{number, Key, Preset};
use super::prim::{self, PrimGeom};
use super::prim::{intersect_prim, Prims};
use super::sah::{self, SahCosts};
use super::BuildStats;
use crate::math::aabb::FLAT_RCP;
use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

/// 16-byte texel fetches of one cell visit in shaders/accel/grid.glsl: its two range
/// words, `start[c]` and `start[c + 1]`, each a `node_word` fetch.
pub const CELL_TEXELS: u32 = 2;

/// Most cells along one axis.
pub const MAX_RES: u32 = 4096;
/// Insertion tests at most this many (cell, primitive) candidate pairs per primitive
/// and cell: `CANDIDATES_PER_ITEM x (N + cells)`. A grid whose primitives' boxes reach
/// more cells is rebuilt coarser (see `Grid::cap_candidates`), so references, memory
/// and build time stay linear in N + cells.
pub const CANDIDATES_PER_ITEM: u64 = 8;
/// Words before the cell starts in the GPU layout (a `GpuGridHeader`).
pub const HEADER_WORDS: usize = std::mem::size_of::<super::gpu_layout::GpuGridHeader>() / 4;

/// Parameters of the grid builder.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct GridParams {
    /// Cells per primitive (the grid has about `lambda * N` cells).
    pub lambda: f32,
    /// Most cells in all.
    pub max_cells: u64,
}

impl Default for GridParams {
    /// lambda = 2: on lavapipe (100k-triangle blob, 1024x1024 primary rays) it traced
    /// fastest of 0.5, 1, 2, 4 and 8; see docs/grid-octree.md.
    fn default() -> Self {
        GridParams { lambda: 2.0, max_cells: 1 << 24 }
    }
}

/// `--grid`: preset `default`; keys `lambda` (cells per primitive) and `cells` (most
/// cells in all).
impl super::params::Params for GridParams {
    const FLAG: &'static str = "grid";
    const PRESETS: &'static [Preset<Self>] = &[("default", GridParams::default)];
    const KEYS: &'static [Key<Self>] = &[
        Key {
            name: "lambda",
            expects: "a number in (0, 10000]",
            set: |p, v| {
                p.lambda = number(v, f32::MIN_POSITIVE, 1e4)?;
                Some(())
            },
        },
        Key {
            name: "cells",
            expects: "1..=33554432",
            set: |p, v| {
                p.max_cells = number(v, 1, 1 << 25)?;
                Some(())
            },
        },
    ];
}

/// A built uniform grid.
#[derive(Debug, Clone)]
pub struct Grid {
    pub bounds: Aabb,
    pub res: [u32; 3],
    /// Cell size per axis (0 on an axis of zero extent).
    pub cell: Vec3,
    /// Prefix sums: cell c's primitives are `indices[start[c]..start[c + 1]]`.
    pub start: Vec<u32>,
    pub indices: Vec<u32>,
    pub prims: usize,
    pub params: GridParams,
    /// Per axis, in cells: how far outside a primitive's box a cell may still take it
    /// (see `candidates`).
    margin: [f64; 3],
    build_ms: f64,
    phases: Vec<super::Phase>,
}

/// Cells per axis for `n` primitives in `bounds`.
pub fn resolution(bounds: &Aabb, n: usize, params: &GridParams) -> [u32; 3] {
    let e = bounds.extent();
    let longest = e.max_element();
    if n == 0 || bounds.is_empty() || !longest.is_finite() || longest <= 0.0 {
        return [1, 1, 1];
    }
    let active: Vec<usize> = (0..3).filter(|&a| e[a] > longest * 1e-3).collect();
    let volume: f64 = active.iter().map(|&a| f64::from(e[a])).product();
    let target = (f64::from(params.lambda) * n as f64).clamp(1.0, params.max_cells as f64);
    let mag = bounds.min.abs().max(bounds.max.abs()).max_element();
    let min_cell = f64::from(mag) * 4e-6;
    let mut k = (target / volume).powf(1.0 / active.len() as f64);
    loop {
        let mut res = [1u32; 3];
        for &a in &active {
            let mut r = (f64::from(e[a]) * k).round().clamp(1.0, f64::from(MAX_RES));
            if min_cell > 0.0 {
                r = r.min((f64::from(e[a]) / min_cell).floor().max(1.0));
            }
            res[a] = r as u32;
        }
        if res.iter().map(|&r| u64::from(r)).product::<u64>() <= params.max_cells {
            return res;
        }
        k *= 0.95;
    }
}

impl Grid {
    /// Builds the grid of `scene`.
    pub fn build(scene: &Scene, params: &GridParams) -> Grid {
        let start_time = Instant::now();
        let mut t = Instant::now();
        let mut phases = Vec::new();
        let bounds = scene.bounds();
        let n = scene.prim_count();
        let mut g = Grid::empty(bounds, resolution(&bounds, n, params), n, params);
        g.cap_candidates(scene);
        // (cell, primitive) pairs, in primitive order, from chunks in parallel.
        let pairs: Vec<Vec<(u32, u32)>> = (0..n as u32)
            .collect::<Vec<_>>()
            .par_chunks(4096)
            .map(|chunk| {
                let mut out = Vec::with_capacity(chunk.len() * 2);
                for &p in chunk {
                    g.insert(&prim::geom(scene, p), p, &mut out);
                }
                out
            })
            .collect();
        super::bvh::lap(&mut phases, "insert", &mut t);
        // Counting sort by cell, stable: each cell's list stays ascending.
        let ncells = g.cell_count();
        let mut count = vec![0u32; ncells + 1];
        for &(c, _) in pairs.iter().flatten() {
            count[c as usize + 1] += 1;
        }
        for c in 0..ncells {
            count[c + 1] += count[c];
        }
        let total = count[ncells] as usize;
        let mut fill = count.clone();
        let mut indices = vec![0u32; total];
        for &(c, p) in pairs.iter().flatten() {
            let slot = &mut fill[c as usize];
            indices[*slot as usize] = p;
            *slot += 1;
        }
        g.start = count;
        g.indices = indices;
        super::bvh::lap(&mut phases, "sort", &mut t);
        g.phases = phases;
        g.build_ms = start_time.elapsed().as_secs_f64() * 1e3;
        g
    }

    /// A grid of resolution `res` over `bounds` with no cells filled yet.
    fn empty(bounds: Aabb, res: [u32; 3], n: usize, params: &GridParams) -> Grid {
        let cell =
            if n == 0 { Vec3::ZERO } else { bounds.extent() / Vec3::new(res[0] as f32, res[1] as f32, res[2] as f32) };
        let mut g = Grid {
            bounds,
            res,
            cell,
            start: Vec::new(),
            indices: Vec::new(),
            prims: n,
            params: *params,
            margin: [0.0; 3],
            build_ms: 0.0,
            phases: Vec::new(),
        };
        // Candidate cells reach the grown boxes' pad (1e-5 of a cell plus 1e-6 of the
        // coordinates) and a hundredth of a cell for rounding.
        let mag = f64::from(bounds.min.abs().max(bounds.max.abs()).max_element());
        for a in 0..3 {
            if cell[a] > 0.0 {
                g.margin[a] = 0.01 + 1e-5 + mag * 1e-6 / f64::from(cell[a]);
            }
        }
        g
    }

    /// Most (cell, primitive) candidate pairs insertion may test: see [`CANDIDATES_PER_ITEM`].
    pub fn candidate_budget(&self) -> u64 {
        CANDIDATES_PER_ITEM * (self.prims as u64 + self.cell_count() as u64)
    }

    /// Whether the candidate cells of primitives with boxes `boxes` number at most
    /// the budget (stops counting once over).
    fn within_budget(&self, boxes: &[Aabb]) -> bool {
        let budget = self.candidate_budget();
        let mut total = 0u64;
        for b in boxes {
            let (lo, hi) = self.candidates(b);
            total += (0..3).map(|a| u64::from(hi[a] - lo[a] + 1)).product::<u64>();
            if total > budget {
                return false;
            }
        }
        true
    }

    /// Lowers the resolution (lambda x 0.7 per step, down to one cell) until the
    /// candidate pairs fit the budget. Ordinary scenes use a few candidates per
    /// primitive and never get here; co-located or overlapping primitives would
    /// otherwise each fill a share of a grid that grows with N (quadratic).
    fn cap_candidates(&mut self, scene: &Scene) {
        let n = self.prims;
        if n == 0 {
            return;
        }
        let boxes: Vec<Aabb> = (0..n as u32).into_par_iter().map(|p| prim::bounds(&prim::geom(scene, p))).collect();
        let mut params = self.params;
        while !self.within_budget(&boxes) && self.res != [1, 1, 1] {
            params.lambda *= 0.7;
            let mut res = resolution(&self.bounds, n, &params);
            if res.iter().map(|&r| u64::from(r)).product::<u64>() >= self.cell_count() as u64 {
                res = [1, 1, 1];
            }
            *self = Grid::empty(self.bounds, res, n, &self.params);
        }
    }

    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.res.iter().map(|&r| r as usize).product()
    }

    /// Coordinate of boundary `i` on `axis` (boundary 0 is the box minimum).
    #[inline]
    pub fn boundary(&self, axis: usize, i: u32) -> f32 {
        self.bounds.min[axis] + i as f32 * self.cell[axis]
    }

    /// The box of cell (x, y, z).
    pub fn cell_box(&self, c: [u32; 3]) -> Aabb {
        let lo = Vec3::new(self.boundary(0, c[0]), self.boundary(1, c[1]), self.boundary(2, c[2]));
        let hi = Vec3::new(self.boundary(0, c[0] + 1), self.boundary(1, c[1] + 1), self.boundary(2, c[2] + 1));
        Aabb { min: lo, max: hi }
    }

    fn cell_index(&self, c: [u32; 3]) -> usize {
        c[0] as usize + self.res[0] as usize * (c[1] as usize + self.res[1] as usize * c[2] as usize)
    }

    /// Appends (cell, p) for every cell whose grown box `g` overlaps.
    fn insert(&self, g: &PrimGeom, p: u32, out: &mut Vec<(u32, u32)>) {
        let (lo, hi) = self.candidates(&prim::bounds(g));
        let single = lo == hi;
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let c = [x, y, z];
                    if single || prim::overlaps(g, &prim::grow(&self.cell_box(c))) {
                        out.push((self.cell_index(c) as u32, p));
                    }
                }
            }
        }
    }

    /// The range of cells whose grown boxes a primitive with bounds `b` may overlap.
    fn candidates(&self, b: &Aabb) -> ([u32; 3], [u32; 3]) {
        let mut lo = [0u32; 3];
        let mut hi = [0u32; 3];
        for a in 0..3 {
            if self.cell[a] > 0.0 {
                let m = self.margin[a];
                let f = |x: f32| f64::from(x - self.bounds.min[a]) / f64::from(self.cell[a]);
                let last = f64::from(self.res[a] - 1);
                lo[a] = (f(b.min[a]) - m).floor().clamp(0.0, last) as u32;
                hi[a] = (f(b.max[a]) + m).floor().clamp(0.0, last) as u32;
            }
        }
        (lo, hi)
    }

    /// Bytes as uploaded: header, cell starts, indices.
    pub fn bytes(&self) -> u64 {
        ((HEADER_WORDS + self.start.len() + self.indices.len()) * 4) as u64
    }

    /// Build time and phases (what [`Self::stats`] reports of them, without the rest).
    pub fn timing(&self) -> (f64, Vec<super::Phase>) {
        (self.build_ms, self.phases.clone())
    }

    /// Statistics for `arbor info` and the stats JSON; a cell counts as a leaf.
    pub fn stats(&self) -> BuildStats {
        let ncells = self.cell_count();
        let costs = SahCosts::default();
        let root = sah::area(&self.bounds).max(f32::MIN_POSITIVE) as f64;
        let cell_area = if ncells > 0 {
            let c = self.cell;
            2.0 * f64::from(c.x * c.y + c.y * c.z + c.z * c.x) / root
        } else {
            0.0
        };
        let refs = self.indices.len() as u64;
        let empty = (0..ncells).filter(|&c| self.start[c] == self.start[c + 1]).count() as u64;
        // Every cell is a traversal step weighted by its area; primitives as in a leaf.
        let cost = cell_area * (ncells as f64 * f64::from(costs.traversal) + refs as f64 * f64::from(costs.intersect));
        BuildStats {
            kind: "grid".into(),
            build_ms: self.build_ms,
            bytes: self.bytes(),
            nodes: ncells as u64,
            max_depth: 0,
            leaves: ncells as u64,
            empty_leaves: empty,
            mean_leaf_depth: 0.0,
            refs_per_prim: refs as f64 / self.prims.max(1) as f64,
            prims_per_leaf: refs as f64 / (ncells as u64 - empty).max(1) as f64,
            sah_cost: cost,
            phases: self.phases.clone(),
            resolution: Some(self.res),
            levels: None,
            opaque: None,
            on_device: None,
        }
    }

    /// Checks the invariants: prefix sums ascending and complete, indices valid and
    /// ascending per cell, and every primitive listed in every cell whose box (shrunk
    /// by a relative 1e-5, so touching a face does not count) it overlaps.
    pub fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        let ncells = self.cell_count();
        if self.res.iter().any(|&r| r == 0 || r > MAX_RES) {
            return Err(ValidateError::whole(format!("resolution {:?} outside 1..={MAX_RES}", self.res)));
        }
        if self.start.len() != ncells + 1 || self.start[0] != 0 {
            return Err(ValidateError::whole(format!("{} cell starts for {ncells} cells", self.start.len())));
        }
        if self.start.windows(2).any(|w| w[0] > w[1]) || self.start[ncells] as usize != self.indices.len() {
            return Err(ValidateError::whole("cell starts are not ascending prefix sums of the index array"));
        }
        let np = scene.prim_count() as u32;
        for c in 0..ncells {
            let list = &self.indices[self.start[c] as usize..self.start[c + 1] as usize];
            if let Some(bad) = list.iter().find(|&&p| p >= np) {
                return Err(ValidateError::cell(c, format!("references primitive {bad} of {np}")));
            }
            if list.windows(2).any(|w| w[0] >= w[1]) {
                return Err(ValidateError::cell(c, "primitive list not strictly ascending"));
            }
        }
        if np > 0 && (self.bounds.is_empty() || !self.bounds.min.is_finite() || !self.bounds.max.is_finite()) {
            return Err(ValidateError::whole(format!("grid box {:?} is empty or not finite", self.bounds)));
        }
        let missing = (0..np).into_par_iter().find_map_first(|p| {
            let g = prim::geom(scene, p);
            let b = prim::bounds(&g);
            // Every cell the primitive's box touches (candidates() is a superset).
            let (lo, hi) = self.candidates(&b);
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let cb = self.cell_box([x, y, z]);
                        if cb.max.cmplt(b.min).any() || cb.min.cmpgt(b.max).any() {
                            continue;
                        }
                        let inner = shrink(&cb);
                        if inner.is_empty() || !prim::overlaps(&g, &inner) {
                            continue;
                        }
                        let c = self.cell_index([x, y, z]);
                        let list = &self.indices[self.start[c] as usize..self.start[c + 1] as usize];
                        if list.binary_search(&p).is_err() {
                            return Some(ValidateError::prim(
                                p,
                                format!("overlaps cell {c} ({cb:?}) but is not in it"),
                            ));
                        }
                    }
                }
            }
            None
        });
        match missing {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// 3D-DDA in ray parameter t; see the module doc. Twin of `grid_traverse`.
    fn traverse_impl(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        if self.prims == 0 {
            return false;
        }
        let inv = Aabb::inv_dir(ray.dir);
        let Some((t_enter, _)) = self.bounds.ray_box(ray.origin, inv, ray.tmin, ray.tmax) else {
            return false;
        };
        let o = ray.origin.to_array();
        let iv = inv.to_array();
        let tb = |a: usize, k: u32| (self.boundary(a, k) - o[a]) * iv[a];
        let mut idx = [0u32; 3];
        let mut t_next = [f32::INFINITY; 3];
        for a in 0..3 {
            let flat = iv[a].abs() >= FLAT_RCP;
            // The ray at t_enter lies at or above boundary k (monotone: true up to the
            // cell it is in). Boundary 0 always counts as below.
            let above = |k: u32| {
                if flat {
                    self.boundary(a, k) <= o[a]
                } else if iv[a] > 0.0 {
                    tb(a, k) <= t_enter
                } else {
                    tb(a, k) > t_enter
                }
            };
            let (mut lo, mut hi) = (0u32, self.res[a] - 1);
            while lo < hi {
                let mid = (lo + hi).div_ceil(2);
                if above(mid) {
                    lo = mid;
                } else {
                    hi = mid - 1;
                }
            }
            idx[a] = lo;
            if !flat {
                t_next[a] = if iv[a] > 0.0 { tb(a, lo + 1) } else { tb(a, lo) };
            }
        }
        let mut found = false;
        loop {
            let c = self.cell_index(idx);
            for &p in &self.indices[self.start[c] as usize..self.start[c + 1] as usize] {
                if intersect_prim(prims, p, ray, best) {
                    found = true;
                    if any {
                        return true;
                    }
                }
            }
            // The axis whose boundary comes first (x, then y, then z on ties).
            let mut a = 0;
            if t_next[1] < t_next[a] {
                a = 1;
            }
            if t_next[2] < t_next[a] {
                a = 2;
            }
            let t_exit = t_next[a];
            if before(best.t, t_exit) || t_exit == f32::INFINITY {
                return found;
            }
            if iv[a] > 0.0 {
                idx[a] += 1;
                if idx[a] >= self.res[a] {
                    return found;
                }
                t_next[a] = tb(a, idx[a] + 1);
            } else {
                if idx[a] == 0 {
                    return found;
                }
                idx[a] -= 1;
                t_next[a] = tb(a, idx[a]);
            }
        }
    }

    /// The words the kernel reads (see the module doc) and the index array.
    pub fn to_gpu(&self) -> (Vec<u32>, &[u32]) {
        let head = super::gpu_layout::GpuGridHeader {
            res: [self.res[0], self.res[1], self.res[2], self.cell_count() as u32],
            cell: [self.cell.x, self.cell.y, self.cell.z, 0.0],
        };
        let mut words = Vec::with_capacity(HEADER_WORDS + self.start.len());
        words.extend_from_slice(bytemuck::cast_slice(bytemuck::bytes_of(&head)));
        words.extend_from_slice(&self.start);
        (words, &self.indices)
    }
}

impl super::Traverse for Grid {
    fn traverse(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        self.traverse_impl(prims, ray, best, any)
    }
}

impl super::Structure for Grid {
    fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        Grid::validate(self, scene)
    }
    fn stats(&self, _scene: &Scene) -> BuildStats {
        Grid::stats(self)
    }
    fn timing(&self) -> (f64, Vec<super::Phase>) {
        Grid::timing(self)
    }
    fn bounds(&self) -> Aabb {
        self.bounds
    }
    fn gpu_image(&self, _scene: &Scene) -> Result<super::GpuImage<'_>, ValidateError> {
        let (words, indices) = self.to_gpu();
        Ok(super::GpuImage {
            family: super::KernelFamily::Grid,
            buffers: Some(crate::accel::AccelBuffers::Host(
                std::borrow::Cow::Owned(bytemuck::cast_slice(&words).to_vec()),
                indices,
            )),
            stack_size: 1,
            // About half the cells along the diagonal, a few primitives each.
            cost_per_ray: self.res.iter().map(|&r| u64::from(r)).sum::<u64>() + 16,
            trace_loop: super::TraceLoop::StepBudget,
            ray_structure: None,
            resume_words: super::resume_words(1, 1),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolution_follows_lambda_and_the_box_shape() {
        let b = Aabb { min: Vec3::ZERO, max: Vec3::new(4.0, 2.0, 1.0) };
        let r = resolution(&b, 1000, &GridParams { lambda: 8.0, ..Default::default() });
        // 8000 cells on a 4 x 2 x 1 box: k^3 * 8 = 8000, so k = 10.
        assert_eq!(r, [40, 20, 10]);
        let flat = Aabb { min: Vec3::ZERO, max: Vec3::new(10.0, 10.0, 0.0) };
        let r = resolution(&flat, 100, &GridParams { lambda: 1.0, ..Default::default() });
        assert_eq!(r, [10, 10, 1]);
        let near = Aabb { min: Vec3::splat(1e3), max: Vec3::splat(1e3 + 1.0) };
        let r = resolution(&near, 1_000_000, &GridParams::default());
        assert_eq!(r, [126, 126, 126], "cbrt(2e6) = 126 cells of 0.008, above 4e-6 x 1001");
        let far = Aabb { min: Vec3::splat(1e5), max: Vec3::splat(1e5 + 1.0) };
        let r = resolution(&far, 1_000_000, &GridParams::default());
        assert_eq!(r, [2, 2, 2], "cells stay above 4e-6 of the coordinates: 0.4");
    }
}
