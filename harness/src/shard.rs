//! Shards: `i/n` selects every n-th cell starting at the i-th, so a job array of n tasks runs
//! each cell once and the slices stay balanced when neighbouring cells cost alike.

use std::fmt;
use std::str::FromStr;

/// Shard `index` of `count`, counted from 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    index: usize,
    count: usize,
}

impl Shard {
    /// Whether the cell at `cell_index` (from 0, in the scenario's order) is in this shard.
    pub fn contains(self, cell_index: usize) -> bool {
        cell_index % self.count == self.index - 1
    }
}

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("shard {0:?} is not i/n with 1 <= i <= n (e.g. 2/8)")]
pub struct BadShard(String);

impl FromStr for Shard {
    type Err = BadShard;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || BadShard(s.to_owned());
        let (index, count) = s.split_once('/').ok_or_else(bad)?;
        let index: usize = index.trim().parse().map_err(|_| bad())?;
        let count: usize = count.trim().parse().map_err(|_| bad())?;
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Self { index, count })
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_cells() {
        let shards: Vec<Shard> = ["1/3", "2/3", "3/3"].map(|s| s.parse().unwrap()).to_vec();
        for cell in 0..20 {
            assert_eq!(shards.iter().filter(|s| s.contains(cell)).count(), 1);
        }
        assert!(shards[1].contains(4));
        assert_eq!(shards[2].to_string(), "3/3");
    }

    #[test]
    fn rejects_malformed_shards() {
        for bad in ["0/3", "4/3", "3", "a/b", "1/0", ""] {
            assert_eq!(bad.parse::<Shard>(), Err(BadShard(bad.to_owned())), "{bad}");
        }
    }
}
