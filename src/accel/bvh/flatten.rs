//! The flattener: a canonical tree ([`Nodes`]: a `Binary`, or the tree being
//! restructured) into the GPU layout (see the `bvh` module docs), depth first, left
//! child first.
//!
//! A large tree is flattened in parallel, with the same result word for word:
//!
//! 1. The subtrees [`SPLIT_LEVELS`] levels below the root become parts.
//! 2. Where the tree knows each part's size without a walk ([`Nodes::emitted`]: the
//!    LBVH, whose leaves hold one primitive each in key order), the output is
//!    allocated zeroed (no pages touched yet). A serial pass over the nodes above the
//!    parts finds where each part's hole goes, each part is flattened by its own task
//!    straight into its hole, and the serial pass runs again with the parts' boxes.
//!    Every node and index below the top levels is written once, in its final place.
//! 3. Otherwise each part is first flattened by its own task into vectors of its own,
//!    numbered from zero; the serial pass leaves holes of their sizes; then the output
//!    is filled in parallel: each part is copied into its hole with its references
//!    moved by the hole's place, and the serial pass's runs between the holes are
//!    copied as they are. (The parts' vectors are fresh memory: about 64 MB at a
//!    million primitives, which a first build faults in page by page.)

use glam::Vec3;
use rayon::prelude::*;

use super::{leaf_ref, GpuBvhNode, Nodes, PrimRefs, EMPTY_REF, LEAF_REF, MAX_LEAF};
use crate::gpu::bindings::BVH_LEAF_COUNT_BITS;
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
    if !roots.is_empty() {
        let sizes: Option<Vec<(usize, usize)>> = roots.iter().map(|r| bin.emitted(r.0)).collect();
        if let (Some(total), Some(sizes)) = (bin.emitted(root), sizes) {
            return flatten_in_place(bin, refs, &roots, &sizes, total);
        }
    }
    // An even share; a larger part grows its vectors (large ones move by remapping).
    let share = refs.len() / roots.len().max(1) + 1;
    let parts: Vec<Part> = roots
        .par_iter()
        .map(|&(n, depth)| {
            let mut f = Flattener::new(bin, refs, Sink::owned(share), Sink::owned(share));
            let (_, bounds) = f.emit(Child::Node(n), depth);
            Part { nodes: f.nodes.into_vec(), indices: f.indices.into_vec(), bounds, depth: f.depth }
        })
        .collect();

    let capacity = if roots.is_empty() { refs.len() } else { 64 };
    let mut f = Flattener::new(bin, refs, Sink::owned(capacity), Sink::owned(capacity));
    f.parts = roots.iter().map(|r| r.0).zip(parts.iter().map(|p| (p.nodes.len(), p.indices.len(), p.bounds))).collect();
    f.emit_root();
    let depth = parts.iter().fold(f.depth, |d, p| d.max(p.depth));
    if f.holes.is_empty() {
        return (f.nodes.into_vec(), f.indices.into_vec(), depth, 0);
    }
    let (nodes, indices) = assemble(&f, &parts);
    (nodes, indices, depth, parts.len())
}

/// Step 2 of the module docs: the parts (`roots`, of `sizes` nodes and indices) and
/// the nodes above them written straight into an output of `total` nodes and indices.
/// The serial pass runs twice: first for the holes' places (they depend on the sizes
/// alone), then, once the parts have been written and their boxes are known, again
/// with the boxes (it writes the same places; it is the top few levels).
fn flatten_in_place<T: Nodes>(
    bin: &T,
    refs: &PrimRefs,
    roots: &[(u32, u32)],
    sizes: &[(usize, usize)],
    total: (usize, usize),
) -> (Vec<GpuBvhNode>, Vec<u32>, u32, usize) {
    let mut nodes = vec![[[0u32; 4]; 4]; total.0];
    let mut indices = vec![0u32; total.1];
    let top = |nodes: &mut [GpuBvhNode], indices: &mut [u32], boxes: &[Aabb]| {
        let mut f = Flattener::new(bin, refs, Sink::Slice(nodes, 0), Sink::Slice(indices, 0));
        f.parts = roots.iter().zip(sizes).zip(boxes).map(|((r, s), b)| (r.0, (s.0, s.1, *b))).collect();
        f.emit_root();
        assert_eq!((f.nodes.len(), f.indices.len()), total, "flattened sizes");
        (f.holes, f.depth)
    };
    let (holes, _) = top(&mut nodes, &mut indices, &vec![Aabb::EMPTY; roots.len()]);
    // The holes in output order, as disjoint slices for the parts' tasks.
    let mut jobs = Vec::with_capacity(holes.len());
    let (mut rest_n, mut rest_i): (&mut [GpuBvhNode], &mut [u32]) = (&mut nodes, &mut indices);
    let (mut at_n, mut at_i) = (0, 0);
    for h in &holes {
        let (pn, pi) = sizes[h.part];
        let (_, tn) = std::mem::take(&mut rest_n).split_at_mut(h.nodes - at_n);
        let (_, ti) = std::mem::take(&mut rest_i).split_at_mut(h.indices - at_i);
        let (dn, tn) = tn.split_at_mut(pn);
        let (di, ti) = ti.split_at_mut(pi);
        jobs.push((h, dn, di));
        (at_n, at_i) = (h.nodes + pn, h.indices + pi);
        (rest_n, rest_i) = (tn, ti);
    }
    let done: Vec<(usize, Aabb, u32)> = jobs
        .into_par_iter()
        .map(|(h, dn, di)| {
            let (n, depth) = roots[h.part];
            let size = (dn.len(), di.len());
            let mut f = Flattener::new(bin, refs, Sink::Slice(dn, 0), Sink::Slice(di, 0));
            (f.base_nodes, f.base_indices) = (h.nodes, h.indices);
            let (_, bounds) = f.emit(Child::Node(n), depth);
            assert_eq!((f.nodes.len(), f.indices.len()), size, "part size");
            (h.part, bounds, f.depth)
        })
        .collect();
    let mut boxes = vec![Aabb::EMPTY; roots.len()];
    for &(k, b, _) in &done {
        boxes[k] = b;
    }
    let (_, depth) = top(&mut nodes, &mut indices, &boxes);
    let depth = done.iter().fold(depth, |d, p| d.max(p.2));
    (nodes, indices, depth, holes.len())
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

/// Where a part goes: after this many nodes and indices of the serial pass (owned
/// sinks), or at this place in the output (in place).
struct Hole {
    part: usize,
    nodes: usize,
    indices: usize,
}

/// Fills the output from the serial pass `f` and the parts (see the module docs).
fn assemble<T: Nodes>(f: &Flattener<T>, parts: &[Part]) -> (Vec<GpuBvhNode>, Vec<u32>) {
    let (f_nodes, f_indices) = (f.nodes.written(), f.indices.written());
    let mut nodes = vec![[[0u32; 4]; 4]; f_nodes.len() + f.skipped_nodes];
    let mut indices = vec![0u32; f_indices.len() + f.skipped_indices];
    // Jobs in output order: a run of the serial pass, then a part, and so on.
    enum Src<'a> {
        Run(&'a [GpuBvhNode], &'a [u32]),
        Part(&'a Part, u32, u32),
    }
    let mut jobs: Vec<(&mut [GpuBvhNode], &mut [u32], Src)> = Vec::with_capacity(2 * f.holes.len() + 1);
    let (mut rest_n, mut rest_i): (&mut [GpuBvhNode], &mut [u32]) = (&mut nodes, &mut indices);
    let (mut at_n, mut at_i, mut out_n, mut out_i) = (0, 0, 0, 0);
    for h in f.holes.iter().map(Some).chain([None]) {
        let (end_n, end_i) = h.map_or((f_nodes.len(), f_indices.len()), |h| (h.nodes, h.indices));
        let (dn, tn) = std::mem::take(&mut rest_n).split_at_mut(end_n - at_n);
        let (di, ti) = std::mem::take(&mut rest_i).split_at_mut(end_i - at_i);
        jobs.push((dn, di, Src::Run(&f_nodes[at_n..end_n], &f_indices[at_i..end_i])));
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
                r if r & LEAF_REF != 0 => r + (ib << BVH_LEAF_COUNT_BITS),
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

/// Where a flattener writes: vectors of its own, or a slice of the output with the
/// number written (or skipped) so far.
enum Sink<'o, T> {
    Own(Vec<T>),
    Slice(&'o mut [T], usize),
}

impl<T: Copy> Sink<'_, T> {
    fn owned(capacity: usize) -> Self {
        Sink::Own(Vec::with_capacity(capacity))
    }
    fn len(&self) -> usize {
        match self {
            Sink::Own(v) => v.len(),
            Sink::Slice(_, at) => *at,
        }
    }
    fn push(&mut self, x: T) {
        match self {
            Sink::Own(v) => v.push(x),
            Sink::Slice(s, at) => {
                s[*at] = x;
                *at += 1;
            }
        }
    }
    fn extend(&mut self, x: &[T]) {
        match self {
            Sink::Own(v) => v.extend_from_slice(x),
            Sink::Slice(s, at) => {
                s[*at..*at + x.len()].copy_from_slice(x);
                *at += x.len();
            }
        }
    }
    fn set(&mut self, i: usize, x: T) {
        match self {
            Sink::Own(v) => v[i] = x,
            Sink::Slice(s, _) => s[i] = x,
        }
    }
    fn written(&self) -> &[T] {
        match self {
            Sink::Own(v) => v,
            Sink::Slice(s, at) => &s[..*at],
        }
    }
    fn into_vec(self) -> Vec<T> {
        match self {
            Sink::Own(v) => v,
            Sink::Slice(s, at) => s[..at].to_vec(),
        }
    }
}

struct Flattener<'a, 'o, T: Nodes> {
    bin: &'a T,
    refs: &'a PrimRefs,
    nodes: Sink<'o, GpuBvhNode>,
    indices: Sink<'o, u32>,
    /// Output place of the sinks' first element.
    base_nodes: usize,
    base_indices: usize,
    gathered: Vec<u32>,
    depth: u32,
    /// Subtrees flattened as parts: root node, then the part's nodes, indices, box.
    parts: Vec<(u32, (usize, usize, Aabb))>,
    holes: Vec<Hole>,
    /// Nodes and indices in the holes so far of owned sinks: a position in `nodes`
    /// (`indices`) plus these is a position in the output. (A slice sink steps over
    /// the holes itself.)
    skipped_nodes: usize,
    skipped_indices: usize,
}

impl<'a, 'o, T: Nodes> Flattener<'a, 'o, T> {
    fn new(bin: &'a T, refs: &'a PrimRefs, nodes: Sink<'o, GpuBvhNode>, indices: Sink<'o, u32>) -> Self {
        Flattener {
            bin,
            refs,
            nodes,
            indices,
            base_nodes: 0,
            base_indices: 0,
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
        self.bin.read_ahead(n);
        Child::Node(n)
    }

    /// Output position of the next index.
    fn next_index(&self) -> u32 {
        (self.base_indices + self.indices.len() + self.skipped_indices) as u32
    }

    /// Emits the root. It is always an inner node: a one-leaf tree gets an empty
    /// sibling.
    fn emit_root(&mut self) {
        let (l, r) = match self.child(self.bin.root()) {
            Child::Node(n) => {
                let node = self.bin.node(n);
                (self.child(node.left), self.child(node.right))
            }
            leaf => (leaf, Child::Owned(Vec::new())),
        };
        self.emit_inner(l, r, 1);
    }

    /// Writes a leaf of `list` (at most MAX_LEAF primitives); returns its reference.
    fn leaf(&mut self, list: &[u32]) -> u32 {
        let first = self.next_index();
        self.indices.extend(list);
        leaf_ref(first, list.len() as u32)
    }

    /// Emits `c` below an inner node at `depth`: its reference and box.
    fn emit(&mut self, c: Child, depth: u32) -> (u32, Aabb) {
        match c {
            Child::Range(_, 0, _, _) => (EMPTY_REF, Aabb::EMPTY),
            Child::Range(start, len, b, gathered) if len <= MAX_LEAF => {
                let first = self.next_index();
                let src = if gathered { &self.gathered } else { self.bin.prims() };
                self.indices.extend(&src[start..start + len]);
                (leaf_ref(first, len as u32), b)
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
        let at = self.base_nodes + self.nodes.len() + self.skipped_nodes;
        self.holes.push(Hole { part: k, nodes: self.nodes.len(), indices: self.indices.len() });
        match (&mut self.nodes, &mut self.indices) {
            (Sink::Slice(_, n), Sink::Slice(_, i)) => {
                *n += nodes;
                *i += indices;
            }
            _ => {
                self.skipped_nodes += nodes;
                self.skipped_indices += indices;
            }
        }
        (at as u32, bounds)
    }

    /// Emits an inner node at `depth` (1 = root) with children `l`, `r`.
    fn emit_inner(&mut self, l: Child, r: Child, depth: u32) -> (u32, Aabb) {
        self.depth = self.depth.max(depth);
        let slot = self.nodes.len();
        let me = self.base_nodes + slot + self.skipped_nodes;
        self.nodes.push([[0; 4]; 4]);
        let (lref, lbox) = self.emit(l, depth);
        let (rref, rbox) = self.emit(r, depth);
        let bits = |v: Vec3, w: u32| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits(), w];
        let (lbox_g, rbox_g) = (gpu_box(&lbox), gpu_box(&rbox));
        self.nodes
            .set(slot, [bits(lbox_g.min, lref), bits(lbox_g.max, rref), bits(rbox_g.min, 0), bits(rbox_g.max, 0)]);
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
            let lbvh = lbvh::build(&refs, &mut phases, &mut t);
            same_in_parts(&lbvh, &refs, &what("lbvh"));
            // Written in place, the same again: the whole tree is n - 1 nodes and n
            // indices.
            let in_place = super::super::LbvhNodes(&lbvh);
            if n >= 2 {
                assert_eq!(in_place.emitted(lbvh.root), Some((n - 1, n)), "{}", what("lbvh"));
            }
            same_in_parts(&in_place, &refs, &what("lbvh in place"));
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
