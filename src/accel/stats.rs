//! What a build cost and produced ([`BuildStats`]), its timed phases, and the leaf
//! counts every tree's statistics are made of ([`LeafTally`]).

/// What building a structure cost and produced. Every field means the same for every
/// structure: a grid cell counts as a leaf, an absent octant or an empty BVH child as an
/// empty leaf, and brute force as one leaf holding everything.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct BuildStats {
    /// The structure's name ([`super::AccelKind::name`]).
    pub kind: String,
    /// CPU wall-clock build time.
    pub build_ms: f64,
    /// Bytes of the structure as uploaded (nodes + indices).
    pub bytes: u64,
    /// Inner nodes plus leaves (as counted in `leaves`).
    pub nodes: u64,
    /// Deepest leaf; the root is depth 0 for trees, and grids and brute force are 0.
    pub max_depth: u32,
    /// Every leaf, empty ones included.
    pub leaves: u64,
    /// Leaves that hold no primitive (a subset of `leaves`).
    pub empty_leaves: u64,
    /// Mean depth over every leaf, empty ones included.
    pub mean_leaf_depth: f64,
    /// Primitive references in leaves per primitive.
    pub refs_per_prim: f64,
    /// Primitive references per non-empty leaf.
    pub prims_per_leaf: f64,
    /// SAH cost of the tree with the default constants (sah.rs), relative to the root.
    pub sah_cost: f64,
    /// Build phases in order, CPU wall clock.
    pub phases: Vec<Phase>,
    /// Cells per axis (grid only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resolution: Option<[u32; 3]>,
    /// Each level of a two-level structure (instanced scenes only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub levels: Option<super::instance::LevelStats>,
    /// Set where the structure is the driver's (`rayquery`): what arbor cannot see of
    /// it (node counts, depth and SAH cost are then 0, meaning unknown). The kernel
    /// cannot count its nodes and primitives either, so renders leave those out.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub opaque: Option<String>,
    /// Set where arbor's own tree was built on the device and kept there: what needs
    /// it read back to the host (leaf counts, SAH cost; 0 until then). The kernel
    /// counts nodes visited and primitives tested as for any tree.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub on_device: Option<String>,
}

/// One timed phase of a build.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Phase {
    /// What the phase does (e.g. `sort`, `flatten`).
    pub name: String,
    /// CPU wall-clock time.
    pub ms: f64,
    /// What the phase did, where it says more than its time (e.g. treelets optimised).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detail: Option<String>,
}

impl Phase {
    /// Phase `name` from `since` until now, also a span on this thread's timeline
    /// ([`crate::timeline`]), where it nests inside the build's span.
    pub fn since(name: impl Into<String>, since: std::time::Instant) -> Phase {
        let name = name.into();
        crate::timeline::phase("build", &name, since, Default::default());
        Phase { name, ms: since.elapsed().as_secs_f64() * 1e3, detail: None }
    }

    /// The same phase with `detail`.
    pub fn with_detail(mut self, detail: String) -> Phase {
        self.detail = Some(detail);
        self
    }
}

/// Records the time since `t` as phase `name` ([`Phase::since`]) and restarts `t`.
pub(crate) fn lap(phases: &mut Vec<Phase>, name: &str, t: &mut std::time::Instant) {
    phases.push(Phase::since(name, *t));
    *t = std::time::Instant::now();
}

/// What a walk over a tree's leaves counts, from which [`BuildStats`]'s leaf figures
/// follow with the same meaning for every tree (the kd-tree, the octree, the BVHs of
/// every width). Each tree walks itself and says what it met; SAH weights come from
/// the caller, which knows its tree's areas.
#[derive(Debug, Clone, Copy, Default)]
pub struct LeafTally {
    /// Every leaf, empty ones included.
    pub leaves: u64,
    /// Leaves that hold no primitive.
    pub empty: u64,
    /// The sum of the leaves' depths.
    pub depth_sum: u64,
    /// Primitive references in leaves.
    pub refs: u64,
    /// The SAH cost summed so far.
    pub cost: f64,
}

impl LeafTally {
    /// A leaf at `depth` holding `count` references, adding `cost` to the SAH cost.
    pub fn leaf(&mut self, depth: u32, count: u64, cost: f64) {
        self.leaves += 1;
        self.empty += u64::from(count == 0);
        self.depth_sum += u64::from(depth);
        self.refs += count;
        self.cost += cost;
    }

    /// An inner node, adding `cost` to the SAH cost.
    pub fn inner(&mut self, cost: f64) {
        self.cost += cost;
    }

    /// Both tallies together (the second's cost added to the first's sum).
    pub fn and(self, other: LeafTally) -> LeafTally {
        LeafTally {
            leaves: self.leaves + other.leaves,
            empty: self.empty + other.empty,
            depth_sum: self.depth_sum + other.depth_sum,
            refs: self.refs + other.refs,
            cost: self.cost + other.cost,
        }
    }

    /// The statistics of a tree of `kind` with `nodes` nodes (as its kind counts them),
    /// deepest leaf `max_depth`, over `prims` primitives; the SAH cost is the tally's,
    /// the build time and phases 0 and none.
    pub fn stats(&self, kind: &str, nodes: u64, max_depth: u32, bytes: u64, prims: usize) -> BuildStats {
        BuildStats {
            kind: kind.into(),
            build_ms: 0.0,
            bytes,
            nodes,
            max_depth,
            leaves: self.leaves,
            empty_leaves: self.empty,
            mean_leaf_depth: self.depth_sum as f64 / self.leaves.max(1) as f64,
            refs_per_prim: self.refs as f64 / prims.max(1) as f64,
            prims_per_leaf: self.refs as f64 / (self.leaves - self.empty).max(1) as f64,
            sah_cost: self.cost,
            ..Default::default()
        }
    }
}
