//! Treelet restructuring after Karras & Aila, "Fast parallel construction of
//! high-quality bounding volume hierarchies" (HPG 2013).
//!
//! A treelet is formed at an inner node by starting from its two children and
//! repeatedly expanding the treelet leaf with the largest surface area (only inner
//! nodes can be expanded) until it has [`TREELET_LEAVES`] leaves. Its optimal topology
//! is found by dynamic programming over the subsets of its leaves: for every subset S,
//! the cheapest of splitting it into two subsets (C_T·A(S) + c(P) + c(S∖P)) and, when
//! S holds at most [`MAX_LEAF`] primitives, of making it one leaf (C_I·A(S)·N(S)). The
//! treelet's inner nodes are reused for the new topology; subtrees below its leaves are
//! kept intact.
//!
//! The tree to restructure is the LBVH, built straight into this module's nodes by a
//! climb from the leaves ([`Restructure::lbvh`]), or any canonical tree
//! ([`Restructure::new`]).
//!
//! Nodes are processed bottom-up, so a treelet is optimised after every treelet below
//! it, and only at nodes whose subtree holds at least γ primitives. As in the paper,
//! several rounds run, with γ set per round ([`TreeletParams::gamma`]; by default 7, 7,
//! 28, where the paper doubles it: 7, 14, 28). A round is a post-order
//! walk that prunes subtrees below γ primitives; the two subtrees of a large node are
//! walked by parallel tasks, since their treelets are disjoint. Within one task's
//! subtree the treelet roots are listed level by level, and a root is optimised once
//! the roots below it are done: sixteen disjoint treelets at once, one per SIMD lane
//! (AVX-512 where the processor has it, else AVX2 or SSE), by a generated straight-line
//! programme (`dp_gen.rs`). The result does not
//! depend on thread count or order: each treelet's solution reads only its own subtree
//! (restructuring permutes nodes only within a treelet, so every node's subtree keeps
//! its set of nodes), and the GPU kernel, which goes bottom-up by levels, gets the
//! same tree. A treelet that was optimised without change, and under which nothing
//! has changed since, is skipped in later rounds: its optimum would be the same.
//!
//! A restructuring is applied only when it lowers the treelet root's cost, so the SAH
//! cost (with collapse) never increases. The flattener then collapses the subtrees that
//! are cheaper as one leaf (`Nodes::collapsed`).
//!
//! One submodule per job: `params` ([`TreeletParams`]: presets, the γ schedule, the
//! `--trbvh` spec), `tree` (the nodes being restructured, [`Restructure`], and their
//! fitting), `climb` (the LBVH built straight into those nodes), `rounds` (forming,
//! optimising and rewriting treelets, [`Restructure::round`]) and `lanes` (the
//! generated dynamic programme over 16 treelets at once, in SSE, AVX2 or AVX-512).
//!
//! [`MAX_LEAF`]: super::MAX_LEAF

use super::Binary;
use crate::accel::sah::SahCosts;

mod climb;
mod lanes;
mod params;
mod rounds;
mod tree;

pub use params::{gamma, TreeletParams, MAX_ROUNDS, ROUNDS};
pub use rounds::RoundStats;
pub use tree::Restructure;

/// Most leaves per treelet (the paper's choice, and the default).
pub const TREELET_LEAVES: usize = 7;
/// A treelet is rewritten only when its optimised cost is below this fraction of its
/// cost (so rounding noise never rewrites a tree); the GPU build gets the same bits.
pub const KEEP_FACTOR: f32 = 1.0 - 1e-6;

/// Helper for tests: the collapsed SAH cost of a canonical tree.
pub fn collapsed_cost(bin: &Binary, costs: &SahCosts) -> f64 {
    bin.sah_cost(costs, true)
}
