//! Who listens to whom in graph attention. A batch holds many groups (the agents of one
//! environment at one time step, stored as consecutive rows); edges never cross groups. The
//! graph is kept in compressed rows: the neighbours of agent `i` are
//! `neighbours[offsets[i]..offsets[i + 1]]`, in increasing order. Edge `e` is that position.
//!
//! Within a communication radius the neighbours come from a bucket grid of side r: an agent
//! looks in its own bucket and the eight around it only, so building the graph costs the
//! agents plus the candidate pairs, not N^2, and the attention layer's cost is its edges.

use std::ops::Range;

#[cfg(test)]
use super::error::NnError;

/// How the neighbours of an agent are chosen within its group.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Neighbours {
    /// Every other agent (the paper).
    AllOthers,
    /// Every agent, itself included (the authors' released code).
    AllAgents,
    /// Other agents at Euclidean distance at most this radius (limited communication).
    WithinRadius(f64),
}

/// The attention graph of a batch; cleared and refilled each step without reallocating.
#[derive(Debug, Clone)]
pub struct AgentGraph {
    offsets: Vec<usize>,
    neighbours: Vec<usize>,
    /// The group being added, as (bucket column, bucket row, agent), sorted.
    buckets: Vec<(i64, i64, usize)>,
}

impl Default for AgentGraph {
    fn default() -> Self {
        AgentGraph {
            offsets: vec![0],
            neighbours: Vec::new(),
            buckets: Vec::new(),
        }
    }
}

impl AgentGraph {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn clear(&mut self) {
        self.offsets.truncate(1);
        self.neighbours.clear();
    }

    /// Agents (batch rows) in all groups so far.
    pub fn agents(&self) -> usize {
        self.offsets.len() - 1
    }

    pub fn edges(&self) -> usize {
        self.neighbours.len()
    }

    /// The edges leaving agent `agent` (positions into [`AgentGraph::neighbour_rows`] and into
    /// per-edge arrays such as attention weights).
    pub(crate) fn edge_range(&self, agent: usize) -> Range<usize> {
        self.offsets[agent]..self.offsets[agent + 1]
    }

    /// The batch row of every edge's neighbour.
    pub fn neighbour_rows(&self) -> &[usize] {
        &self.neighbours
    }

    /// `(edge, neighbour row)` for every neighbour of `agent`.
    pub fn edges_of(&self, agent: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        let range = self.edge_range(agent);
        range.clone().zip(self.neighbours[range].iter().copied())
    }

    /// Appends a group of `positions.len()` agents; positions matter only for
    /// [`Neighbours::WithinRadius`].
    pub fn push_group(&mut self, rule: Neighbours, positions: &[[f64; 2]]) {
        match rule {
            Neighbours::AllOthers => self.push_with(positions.len(), |i, j| i != j),
            Neighbours::AllAgents => self.push_with(positions.len(), |_, _| true),
            Neighbours::WithinRadius(radius) => self.push_within(radius, positions),
        }
    }

    /// Other agents at distance at most `radius`, from the bucket grid (module doc).
    fn push_within(&mut self, radius: f64, positions: &[[f64; 2]]) {
        let first = self.agents();
        let side = radius.max(1.0);
        let bucket = |p: [f64; 2]| ((p[0] / side).floor() as i64, (p[1] / side).floor() as i64);
        self.buckets.clear();
        self.buckets
            .extend(positions.iter().enumerate().map(|(i, &p)| {
                let (bx, by) = bucket(p);
                (bx, by, i)
            }));
        self.buckets.sort_unstable();
        for (i, &p) in positions.iter().enumerate() {
            let start = self.neighbours.len();
            let (bx, by) = bucket(p);
            for column in bx - 1..=bx + 1 {
                let lo = self
                    .buckets
                    .partition_point(|b| (b.0, b.1) < (column, by - 1));
                let hi = self
                    .buckets
                    .partition_point(|b| (b.0, b.1) <= (column, by + 1));
                let near = self.buckets[lo..hi].iter().map(|b| b.2).filter(|&j| {
                    let (dx, dy) = (p[0] - positions[j][0], p[1] - positions[j][1]);
                    i != j && dx * dx + dy * dy <= radius * radius
                });
                self.neighbours.extend(near.map(|j| first + j));
            }
            self.neighbours[start..].sort_unstable();
            self.offsets.push(self.neighbours.len());
        }
    }

    /// Keeps, among the edges of the agents from batch row `first` on (the groups pushed
    /// since), those for which `keep(agent, neighbour)` holds, both as batch rows: the links
    /// that carry a message this step when robots are lost or links drop.
    pub fn retain_from(&mut self, first: usize, keep: impl Fn(usize, usize) -> bool) {
        let (mut write, mut read_start) = (self.offsets[first], self.offsets[first]);
        for agent in first..self.agents() {
            let read = read_start..self.offsets[agent + 1];
            read_start = read.end;
            for edge in read {
                let neighbour = self.neighbours[edge];
                if keep(agent, neighbour) {
                    self.neighbours[write] = neighbour;
                    write += 1;
                }
            }
            self.offsets[agent + 1] = write;
        }
        self.neighbours.truncate(write);
    }

    /// Appends a group of `agents` agents with a row-major adjacency: `adjacency[i * agents + j]`
    /// says whether agent `i` listens to agent `j`.
    #[cfg(test)]
    fn push_group_adjacency(&mut self, agents: usize, adjacency: &[bool]) -> Result<(), NnError> {
        if adjacency.len() != agents * agents {
            return Err(NnError::AdjacencyLength {
                agents,
                expected: agents * agents,
                got: adjacency.len(),
            });
        }
        self.push_with(agents, |i, j| adjacency[i * agents + j]);
        Ok(())
    }

    fn push_with(&mut self, agents: usize, listens: impl Fn(usize, usize) -> bool) {
        let first = self.agents();
        for i in 0..agents {
            let rows = (0..agents).filter(|&j| listens(i, j)).map(|j| first + j);
            self.neighbours.extend(rows);
            self.offsets.push(self.neighbours.len());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn retained_edges_are_those_kept_and_earlier_groups_are_untouched() {
        let mut graph = AgentGraph::new();
        graph.push_group(Neighbours::AllOthers, &[[0.0, 0.0]; 2]);
        graph.push_group(Neighbours::AllOthers, &[[0.0, 0.0]; 3]);
        // Row 3 is silent, and row 2 no longer hears row 4.
        graph.retain_from(2, |agent, neighbour| {
            neighbour != 3 && (agent, neighbour) != (2, 4)
        });
        let edges: Vec<Vec<usize>> = (0..graph.agents())
            .map(|a| graph.edges_of(a).map(|(_, n)| n).collect())
            .collect();
        assert_eq!(edges, [vec![1], vec![0], vec![], vec![2, 4], vec![2]]);
        assert_eq!(graph.edges(), 5);
    }

    #[test]
    fn groups_do_not_mix_and_rules_pick_the_right_neighbours() {
        let mut graph = AgentGraph::new();
        graph.push_group(Neighbours::AllOthers, &[[0.0, 0.0]; 3]);
        graph.push_group(Neighbours::AllAgents, &[[0.0, 0.0]; 2]);
        graph.push_group(
            Neighbours::WithinRadius(1.5),
            &[[0.0, 0.0], [1.0, 1.0], [3.0, 0.0]],
        );
        graph.push_group(Neighbours::AllOthers, &[[0.0, 0.0]]);
        assert_eq!(graph.agents(), 9);
        let of = |i: usize| graph.neighbour_rows()[graph.edge_range(i)].to_vec();
        assert_eq!(of(0), vec![1, 2]);
        assert_eq!(of(3), vec![3, 4]);
        assert_eq!(of(5), vec![6]);
        assert_eq!(of(7), Vec::<usize>::new());
        assert_eq!(of(8), Vec::<usize>::new());
        graph.clear();
        assert_eq!((graph.agents(), graph.edges()), (0, 0));
    }

    #[test]
    fn radius_buckets_find_exactly_the_agents_within_the_radius() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
        for radius in [0.0, 0.5, 1.0, 3.0, 7.5, 40.0, 1e6] {
            let positions: Vec<[f64; 2]> = (0..60)
                .map(|_| {
                    let mut c = || f64::from(rng.next_u32() % 50);
                    [c(), c()]
                })
                .collect();
            let mut graph = AgentGraph::new();
            graph.push_group(Neighbours::AllOthers, &positions[..3]);
            graph.push_group(Neighbours::WithinRadius(radius), &positions);
            for i in 0..positions.len() {
                let expected: Vec<usize> = (0..positions.len())
                    .filter(|&j| {
                        let (dx, dy) = (
                            positions[i][0] - positions[j][0],
                            positions[i][1] - positions[j][1],
                        );
                        i != j && (dx * dx + dy * dy).sqrt() <= radius
                    })
                    .map(|j| j + 3)
                    .collect();
                let got = graph.neighbour_rows()[graph.edge_range(i + 3)].to_vec();
                assert_eq!(got, expected, "agent {i}, radius {radius}");
            }
        }
    }

    #[test]
    fn adjacency_length_is_checked() {
        let mut graph = AgentGraph::new();
        assert!(graph.push_group_adjacency(2, &[true; 3]).is_err());
        graph
            .push_group_adjacency(2, &[false, true, false, false])
            .unwrap();
        assert_eq!(graph.neighbour_rows(), &[1]);
    }
}
