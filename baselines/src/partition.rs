//! Partitioned tours (beyond the paper): the viewpoints are split into one group per agent by
//! k-means on their coordinates, and each agent patrols its own short tour.
//!
//! The split depends only on the map and the number of agents: k-means is seeded from a fixed
//! node of the seed tree, so every episode with N agents patrols the same tours. Agents start
//! on their tours, as TSPC's do. With fewer viewpoints than agents each viewpoint is its own
//! group (a tour that stays put) and the surplus agents share groups round-robin.

use std::sync::Arc;

use linfa::DatasetBase;
use linfa::traits::{Fit, Predict};
use linfa_clustering::KMeans;
use ndarray::Array2;
use rand_core_06::SeedableRng;
use world::paths::BreadthFirst;
use world::{Action, Cell, Episode, Seed, World};

use crate::closed_walk::ClosedWalk;
use crate::error::BaselineError;
use crate::patrol::Patrol;
use crate::viewpoints::covering_viewpoints;
use world::Policy;

/// Root of the k-means seeds; its child for N agents seeds the split into N groups.
const SPLIT_SEED: u64 = 0x7061_7274;

pub(crate) struct Partition {
    world: Arc<World>,
    viewpoints: Vec<Cell>,
    /// The patrol for the last agent count planned for.
    patrol: Option<(usize, Patrol)>,
}

impl Partition {
    /// Fails when the viewpoints are not all connected, as no tour could join them.
    pub(crate) fn new(world: &Arc<World>) -> Result<Self, BaselineError> {
        let map = world.map();
        let viewpoints = covering_viewpoints(world);
        let mut search = BreadthFirst::new(map);
        search.explore(map, viewpoints[0]);
        if let Some(&cut_off) = viewpoints
            .iter()
            .find(|&&v| search.distance(map, v).is_none())
        {
            return Err(BaselineError::Disconnected {
                map: map.name().to_owned(),
                from: (viewpoints[0].x, viewpoints[0].y),
                to: (cut_off.x, cut_off.y),
            });
        }
        Ok(Self {
            world: world.clone(),
            viewpoints,
            patrol: None,
        })
    }

    /// The tours for `agents` agents, planned on first use.
    fn patrol(&mut self, agents: usize) -> &mut Patrol {
        if self
            .patrol
            .as_ref()
            .is_none_or(|(planned, _)| *planned != agents)
        {
            let map = self.world.map();
            let walks = split(&self.viewpoints, agents)
                .iter()
                .map(|group| ClosedWalk::through(map, group))
                .collect::<Result<Vec<_>, _>>()
                .expect("viewpoints are connected, as checked when planning began");
            self.patrol = Some((agents, Patrol::new(map, walks)));
        }
        &mut self.patrol.as_mut().expect("planned above").1
    }
}

/// At most `agents` (at least one) non-empty groups of viewpoints, in cluster order, each in viewpoint order.
fn split(viewpoints: &[Cell], agents: usize) -> Vec<Vec<Cell>> {
    let clusters = agents.max(1);
    if viewpoints.len() <= clusters {
        return viewpoints.iter().map(|&v| vec![v]).collect();
    }
    let coordinates = Array2::from_shape_fn((viewpoints.len(), 2), |(row, axis)| {
        let v = viewpoints[row];
        f64::from(if axis == 0 { v.x } else { v.y })
    });
    let seed = Seed::new(SPLIT_SEED).child(agents as u64).value();
    let rng = rand_pcg_03::Pcg64Mcg::seed_from_u64(seed);
    let dataset = DatasetBase::from(coordinates.clone());
    let model = KMeans::params_with_rng(clusters, rng)
        .fit(&dataset)
        .expect("k-means on more distinct points than clusters converges");
    let membership = model.predict(&coordinates);
    let mut groups = vec![Vec::new(); clusters];
    for (&group, &viewpoint) in membership.iter().zip(viewpoints) {
        groups[group].push(viewpoint);
    }
    groups.retain(|group| !group.is_empty());
    groups
}

impl Policy for Partition {
    fn name(&self) -> &str {
        "partition"
    }

    fn starts(&mut self, world: &World, agents: usize) -> Option<Vec<Cell>> {
        Some(self.patrol(agents).starts(world.map(), agents))
    }

    fn reset(&mut self, episode: &Episode, seed: Seed) {
        self.patrol(episode.agents()).reset(episode, seed);
    }

    fn act(&mut self, episode: &Episode, actions: &mut [Action]) {
        self.patrol(episode.agents()).act(episode, actions);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_points(count: u16) -> Vec<Cell> {
        (0..count)
            .map(|i| Cell::new(i % 6 * 8, i / 6 * 8))
            .collect()
    }

    #[test]
    fn groups_share_out_every_viewpoint_once() {
        let viewpoints = grid_points(30);
        for agents in [1, 2, 5, 10] {
            let groups = split(&viewpoints, agents);
            assert!(!groups.is_empty() && groups.len() <= agents);
            let mut all: Vec<Cell> = groups.concat();
            all.sort();
            let mut expected = viewpoints.clone();
            expected.sort();
            assert_eq!(all, expected, "{agents} agents");
            assert_eq!(split(&viewpoints, agents), groups, "seeded");
        }
    }

    #[test]
    fn fewer_viewpoints_than_agents_gives_one_viewpoint_each() {
        let viewpoints = grid_points(3);
        let groups = split(&viewpoints, 5);
        assert_eq!(
            groups,
            viewpoints.iter().map(|&v| vec![v]).collect::<Vec<_>>()
        );
    }
}
