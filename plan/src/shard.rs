//! Shards: `i/n` selects the i-th of n slices of a sweep's cells, balanced by estimated cost,
//! so that a job array of n tasks runs each cell once and its tasks end at about the same time.
//!
//! Every task computes the whole assignment from the whole cell list on its own: the slices are
//! disjoint and cover every cell without the tasks sharing anything.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::fmt;
use std::str::FromStr;

use crate::cell::SweepCell;

/// Shard `index` of `count`, counted from 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    index: usize,
    count: usize,
}

impl Shard {
    /// This shard's cells, in the scenario's order.
    pub fn select(self, cells: &[SweepCell]) -> Vec<&SweepCell> {
        slices(cells, self.count).swap_remove(self.index - 1)
    }
}

/// What the balance weighs a cell by: its estimated work, in which a training step weighs
/// far more than a test step.
pub fn weight(cell: &SweepCell) -> u64 {
    cell.config.cost().work
}

/// The cells split into `count` slices of about equal total weight, each in the scenario's
/// order.
pub fn slices(cells: &[SweepCell], count: usize) -> Vec<Vec<&SweepCell>> {
    let weights: Vec<u64> = cells.iter().map(weight).collect();
    let mut slices = vec![Vec::new(); count];
    for (cell, slice) in cells.iter().zip(balance(&weights, count)) {
        slices[slice].push(cell);
    }
    slices
}

/// The slice of each item. Longest processing time first: the heaviest item not yet placed
/// goes to the lightest slice so far; ties go to the earlier item and the lower slice, so the
/// split is a pure function of the weights.
fn balance(weights: &[u64], count: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..weights.len()).collect();
    order.sort_by_key(|&item| (Reverse(weights[item]), item));
    let mut loads: BinaryHeap<Reverse<(u64, usize)>> =
        (0..count).map(|slice| Reverse((0, slice))).collect();
    let mut owner = vec![0; weights.len()];
    for item in order {
        let Reverse((load, slice)) = loads.pop().expect("at least one slice");
        owner[item] = slice;
        loads.push(Reverse((load + weights[item], slice)));
    }
    owner
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
    use std::path::Path;

    use super::*;
    use crate::scenario::Scenario;

    /// `repetitions` cells of equal cost.
    fn equal_cells(repetitions: u32) -> Vec<SweepCell> {
        let text = format!(
            "name: unit\nseed: 3\nmaps:\n  - inline: {{name: m, grid: \"....\\n....\\n\"}}\n\
             world: {{fov: 3, test_steps: 20}}\npolicies:\n  - baseline: {{name: random}}\n\
             agents: {{test: [1]}}\nrepetitions: {repetitions}\ntest_episodes: 1\n"
        );
        Scenario::parse(&text, Path::new("unit.yaml"))
            .unwrap()
            .cells()
    }

    fn indices(slice: &[&SweepCell]) -> Vec<usize> {
        slice.iter().map(|c| c.index).collect()
    }

    #[test]
    fn shards_partition_the_cells() {
        let cells = equal_cells(20);
        for count in 1..=25 {
            let mut seen: Vec<usize> = (1..=count)
                .flat_map(|i| indices(&Shard { index: i, count }.select(&cells)))
                .collect();
            seen.sort();
            assert_eq!(seen, (0..cells.len()).collect::<Vec<_>>(), "{count} shards");
        }
    }

    #[test]
    fn equal_cells_are_dealt_in_turn() {
        let cells = equal_cells(7);
        let shard: Shard = "2/3".parse().unwrap();
        assert_eq!(indices(&shard.select(&cells)), [1, 4]);
        assert_eq!(shard.to_string(), "2/3");
    }

    #[test]
    fn the_heaviest_go_first_to_the_lightest_slice() {
        let weights = [8, 7, 6, 5, 4, 3, 2, 1, 1, 1];
        let owner = balance(&weights, 3);
        assert_eq!(owner, [0, 1, 2, 2, 1, 0, 0, 1, 2, 1]);
        let load = |slice| -> u64 {
            (0..10)
                .filter(|&i| owner[i] == slice)
                .map(|i| weights[i])
                .sum()
        };
        assert_eq!([load(0), load(1), load(2)], [13, 13, 12]);
    }

    #[test]
    fn more_slices_than_items_leaves_some_empty() {
        assert_eq!(balance(&[5, 9], 4), [1, 0]);
        assert_eq!(balance(&[], 2), Vec::<usize>::new());
    }

    #[test]
    fn rejects_malformed_shards() {
        for bad in ["0/3", "4/3", "3", "a/b", "1/0", ""] {
            assert_eq!(bad.parse::<Shard>(), Err(BadShard(bad.to_owned())), "{bad}");
        }
    }
}
