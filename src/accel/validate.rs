//! The typed error every structure's `validate()` returns: where the structure is
//! wrong (a node, a grid cell, a primitive, or the structure as a whole) and what.

use std::fmt;

/// Where a structure broke an invariant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Site {
    /// The structure as a whole (its depth, box, resolution or arrays).
    Whole,
    /// A node (kd-tree, BVH or octree record index; for a BVH, an inner node).
    Node(u64),
    /// A grid cell (linear index, x fastest).
    Cell(u64),
    /// A primitive (triangles first, then spheres).
    Prim(u64),
}

/// A broken invariant, found by [`super::Structure::validate`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub struct ValidateError {
    pub site: Site,
    pub what: String,
}

impl ValidateError {
    pub fn whole(what: impl Into<String>) -> ValidateError {
        ValidateError { site: Site::Whole, what: what.into() }
    }
    pub fn node(n: impl TryInto<u64>, what: impl Into<String>) -> ValidateError {
        ValidateError { site: Site::Node(n.try_into().unwrap_or(u64::MAX)), what: what.into() }
    }
    pub fn cell(c: impl TryInto<u64>, what: impl Into<String>) -> ValidateError {
        ValidateError { site: Site::Cell(c.try_into().unwrap_or(u64::MAX)), what: what.into() }
    }
    pub fn prim(p: impl TryInto<u64>, what: impl Into<String>) -> ValidateError {
        ValidateError { site: Site::Prim(p.try_into().unwrap_or(u64::MAX)), what: what.into() }
    }
}

impl fmt::Display for ValidateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.site {
            Site::Whole => f.write_str(&self.what),
            Site::Node(n) => write!(f, "node {n}: {}", self.what),
            Site::Cell(c) => write!(f, "cell {c}: {}", self.what),
            Site::Prim(p) => write!(f, "primitive {p}: {}", self.what),
        }
    }
}
