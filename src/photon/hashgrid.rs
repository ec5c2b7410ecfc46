//! The hash grid over visible points (Hachisuka, Ogaki & Jensen 2010; pbrt-v4's
//! SPPM), built by a counting sort of (point, cell) pairs.
//!
//! # Layout
//!
//! ```text
//! cell edge  = the largest radius (so a sphere spans at most 3 cells an axis: at
//!              most 27 cells a point)
//! res[a]     = cells along axis a = clamp(floor(extent[a] / edge), 1, MAX_RES)
//! cell of p  = floor((p - min) / edge), clamped to res - 1
//! bucket     = hash(cell) mod buckets, buckets = the number of points (at least 1)
//! starts     = buckets + 1 words: bucket b's points are entries[starts[b]..starts[b + 1]]
//! entries    = point indices, in index order within a bucket; a point appears once
//!              a bucket even where two of its cells hash alike
//! ```
//!
//! Worked example: points 0 at (0, 0, 0) and 1 at (3, 0, 0), both of radius 1, give
//! min (-1, -1, -1), max (4, 1, 1), edge 1, res (5, 2, 2); point 0's box [-1, 1]^3
//! covers cells x 0..=2 (its face x = 1 is where cell 2 starts), y and z 0..=1
//! (clamped), point 1's x 2..=4. A photon at (0.5, 0, 0) is in cell (1, 1, 1): its
//! bucket lists point 0 (and point 1 only where a cell of point 1 hashes to the same
//! bucket; the distance test drops it).

use glam::Vec3;

use super::{check_points, holds};

/// Most cells along one axis: the cell coordinates hash as 32-bit integers, and a
/// scene whose largest radius is this much smaller than its extent gets longer cells.
pub const MAX_RES: u32 = crate::gpu::bindings::PHOTON_GRID_MAX_RES;

/// Teschner et al. 2003's spatial hash of a cell (pbrt-v4's, wrapping 32-bit).
pub fn hash(c: [u32; 3], buckets: u32) -> u32 {
    (c[0].wrapping_mul(73_856_093) ^ c[1].wrapping_mul(19_349_663) ^ c[2].wrapping_mul(83_492_791)) % buckets
}

/// A built hash grid; see the module's layout.
#[derive(Debug, Clone, PartialEq)]
pub struct HashGrid {
    /// The least corner of the points' spheres.
    pub min: Vec3,
    /// The greatest corner of the points' spheres.
    pub max: Vec3,
    /// The cell edge.
    pub edge: f32,
    /// Cells along each axis.
    pub res: [u32; 3],
    /// Bucket b's entries are `entries[starts[b]..starts[b + 1]]`.
    pub starts: Vec<u32>,
    /// Point indices, bucket after bucket.
    pub entries: Vec<u32>,
}

impl HashGrid {
    /// Builds the grid over visible points at `positions` with `radii` (an error
    /// names the first unusable point, [`check_points`]).
    pub fn build(positions: &[Vec3], radii: &[f32]) -> Result<HashGrid, String> {
        check_points(positions, radii)?;
        let (mut min, mut max) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let mut edge = 0f32;
        for (&p, &r) in positions.iter().zip(radii) {
            min = min.min(p - Vec3::splat(r));
            max = max.max(p + Vec3::splat(r));
            edge = edge.max(r);
        }
        let buckets = positions.len().max(1) as u32;
        let mut grid =
            HashGrid { min, max, edge, res: [1; 3], starts: vec![0; buckets as usize + 1], entries: Vec::new() };
        if positions.is_empty() {
            grid.min = Vec3::ZERO;
            grid.max = Vec3::ZERO;
            return Ok(grid);
        }
        let extent = max - min;
        for a in 0..3 {
            // A longer edge where the extent holds more than MAX_RES of them.
            let cells = (extent[a] / edge).floor();
            grid.res[a] = if cells.is_finite() { (cells as u64).clamp(1, u64::from(MAX_RES)) as u32 } else { MAX_RES };
        }
        let longest = (0..3).map(|a| extent[a] / grid.res[a] as f32).fold(edge, f32::max);
        grid.edge = longest;
        // Counting sort: count each point's distinct buckets, scan, then scatter in
        // point order (so each bucket lists its points in index order).
        let mut counts = vec![0u32; buckets as usize];
        let mut seen = Vec::with_capacity(27);
        for i in 0..positions.len() {
            grid.buckets_of(positions[i], radii[i], &mut seen);
            for &b in &seen {
                counts[b as usize] += 1;
            }
        }
        let mut total = 0u32;
        for (b, &c) in counts.iter().enumerate() {
            grid.starts[b] = total;
            total += c;
        }
        grid.starts[buckets as usize] = total;
        grid.entries = vec![0; total as usize];
        let mut next: Vec<u32> = grid.starts[..buckets as usize].to_vec();
        for i in 0..positions.len() {
            grid.buckets_of(positions[i], radii[i], &mut seen);
            for &b in &seen {
                grid.entries[next[b as usize] as usize] = i as u32;
                next[b as usize] += 1;
            }
        }
        Ok(grid)
    }

    /// The number of buckets.
    pub fn buckets(&self) -> u32 {
        (self.starts.len() - 1) as u32
    }

    /// The cell holding `p`, clamped into the grid.
    pub fn cell_of(&self, p: Vec3) -> [u32; 3] {
        let mut c = [0u32; 3];
        for (a, c) in c.iter_mut().enumerate() {
            let k = ((p[a] - self.min[a]) / self.edge).floor();
            *c = if k > 0.0 { (k as u64).min(u64::from(self.res[a] - 1)) as u32 } else { 0 };
        }
        c
    }

    /// The distinct buckets of the cells that the box of a sphere at `p` of radius
    /// `r` overlaps (at most 27), in the order first met.
    fn buckets_of(&self, p: Vec3, r: f32, out: &mut Vec<u32>) {
        out.clear();
        let lo = self.cell_of(p - Vec3::splat(r));
        // Two cells past the first at most: 2 r <= 2 edges, whatever the rounding at a
        // cell's face (the kernel loops as far).
        let mut hi = self.cell_of(p + Vec3::splat(r));
        for a in 0..3 {
            hi[a] = hi[a].min(lo[a] + 2);
        }
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let b = hash([x, y, z], self.buckets());
                    if !out.contains(&b) {
                        out.push(b);
                    }
                }
            }
        }
    }

    /// Appends to `out` every visible point that holds `p` (each once, in index
    /// order); returns the points tested.
    pub fn lookup(&self, positions: &[Vec3], radii: &[f32], p: Vec3, out: &mut Vec<u32>) -> usize {
        if positions.is_empty() || !(p.cmpge(self.min).all() && p.cmple(self.max).all()) {
            return 0;
        }
        let b = hash(self.cell_of(p), self.buckets()) as usize;
        let list = &self.entries[self.starts[b] as usize..self.starts[b + 1] as usize];
        out.extend(list.iter().copied().filter(|&i| holds(positions, radii, i as usize, p)));
        list.len()
    }
}

#[cfg(test)]
mod tests {
    use super::super::brute_force;
    use super::super::tests::{point_sets, queries};
    use super::*;

    #[test]
    fn lookups_find_what_testing_every_point_finds() {
        for (name, positions, radii) in point_sets() {
            let grid = HashGrid::build(&positions, &radii).expect("builds");
            let mut tested = 0;
            for q in queries(&positions, &radii) {
                let mut got = Vec::new();
                tested += grid.lookup(&positions, &radii, q, &mut got);
                assert_eq!(got, brute_force(&positions, &radii, q), "{name}: photon at {q}");
            }
            // The grid tests a fraction of the points a brute-force search would.
            let queries = queries(&positions, &radii).len();
            if positions.len() >= 2000 {
                assert!(tested * 20 < queries * positions.len(), "{name}: {tested} tests for {queries} photons");
            }
        }
    }

    #[test]
    fn the_worked_example() {
        let positions = [Vec3::ZERO, Vec3::new(3.0, 0.0, 0.0)];
        let grid = HashGrid::build(&positions, &[1.0, 1.0]).expect("builds");
        assert_eq!((grid.min, grid.edge, grid.res), (Vec3::splat(-1.0), 1.0, [5, 2, 2]));
        assert_eq!(grid.cell_of(Vec3::new(0.5, 0.0, 0.0)), [1, 1, 1]);
        let mut got = Vec::new();
        grid.lookup(&positions, &[1.0, 1.0], Vec3::new(0.5, 0.0, 0.0), &mut got);
        assert_eq!(got, [0]);
    }

    #[test]
    fn a_point_is_listed_once_a_bucket() {
        // One bucket for every cell: each point's cells all hash alike.
        let positions = [Vec3::ZERO];
        let grid = HashGrid::build(&positions, &[0.5]).expect("builds");
        assert_eq!(grid.buckets(), 1);
        assert_eq!(grid.entries, [0]);
    }
}
