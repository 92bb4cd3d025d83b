//! Static coverage (beyond the paper): N cells chosen greedily to see as many free cells as
//! possible; each agent walks to one of them and stays.
//!
//! The paper observes that with many agents the best policy is nearly static; this baseline
//! measures how far a purely static one gets. Agents are matched to cells greedily by path
//! length (shortest first; ties to the lower agent, then the better-ranked cell), so agents
//! seldom cross each other's way; one that keeps being blocked plans around the agents
//! in its way. An agent standing on another's only way in still blocks it for good; on the
//! shipped maps every passage is three cells wide.

use std::sync::Arc;

use world::paths::BreadthFirst;
use world::{Action, Cell, Episode, Seed, World};

use crate::cover::greedy_max_coverage;
use crate::route::{Impatience, Route};
use crate::viewpoints::VisibilitySets;
use world::Policy;

pub(crate) struct StaticCoverage {
    world: Arc<World>,
    /// The greedy's first picks so far, best first: the picks for k agents are a prefix of
    /// those for more, so every episode's posts are read from here, and the greedy over the
    /// map's visibility sets runs again only for a larger team.
    ranked: Vec<Cell>,
    search: BreadthFirst,
    routes: Vec<Route>,
    impatience: Vec<Impatience>,
}

impl StaticCoverage {
    pub(crate) fn new(world: &Arc<World>) -> Self {
        Self {
            world: world.clone(),
            ranked: Vec::new(),
            search: BreadthFirst::new(world.map()),
            routes: Vec::new(),
            impatience: Vec::new(),
        }
    }

    /// The `agents` cells that together see the most, best first.
    fn posts(&mut self, agents: usize) -> Vec<Cell> {
        if self.ranked.len() < agents {
            let free = self.world.map().free_cells();
            let chosen = greedy_max_coverage(&VisibilitySets::new(&self.world), agents);
            self.ranked = chosen.iter().map(|&index| free[index]).collect();
        }
        self.ranked[..agents.min(self.ranked.len())].to_vec()
    }

    /// Pairs (agent, post), shortest path first; unreachable pairs are never matched.
    fn match_posts(&mut self, positions: &[Cell], posts: &[Cell]) -> Vec<Option<Cell>> {
        let map = self.world.map();
        let mut pairs = Vec::new();
        for (agent, &position) in positions.iter().enumerate() {
            self.search.explore(map, position);
            for (rank, &post) in posts.iter().enumerate() {
                if let Some(distance) = self.search.distance(map, post) {
                    pairs.push((distance, agent, rank));
                }
            }
        }
        pairs.sort_unstable();
        let mut matched = vec![None; positions.len()];
        let mut taken = vec![false; posts.len()];
        for (_, agent, rank) in pairs {
            if matched[agent].is_none() && !taken[rank] {
                matched[agent] = Some(posts[rank]);
                taken[rank] = true;
            }
        }
        matched
    }
}

impl Policy for StaticCoverage {
    fn name(&self) -> &str {
        "static"
    }

    fn reset(&mut self, episode: &Episode, seed: Seed) {
        self.impatience = (0..episode.agents())
            .map(|agent| Impatience::of_agent(seed, agent))
            .collect();
        let posts = self.posts(episode.agents());
        let matched = self.match_posts(episode.positions(), &posts);
        let map = self.world.map();
        self.routes.clear();
        for (&position, post) in episode.positions().iter().zip(matched) {
            let mut route = Route::default();
            if let Some(post) = post {
                self.search
                    .nearest(map, position, |cell| (cell == post).then_some(()));
                route.plan(&self.search, map, post);
            }
            self.routes.push(route);
        }
    }

    fn act(&mut self, episode: &Episode, actions: &mut [Action]) {
        let (map, positions) = (self.world.map(), episode.positions());
        let walkers = self.routes.iter_mut().zip(&mut self.impatience);
        for (((route, impatience), &position), action) in walkers.zip(positions).zip(actions) {
            *action =
                route.next_move_around(position, impatience, positions, &mut self.search, map);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use world::{Map, WorldParams};

    use super::*;

    #[test]
    fn agents_walk_to_the_best_posts_and_stay() {
        let text = ".......#.......\n.......#.......\n...............\n";
        let map = Map::parse_text("t", text, Path::new("t.txt")).unwrap();
        let world = World::new(map, WorldParams::new(5, 1.0, 400.0).unwrap());
        let mut policy = StaticCoverage::new(&world);
        let posts = policy.posts(2);
        let mut episode = Episode::new(world.clone(), 2).unwrap();
        episode
            .reset_at(&[Cell::new(0, 0), Cell::new(1, 0)])
            .unwrap();
        policy.reset(&episode, Seed::new(0));
        let mut actions = [Action::Stay; 2];
        for _ in 0..40 {
            policy.act(&episode, &mut actions);
            episode.step(&actions);
        }
        let mut at = episode.positions().to_vec();
        at.sort();
        let mut expected = posts.clone();
        expected.sort();
        assert_eq!(at, expected);
        policy.act(&episode, &mut actions);
        assert_eq!(actions, [Action::Stay; 2]);
    }
}
