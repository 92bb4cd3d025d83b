//! The Random baseline: every agent draws one of the five actions uniformly.

use rand::RngExt;
use rand_pcg::Pcg64Mcg;
use world::seed::purpose;
use world::{Action, Episode, Seed};

use world::Policy;

/// Each agent draws from its own stream, so agent i's actions do not depend on how many
/// agents there are.
#[derive(Debug, Default)]
pub struct RandomPolicy {
    streams: Vec<Pcg64Mcg>,
}

impl RandomPolicy {
    pub fn new() -> Self {
        Self::default()
    }
}

impl Policy for RandomPolicy {
    fn name(&self) -> &str {
        "random"
    }

    fn reset(&mut self, episode: &Episode, seed: Seed) {
        let policy = seed.child(purpose::POLICY);
        self.streams = (0..episode.agents() as u64)
            .map(|agent| policy.child(agent).rng())
            .collect();
    }

    fn act(&mut self, _episode: &Episode, actions: &mut [Action]) {
        for (action, stream) in actions.iter_mut().zip(&mut self.streams) {
            *action = Action::ALL[stream.random_range(0..Action::ALL.len())];
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use world::{Map, World, WorldParams};

    use super::*;

    #[test]
    fn agents_draw_every_action_from_their_own_streams() {
        let map = Map::parse_text("t", "........\n........\n", Path::new("t.txt")).unwrap();
        let world = World::new(map, WorldParams::new(3, 1.0, 400.0).unwrap());
        let draw = |agents: usize| {
            let mut episode = Episode::new(world.clone(), agents).unwrap();
            episode.reset(Seed::new(1));
            let mut policy = RandomPolicy::new();
            policy.reset(&episode, Seed::new(1));
            let mut actions = vec![Action::Stay; agents];
            (0..500)
                .map(|_| {
                    policy.act(&episode, &mut actions);
                    actions[0]
                })
                .collect::<Vec<_>>()
        };
        let (two, three) = (draw(2), draw(3));
        assert_eq!(
            two, three,
            "agent 0's stream does not depend on the agent count"
        );
        for action in Action::ALL {
            let share = two.iter().filter(|&&a| a == action).count() as f64 / 500.0;
            assert!((share - 0.2).abs() < 0.06, "{action:?}: {share}");
        }
    }
}
