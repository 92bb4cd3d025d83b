//! The tree of random streams: every random draw in the project comes from a `Seed` derived
//! from the scenario seed by a path of integers (cell, repetition, episode, purpose, agent).
//!
//! Deriving children by hashing, rather than by drawing from a parent generator, makes each
//! stream independent of how many draws any other stream made, so results do not depend on the
//! order or the thread in which work runs.

use rand_pcg::Pcg64Mcg;

/// A node of the seed tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Seed(u64);

/// Named children of an episode's seed, so that streams for different purposes never collide.
pub mod purpose {
    /// Start positions of the agents.
    pub(crate) const STARTS: u64 = 1;
    /// The policy's own draws (one child per agent below it where agents draw independently).
    pub const POLICY: u64 = 2;
    /// The number of agents, where an episode draws it (training over a range of team sizes).
    pub const AGENT_COUNT: u64 = 3;
    /// Which links between robots are down at each step, when communication is disturbed.
    pub(crate) const LINKS: u64 = 4;
    /// Which robots are lost, when a disturbance names how many but not which.
    pub const LOST_ROBOTS: u64 = 5;
}

impl Seed {
    pub fn new(root: u64) -> Self {
        Self(root)
    }

    pub fn value(self) -> u64 {
        self.0
    }

    /// The child `index` of this node.
    pub fn child(self, index: u64) -> Self {
        Self(splitmix64(
            self.0 ^ splitmix64(index.wrapping_add(0x5851_f42d_4c95_7f2d)),
        ))
    }

    /// The child reached by following `path` from this node.
    pub fn descend(self, path: &[u64]) -> Self {
        path.iter().fold(self, |seed, &index| seed.child(index))
    }

    /// A generator for this node's stream.
    pub fn rng(self) -> Pcg64Mcg {
        let high = splitmix64(self.0) as u128;
        let low = splitmix64(self.0 ^ 0x9e37_79b9_7f4a_7c15) as u128;
        Pcg64Mcg::new(high << 64 | low)
    }

    /// `count` distinct indices below `from` (all of them if there are fewer), drawn from this
    /// node's stream by a partial Fisher-Yates shuffle, in ascending order.
    pub fn choose(self, from: usize, count: usize) -> Vec<usize> {
        use rand::RngExt;
        let mut indices: Vec<usize> = (0..from).collect();
        let mut rng = self.rng();
        let count = count.min(from);
        for i in 0..count {
            let j = rng.random_range(i..from);
            indices.swap(i, j);
        }
        indices.truncate(count);
        indices.sort_unstable();
        indices
    }
}

/// Sebastiano Vigna's SplitMix64 finaliser: a bijection that scatters nearby inputs.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use rand::RngExt;

    use super::*;

    #[test]
    fn children_are_distinct_and_stable() {
        let root = Seed::new(7);
        assert_ne!(root.child(0), root.child(1));
        assert_ne!(root.child(0).child(1), root.child(1).child(0));
        assert_eq!(root.descend(&[3, 4]), root.child(3).child(4));
        let draw = |s: Seed| s.rng().random::<u64>();
        assert_eq!(draw(root.child(5)), draw(Seed::new(7).child(5)));
        assert_ne!(draw(root.child(5)), draw(root.child(6)));
    }

    #[test]
    fn chooses_distinct_indices_reproducibly() {
        let a = Seed::new(3).choose(100, 10);
        assert_eq!(a.len(), 10);
        assert!(a.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(a, Seed::new(3).choose(100, 10));
        assert_ne!(a, Seed::new(4).choose(100, 10));
        assert_eq!(Seed::new(3).choose(5, 10), vec![0, 1, 2, 3, 4]);
    }
}
