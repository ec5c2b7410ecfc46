//! Treelet restructuring parameters ([`TreeletParams`]): named presets, the γ of each
//! round, and the `--trbvh` spec they are parsed from.

use super::TREELET_LEAVES;
use crate::accel::params::{number, Key, Preset};

/// Rounds of restructuring by default.
pub const ROUNDS: u32 = 3;
/// Most rounds.
pub const MAX_ROUNDS: usize = 8;
/// γ of each round by default, as multiples of the treelet size: two rounds at the
/// treelet size, then one at 4 times it (7, 7, 28 for 7 leaves); later rounds repeat
/// the pattern. Measured at 1M triangles (docs/bvh.md, "trbvh"), the paper's doubling (7,
/// 14, 28) spends its second round where little improves: two rounds at 7 alone gave a
/// lower SAH cost than 7, 14, 28, and 7, 7, 28 is within 3% of the binned SAH builder.
const SCHEDULE: [u32; MAX_ROUNDS] = [1, 1, 4, 1, 1, 4, 1, 1];
/// The paper's schedule: γ doubles each round (a round beyond the third starts again;
/// doubling on to 8 and 16 times finds almost nothing to improve).
const DOUBLING: [u32; MAX_ROUNDS] = [1, 2, 4, 1, 2, 4, 1, 2];

/// Minimum primitives below a treelet root in `round` (0-based) for the default
/// parameters.
pub fn gamma(round: u32) -> u32 {
    TreeletParams::default().gamma(round)
}

/// Treelet restructuring parameters: the user's trade between build time and SAH.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TreeletParams {
    /// Leaves per treelet, 3..=7: the dynamic programming costs about 3^leaves.
    pub leaves: usize,
    /// Rounds, 0..=MAX_ROUNDS.
    pub rounds: u32,
    /// Minimum primitives below a treelet root in each round, as a multiple of
    /// `leaves` (see [`TreeletParams::gamma`]).
    pub gamma: [u32; MAX_ROUNDS],
}

impl Default for TreeletParams {
    /// The paper's 7 leaves and 3 rounds, with γ at 7, 7 and 28 (not the paper's 7, 14, 28).
    fn default() -> Self {
        TreeletParams { leaves: TREELET_LEAVES, rounds: ROUNDS, gamma: SCHEDULE }
    }
}

impl TreeletParams {
    /// Faster: 5-leaf treelets (docs/bvh.md, "trbvh").
    pub fn fast() -> Self {
        TreeletParams { leaves: 5, ..Self::default() }
    }

    /// The paper's schedule: γ at 7, 14 and 28.
    pub fn paper() -> Self {
        TreeletParams { gamma: DOUBLING, ..Self::default() }
    }

    /// Better trees for a longer build: every round at γ = the treelet size. Small
    /// subtrees gain most, and they gain again once the treelets above have regrouped
    /// the nodes below them (docs/bvh.md, "trbvh").
    pub fn quality() -> Self {
        TreeletParams { gamma: [1; MAX_ROUNDS], ..Self::default() }
    }

    /// Minimum primitives below a treelet root in `round` (0-based).
    pub fn gamma(&self, round: u32) -> u32 {
        self.leaves as u32 * self.gamma[round as usize % MAX_ROUNDS]
    }
}

/// `--trbvh`: presets `default`, `fast`, `quality`, `paper`; keys `leaves` (3..=7),
/// `rounds` (0..=8) and `gamma=A/B/...` (each round's minimum subtree size as a
/// multiple of `leaves`; it sets the rounds too).
impl crate::accel::params::Params for TreeletParams {
    const FLAG: &'static str = "trbvh";
    const PRESETS: &'static [Preset<Self>] = &[
        ("default", TreeletParams::default),
        ("fast", TreeletParams::fast),
        ("quality", TreeletParams::quality),
        ("paper", TreeletParams::paper),
    ];
    const KEYS: &'static [Key<Self>] = &[
        Key {
            name: "leaves",
            expects: "3..=7",
            set: |p, v| {
                p.leaves = number(v, 3, TREELET_LEAVES)?;
                Some(())
            },
        },
        Key {
            name: "rounds",
            expects: "0..=8",
            set: |p, v| {
                p.rounds = number(v, 0, MAX_ROUNDS as u32)?;
                Some(())
            },
        },
        Key {
            name: "gamma",
            expects: "1 to 8 multiples of leaves, each 1..=1048576, separated by '/'",
            set: |p, v| {
                let list: Vec<u32> = v.split('/').map(|g| number(g, 1, 1 << 20)).collect::<Option<_>>()?;
                if list.is_empty() || list.len() > MAX_ROUNDS {
                    return None;
                }
                p.gamma[..list.len()].copy_from_slice(&list);
                p.rounds = list.len() as u32;
                Some(())
            },
        },
    ];
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::params::Params;

    /// Presets and keys parse; each round's γ follows the schedule; bad values are
    /// refused.
    #[test]
    fn parameters_parse_and_gamma_cycles() {
        let d = TreeletParams::default();
        assert_eq!(TreeletParams::parse("default"), Ok(d));
        assert_eq!((d.leaves, d.rounds), (7, 3));
        let g: Vec<u32> = (0..3).map(|r| d.gamma(r)).collect();
        assert_eq!(g, [7, 7, 28]);
        let g: Vec<u32> = (0..3).map(|r| TreeletParams::paper().gamma(r)).collect();
        assert_eq!(g, [7, 14, 28]);
        assert_eq!(TreeletParams::parse("quality").map(|q| q.gamma(2)), Ok(7));
        assert_eq!(TreeletParams::parse("fast,rounds=5"), Ok(TreeletParams { leaves: 5, rounds: 5, ..d }));
        let g: Vec<u32> = (0..5).map(|r| TreeletParams::fast().gamma(r)).collect();
        assert_eq!(g, [5, 5, 20, 5, 5]);
        let p = TreeletParams::parse("leaves=6,gamma=1/4/2").expect("parses");
        assert_eq!((p.rounds, p.gamma(0), p.gamma(1), p.gamma(2)), (3, 6, 24, 12));
        for bad in ["leaves=8", "rounds=9", "best", "gamma=", "gamma=0", "gamma=1/x", "gamma=1/1/1/1/1/1/1/1/1"] {
            assert!(TreeletParams::parse(bad).is_err(), "{bad}");
        }
    }
}
