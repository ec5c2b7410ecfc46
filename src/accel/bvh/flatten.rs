//! The flattener: a canonical tree ([`Nodes`]: a `Binary`, or the tree being
//! restructured) into the GPU layout (see the `bvh` module docs), depth first, left
//! child first.
//!
//! A large tree is flattened in parallel, with the same result word for word:
//!
//! 1. The subtrees [`SPLIT_LEVELS`] levels below the root become parts. Each part is
//!    flattened by its own task, with its nodes and indices numbered from zero.
//! 2. One serial pass flattens the nodes above the parts. Where a part belongs it
//!    leaves a hole of the part's size, so every position it writes is final.
//! 3. The output is allocated zeroed (no pages touched yet) and filled in parallel:
//!    each part is copied into its hole with its references moved by the hole's
//!    place, and the serial pass's runs between the holes are copied as they are.

use glam::Vec3;
use rayon::prelude::*;

use super::{GpuBvhNode, Nodes, PrimRefs, EMPTY_REF, LEAF_REF, MAX_LEAF};
use crate::math::Aabb;

/// Levels below the root whose subtrees are flattened as parallel parts (at most
/// 2^5 parts: enough for two threads to balance uneven subtrees).
const SPLIT_LEVELS: u32 = 5;
/// Trees of fewer primitives are flattened in one serial pass.
const PAR_MIN_PRIMS: usize = 1 << 14;

/// Flattens `bin`: (nodes, indices, depth). An inner node `bin` says is collapsed
/// ([`Nodes::collapsed`]) becomes a leaf of its subtree's primitives.
pub(super) fn flatten(bin: &impl Nodes, refs: &PrimRefs) -> (Vec<GpuBvhNode>, Vec<u32>, u32) {
    let (nodes, indices, depth, _) = flatten_from(bin, refs, PAR_MIN_PRIMS);
    (nodes, indices, depth)
}

/// [`flatten`], in parts from `par_min_prims` primitives on; also the number of parts.
fn flatten_from(bin: &impl Nodes, refs: &PrimRefs, par_min_prims: usize) -> (Vec<GpuBvhNode>, Vec<u32>, u32, usize) {
    let root = bin.root();
    let mut roots = Vec::new();
    if refs.len() >= par_min_prims && is_open(bin, root) {
        let node = bin.node(root);
        for c in [node.left, node.right] {
            part_roots(bin, c, 1, 1, &mut roots);
        }
    }
    // An even share; a larger part grows its vectors (large ones move by remapping).
    let share = refs.len() / roots.len().max(1) + 1;
    let parts: Vec<Part> = roots
        .par_iter()
        .map(|&(n, depth)| {
            let mut f = Flattener::new(bin, refs, share);
            let (_, bounds) = f.emit(Child::Node(n), depth);
            Part { nodes: f.nodes, indices: f.indices, bounds, depth: f.depth }
        })
        .collect();

    let mut f = Flattener::new(bin, refs, if roots.is_empty() { refs.len() } else { 64 });
    f.parts = roots.iter().map(|r| r.0).zip(parts.iter().map(|p| (p.nodes.len(), p.indices.len(), p.bounds))).collect();
    // The root is always an inner node; a one-leaf tree gets an empty sibling.
    match f.child(root) {
        Child::Node(n) => {
            let node = bin.node(n);
            let l = f.child(node.left);
            let r = f.child(node.right);
            f.emit_inner(l, r, 1);
        }
        leaf => {
            f.emit_inner(leaf, Child::Owned(Vec::new()), 1);
        }
    }
    let depth = parts.iter().fold(f.depth, |d, p| d.max(p.depth));
    if f.holes.is_empty() {
        return (f.nodes, f.indices, depth, 0);
    }
    let (nodes, indices) = assemble(&f, &parts);
    (nodes, indices, depth, parts.len())
}

/// Whether `n` is an inner node the flattener keeps (not a leaf, not collapsed).
fn is_open(bin: &impl Nodes, n: u32) -> bool {
    !bin.node(n).is_leaf() && !bin.collapsed(n)
}

/// Collects the part roots below `n` (a child of a node at `depth`, at `level` below
/// the root) as (node, depth of its parent).
fn part_roots(bin: &impl Nodes, n: u32, depth: u32, level: u32, out: &mut Vec<(u32, u32)>) {
    if !is_open(bin, n) {
        return;
    }
    if level == SPLIT_LEVELS {
        out.push((n, depth));
        return;
    }
    let node = bin.node(n);
    for c in [node.left, node.right] {
        part_roots(bin, c, depth + 1, level + 1, out);
    }
}

/// A subtree flattened on its own, its references numbered from zero.
struct Part {
    nodes: Vec<GpuBvhNode>,
    indices: Vec<u32>,
    bounds: Aabb,
    depth: u32,
}

/// Where a part goes: after this many nodes and indices of the serial pass.
struct Hole {
    part: usize,
    nodes: usize,
    indices: usize,
}

/// Fills the output from the serial pass `f` and the parts (see the module docs).
fn assemble<T: Nodes>(f: &Flattener<T>, parts: &[Part]) -> (Vec<GpuBvhNode>, Vec<u32>) {
    let mut nodes = vec![[[0u32; 4]; 4]; f.nodes.len() + f.skipped_nodes];
    let mut indices = vec![0u32; f.indices.len() + f.skipped_indices];
    // Jobs in output order: a run of the serial pass, then a part, and so on.
    enum Src<'a> {
        Run(&'a [GpuBvhNode], &'a [u32]),
        Part(&'a Part, u32, u32),
    }
    let mut jobs: Vec<(&mut [GpuBvhNode], &mut [u32], Src)> = Vec::with_capacity(2 * f.holes.len() + 1);
    let (mut rest_n, mut rest_i): (&mut [GpuBvhNode], &mut [u32]) = (&mut nodes, &mut indices);
    let (mut at_n, mut at_i, mut out_n, mut out_i) = (0, 0, 0, 0);
    for h in f.holes.iter().map(Some).chain([None]) {
        let (end_n, end_i) = h.map_or((f.nodes.len(), f.indices.len()), |h| (h.nodes, h.indices));
        let (dn, tn) = std::mem::take(&mut rest_n).split_at_mut(end_n - at_n);
        let (di, ti) = std::mem::take(&mut rest_i).split_at_mut(end_i - at_i);
        jobs.push((dn, di, Src::Run(&f.nodes[at_n..end_n], &f.indices[at_i..end_i])));
        (out_n, out_i) = (out_n + end_n - at_n, out_i + end_i - at_i);
        (at_n, at_i) = (end_n, end_i);
        (rest_n, rest_i) = (tn, ti);
        if let Some(h) = h {
            let p = &parts[h.part];
            let (pn, tn) = std::mem::take(&mut rest_n).split_at_mut(p.nodes.len());
            let (pi, ti) = std::mem::take(&mut rest_i).split_at_mut(p.indices.len());
            jobs.push((pn, pi, Src::Part(p, out_n as u32, out_i as u32)));
            (out_n, out_i) = (out_n + p.nodes.len(), out_i + p.indices.len());
            (rest_n, rest_i) = (tn, ti);
        }
    }
    jobs.into_par_iter().for_each(|(dn, di, src)| match src {
        Src::Run(n, i) => {
            dn.copy_from_slice(n);
            di.copy_from_slice(i);
        }
        Src::Part(p, nb, ib) => {
            let moved = |r: u32| match r {
                EMPTY_REF => r,
                r if r & LEAF_REF != 0 => r + (ib << 3),
                r => r + nb,
            };
            for (d, s) in dn.iter_mut().zip(&p.nodes) {
                *d = *s;
                d[0][3] = moved(s[0][3]);
                d[1][3] = moved(s[1][3]);
            }
            di.copy_from_slice(&p.indices);
        }
    });
    (nodes, indices)
}

/// A child on its way into the GPU layout.
enum Child {
    Node(u32),
    /// A leaf of the canonical tree or a collapsed subtree: a range of `Binary::prims`
    /// (collapsed subtrees are gathered into `Flattener::gathered` first) and its box.
    Range(usize, usize, Aabb, bool),
    /// An oversized leaf being split.
    Owned(Vec<u32>),
}

struct Flattener<'a, T: Nodes> {
    bin: &'a T,
    refs: &'a PrimRefs,
    nodes: Vec<GpuBvhNode>,
    indices: Vec<u32>,
    gathered: Vec<u32>,
    depth: u32,
    /// Subtrees flattened as parts: root node, then the part's nodes, indices, box.
    parts: Vec<(u32, (usize, usize, Aabb))>,
    holes: Vec<Hole>,
    /// Nodes and indices in the holes so far: a position in `nodes` (`indices`) plus
    /// these is a position in the output.
    skipped_nodes: usize,
    skipped_indices: usize,
}

impl<'a, T: Nodes> Flattener<'a, T> {
    fn new(bin: &'a T, refs: &'a PrimRefs, capacity: usize) -> Self {
        Flattener {
            bin,
            refs,
            nodes: Vec::with_capacity(capacity),
            indices: Vec::with_capacity(capacity),
            gathered: Vec::new(),
            depth: 0,
            parts: Vec::new(),
            holes: Vec::new(),
            skipped_nodes: 0,
            skipped_indices: 0,
        }
    }

    fn child(&mut self, n: u32) -> Child {
        let node = self.bin.node(n);
        if node.is_leaf() {
            let r = node.range();
            return Child::Range(r.start, r.len(), node.bounds, false);
        }
        if self.bin.collapsed(n) {
            let start = self.gathered.len();
            let mut list = std::mem::take(&mut self.gathered);
            self.bin.gather_small(n, &mut list);
            self.gathered = list;
            return Child::Range(start, self.gathered.len() - start, node.bounds, true);
        }
        Child::Node(n)
    }

    /// Output position of the next index.
    fn next_index(&self) -> u32 {
        (self.indices.len() + self.skipped_indices) as u32
    }

    /// Writes a leaf of `list` (at most MAX_LEAF primitives); returns its reference.
    fn leaf(&mut self, list: &[u32]) -> u32 {
        let first = self.next_index();
        self.indices.extend_from_slice(list);
        LEAF_REF | (first << 3) | (list.len() as u32 - 1)
    }

    /// Emits `c` below an inner node at `depth`: its reference and box.
    fn emit(&mut self, c: Child, depth: u32) -> (u32, Aabb) {
        match c {
            Child::Range(_, 0, _, _) => (EMPTY_REF, Aabb::EMPTY),
            Child::Range(start, len, b, gathered) if len <= MAX_LEAF => {
                let first = self.next_index();
                let src = if gathered { &self.gathered } else { self.bin.prims() };
                self.indices.extend_from_slice(&src[start..start + len]);
                (LEAF_REF | (first << 3) | (len as u32 - 1), b)
            }
            Child::Range(start, len, _, gathered) => {
                let src = if gathered { &self.gathered } else { self.bin.prims() };
                self.emit(Child::Owned(src[start..start + len].to_vec()), depth)
            }
            Child::Owned(list) if list.is_empty() => (EMPTY_REF, Aabb::EMPTY),
            Child::Owned(list) if list.len() <= MAX_LEAF => (self.leaf(&list), self.refs.union(&list)),
            Child::Owned(mut list) => {
                // Too many for one leaf (identical centroids, or the builder's depth
                // limit): split at the median centroid of the widest axis.
                let cb = list.iter().fold(Aabb::EMPTY, |mut b, &p| {
                    b.grow(self.refs.centroids[p as usize]);
                    b
                });
                let axis = cb.extent().max_position();
                list.sort_by(|&a, &b| {
                    let (ca, cb) = (self.refs.centroids[a as usize][axis], self.refs.centroids[b as usize][axis]);
                    ca.total_cmp(&cb).then(a.cmp(&b))
                });
                let right = list.split_off(list.len() / 2);
                self.emit_inner(Child::Owned(list), Child::Owned(right), depth + 1)
            }
            Child::Node(n) => {
                if let Some(k) = self.parts.iter().position(|p| p.0 == n) {
                    return self.hole(k);
                }
                let node = self.bin.node(n);
                let l = self.child(node.left);
                let r = self.child(node.right);
                self.emit_inner(l, r, depth + 1)
            }
        }
    }

    /// Leaves room for part `k`: its root's reference and its box.
    fn hole(&mut self, k: usize) -> (u32, Aabb) {
        let (nodes, indices, bounds) = self.parts[k].1;
        let at = self.nodes.len() + self.skipped_nodes;
        self.holes.push(Hole { part: k, nodes: self.nodes.len(), indices: self.indices.len() });
        self.skipped_nodes += nodes;
        self.skipped_indices += indices;
        (at as u32, bounds)
    }

    /// Emits an inner node at `depth` (1 = root) with children `l`, `r`.
    fn emit_inner(&mut self, l: Child, r: Child, depth: u32) -> (u32, Aabb) {
        self.depth = self.depth.max(depth);
        let slot = self.nodes.len();
        let me = slot + self.skipped_nodes;
        self.nodes.push([[0; 4]; 4]);
        let (lref, lbox) = self.emit(l, depth);
        let (rref, rbox) = self.emit(r, depth);
        let bits = |v: Vec3, w: u32| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits(), w];
        let (lbox_g, rbox_g) = (gpu_box(&lbox), gpu_box(&rbox));
        self.nodes[slot] = [bits(lbox_g.min, lref), bits(lbox_g.max, rref), bits(rbox_g.min, 0), bits(rbox_g.max, 0)];
        (me as u32, lbox.union(&rbox))
    }
}

/// Empty boxes are stored as zeros (the kernel checks the reference first).
fn gpu_box(b: &Aabb) -> Aabb {
    if b.is_empty() {
        Aabb { min: Vec3::ZERO, max: Vec3::ZERO }
    } else {
        *b
    }
}

#[cfg(test)]
mod tests {
    use super::super::{binned, lbvh, treelet, PrimRefs};
    use super::*;
    use crate::accel::sah::SahCosts;

    /// `n` boxes scattered by a fixed generator; with `same`, every centroid at the
    /// origin (so leaves overflow and the flattener splits them).
    fn boxes(n: usize, same: bool) -> PrimRefs {
        let mut s = 12345u32;
        let mut next = || {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (s >> 8) as f32 / (1u32 << 24) as f32
        };
        let bounds: Vec<Aabb> = (0..n)
            .map(|_| {
                let c = if same { Vec3::ZERO } else { Vec3::new(next(), next(), next()) * 100.0 };
                let h = Vec3::new(next(), next(), next()) + 0.01;
                Aabb { min: c - h, max: c + h }
            })
            .collect();
        let centroids = bounds.iter().map(|b| (b.min + b.max) * 0.5).collect();
        PrimRefs { bounds, centroids }
    }

    /// The test inputs: (primitives, every centroid the same, boxes) for 0 to 20,000
    /// primitives.
    fn cases() -> impl Iterator<Item = (usize, bool, PrimRefs)> {
        [0, 1, 2, 3, 40, 3000, 20_000].into_iter().flat_map(|n| [false, true].map(|same| (n, same, boxes(n, same))))
    }

    /// The climb that builds trbvh's LBVH straight into the restructuring's nodes
    /// (Apetrei's order) gives Karras's tree node for node, fitted, with the same
    /// costs, and the same tree after three rounds; also for 0 to 3 primitives and
    /// when every centroid (so every Morton code) is the same.
    #[test]
    fn climbed_lbvh_equals_karras() {
        let costs = SahCosts::default();
        for (n, same, refs) in cases() {
            let (mut phases, mut t) = (Vec::new(), std::time::Instant::now());
            let mut climbed = treelet::Restructure::lbvh(&refs, &costs, 7, &mut phases, &mut t);
            let karras = lbvh::build_fitted(&refs, &mut phases, &mut t);
            let mut fitted = treelet::Restructure::with_leaves(&karras, &costs, 7);
            for round in 0..=3 {
                let at = format!("{n} primitives, same {same}, after {round} rounds");
                assert_eq!(climbed.root(), fitted.root(), "{at}");
                assert_eq!(climbed.prims(), fitted.prims(), "{at}");
                assert_eq!(climbed.root_cost().to_bits(), fitted.root_cost().to_bits(), "{at}");
                for i in 0..karras.nodes.len() as u32 {
                    assert_eq!(climbed.node(i), fitted.node(i), "node {i}, {at}");
                }
                if round < 3 {
                    climbed.round(treelet::gamma(round));
                    fitted.round(treelet::gamma(round));
                }
            }
        }
    }

    /// Flattening in parts gives the serial pass's layout word for word: for the LBVH,
    /// the binned SAH tree, and the restructured tree with its collapsed subtrees.
    #[test]
    fn parts_give_the_serial_layout_word_for_word() {
        let costs = SahCosts::default();
        for (n, same, refs) in cases() {
            let (mut phases, mut t) = (Vec::new(), std::time::Instant::now());
            let fitted = lbvh::build_fitted(&refs, &mut phases, &mut t);
            let mut work = treelet::Restructure::with_leaves(&fitted, &costs, 7);
            for round in 0..3 {
                work.round(treelet::gamma(round));
            }
            let what = |name: &str| format!("{name}, {n} boxes, same centroids {same}");
            same_in_parts(&lbvh::build(&refs, &mut phases, &mut t), &refs, &what("lbvh"));
            same_in_parts(&binned::build(&refs, &costs), &refs, &what("bvh-sah"));
            same_in_parts(&work, &refs, &what("trbvh"));
            if n >= 3000 && same {
                assert!((0..2 * n as u32 - 1).any(|i| work.collapsed(i)), "{}: nothing collapsed", what("trbvh"));
            }
        }
    }

    fn same_in_parts(bin: &impl Nodes, refs: &PrimRefs, what: &str) {
        let serial = flatten_from(bin, refs, usize::MAX);
        let parts = flatten_from(bin, refs, 0);
        assert_eq!(serial.3, 0, "{what}");
        assert!(refs.len() < 3000 || parts.3 >= 8, "{what}: {} parts", parts.3);
        assert!(serial.0 == parts.0 && serial.1 == parts.1 && serial.2 == parts.2, "{what}");
    }
}
