//! The lecture's kd-tree over visible points, balanced on the points: each node holds
//! one point, the median of its subtree along the axis where the subtree's points
//! spread widest; the points below go left, those above right. Each node also bounds
//! the spheres (point +- radius) of its whole subtree, so a photon's search descends
//! only where some sphere may hold it. Built on the CPU, where a median split is a
//! linear-time selection per level (O(n log n) in all).
//!
//! # Layout (32 bytes a node, preorder)
//!
//! ```text
//! words 0..3  min of the subtree's sphere boxes     word 3  the node's point
//! words 4..7  max of the subtree's sphere boxes     word 7  end: one past the
//!             subtree's last node
//! ```
//!
//! Node k's subtree is nodes k..end; with n = end - k, its left child is node k + 1
//! when n > 1 (the subtree's n / 2 lower points), its right child node k + 1 + n / 2
//! when n / 2 + 1 < n. A balanced tree is at most [`PointTree::depth`] levels deep,
//! so a search's stack holds at most that many entries.
//!
//! Worked example: points 0 at x = 0, 1 at x = 1, 2 at x = 2 (radius 0.5) make node 0
//! point 1 (the median, end 3), node 1 point 0 (end 2), node 2 point 2 (end 3); node 0's
//! box spans x -0.5..2.5.

use glam::Vec3;

use super::{check_points, holds};

/// One node; see the module's layout.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PointNode {
    /// The least corner of the subtree's sphere boxes.
    pub min: [f32; 3],
    /// The node's visible point.
    pub point: u32,
    /// The greatest corner of the subtree's sphere boxes.
    pub max: [f32; 3],
    /// One past the subtree's last node.
    pub end: u32,
}

const _: () = assert!(std::mem::size_of::<PointNode>() == 32);

/// A built tree; see the module's layout.
#[derive(Debug, Clone, PartialEq)]
pub struct PointTree {
    /// The nodes in preorder.
    pub nodes: Vec<PointNode>,
}

impl PointTree {
    /// Builds the tree over visible points at `positions` with `radii` (an error names
    /// the first unusable point, [`check_points`]).
    pub fn build(positions: &[Vec3], radii: &[f32]) -> Result<PointTree, String> {
        check_points(positions, radii)?;
        let mut order: Vec<u32> = (0..positions.len() as u32).collect();
        let mut nodes = vec![PointNode::default(); positions.len()];
        if !positions.is_empty() {
            place(positions, radii, &mut order, &mut nodes, 0);
        }
        Ok(PointTree { nodes })
    }

    /// The most levels a balanced tree of these nodes has: floor(log2(n)) + 1.
    pub fn depth(&self) -> u32 {
        usize::BITS - self.nodes.len().leading_zeros()
    }

    /// Appends to `out` every visible point that holds `p` (each once, in index
    /// order); returns the nodes visited.
    pub fn lookup(&self, positions: &[Vec3], radii: &[f32], p: Vec3, out: &mut Vec<u32>) -> usize {
        let first = out.len();
        let mut visited = 0;
        let mut stack = Vec::with_capacity(self.depth() as usize + 1);
        if !self.nodes.is_empty() {
            stack.push(0u32);
        }
        while let Some(k) = stack.pop() {
            let node = &self.nodes[k as usize];
            visited += 1;
            if !(p.cmpge(Vec3::from(node.min)).all() && p.cmple(Vec3::from(node.max)).all()) {
                continue;
            }
            if holds(positions, radii, node.point as usize, p) {
                out.push(node.point);
            }
            let n = node.end - k;
            if n / 2 + 1 < n {
                stack.push(k + 1 + n / 2);
            }
            if n > 1 {
                stack.push(k + 1);
            }
        }
        out[first..].sort_unstable();
        visited
    }
}

/// Lays out the subtree of the points `order` from node `at` on: the median along the
/// widest axis at `at`, the lower half after it, the upper half after that.
fn place(positions: &[Vec3], radii: &[f32], order: &mut [u32], nodes: &mut [PointNode], at: usize) {
    let n = order.len();
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for &i in order.iter() {
        lo = lo.min(positions[i as usize]);
        hi = hi.max(positions[i as usize]);
    }
    let spread = hi - lo;
    let axis = if spread.x >= spread.y && spread.x >= spread.z {
        0
    } else if spread.y >= spread.z {
        1
    } else {
        2
    };
    // Ties by index, so the tree does not depend on the selection's order.
    let key = |i: &u32| (positions[*i as usize][axis], *i);
    order.select_nth_unstable_by(n / 2, |a, b| key(a).partial_cmp(&key(b)).expect("finite positions"));
    let median = order[n / 2];
    // The lower half first (it becomes the left subtree), then the upper.
    order[..=n / 2].rotate_right(1);
    let (mut min, mut max) =
        (positions[median as usize] - radii[median as usize], positions[median as usize] + radii[median as usize]);
    let (left, right) = order[1..].split_at_mut(n / 2);
    if !left.is_empty() {
        place(positions, radii, left, nodes, at + 1);
        min = min.min(Vec3::from(nodes[at + 1].min));
        max = max.max(Vec3::from(nodes[at + 1].max));
    }
    if !right.is_empty() {
        let r = at + 1 + n / 2;
        place(positions, radii, right, nodes, r);
        min = min.min(Vec3::from(nodes[r].min));
        max = max.max(Vec3::from(nodes[r].max));
    }
    nodes[at] = PointNode { min: min.to_array(), point: median, max: max.to_array(), end: (at + n) as u32 };
}

#[cfg(test)]
mod tests {
    use super::super::brute_force;
    use super::super::tests::{point_sets, queries};
    use super::*;

    #[test]
    fn lookups_find_what_testing_every_point_finds() {
        for (name, positions, radii) in point_sets() {
            let tree = PointTree::build(&positions, &radii).expect("builds");
            let mut visited = 0;
            for q in queries(&positions, &radii) {
                let mut got = Vec::new();
                visited += tree.lookup(&positions, &radii, q, &mut got);
                assert_eq!(got, brute_force(&positions, &radii, q), "{name}: photon at {q}");
            }
            let queries = queries(&positions, &radii).len();
            if positions.len() >= 2000 {
                assert!(visited * 20 < queries * positions.len(), "{name}: {visited} nodes for {queries} photons");
            }
        }
    }

    #[test]
    fn the_tree_is_balanced_and_bounds_its_subtrees() {
        for (name, positions, radii) in point_sets() {
            let tree = PointTree::build(&positions, &radii).expect("builds");
            let mut seen = vec![false; positions.len()];
            let mut deepest = 0;
            // (node, depth): every node's box holds its point's sphere and its
            // children's boxes; every point appears once.
            let mut stack = vec![(0u32, 1u32)];
            while let Some((k, d)) = stack.pop().filter(|_| !tree.nodes.is_empty()) {
                deepest = deepest.max(d);
                let node = tree.nodes[k as usize];
                let i = node.point as usize;
                assert!(!seen[i], "{name}: point {i} twice");
                seen[i] = true;
                let (lo, hi) = (Vec3::from(node.min), Vec3::from(node.max));
                assert!(lo.cmple(positions[i] - radii[i]).all() && hi.cmpge(positions[i] + radii[i]).all());
                let n = node.end - k;
                for c in [(n > 1).then_some(k + 1), (n / 2 + 1 < n).then_some(k + 1 + n / 2)].into_iter().flatten() {
                    let child = tree.nodes[c as usize];
                    assert!(lo.cmple(Vec3::from(child.min)).all() && hi.cmpge(Vec3::from(child.max)).all());
                    stack.push((c, d + 1));
                }
            }
            assert!(seen.iter().all(|&s| s), "{name}: a point is missing");
            assert!(deepest <= tree.depth(), "{name}: depth {deepest} > {}", tree.depth());
        }
    }

    #[test]
    fn the_worked_example() {
        let positions = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)];
        let tree = PointTree::build(&positions, &[0.5; 3]).expect("builds");
        let layout: Vec<_> = tree.nodes.iter().map(|n| (n.point, n.end)).collect();
        assert_eq!(layout, [(1, 3), (0, 2), (2, 3)]);
        assert_eq!((tree.nodes[0].min[0], tree.nodes[0].max[0]), (-0.5, 2.5));
    }
}
