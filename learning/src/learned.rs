//! MA-G-PPO and MA-PPO as policies: observations of every agent, one batched forward pass of
//! the actor, an action per agent. The weights are shared by all agents, so a policy trained
//! with N agents runs with any number.

use rand_pcg::Pcg64Mcg;
use world::seed::purpose;
use world::{Action, Episode, Observer, Seed, World};

use crate::acting::{ActionChoice, push_agents, push_allowed_moves};
use crate::ppo::config::{ArchitectureName, BlockedMoves, ConfigError, TrainingConfig};
use nn::Real;
use nn::{ActorCritic, AgentGraph, Architecture, ModelWorkspace, Neighbours};
use world::{AttentionEdges, Policy};

/// A trained actor driving every agent of an episode.
#[derive(Debug)]
pub struct LearnedPolicy {
    name: &'static str,
    model: ActorCritic<f32>,
    neighbours: Neighbours,
    choice: ActionChoice,
    blocked_moves: BlockedMoves,
    /// The moves each agent may choose at the last step (empty: all).
    allowed: Vec<u8>,
    observer: Observer,
    workspace: ModelWorkspace<f32>,
    graph: AgentGraph,
    observations: Vec<f32>,
    points: Vec<[f64; 2]>,
    streams: Vec<Pcg64Mcg>,
    /// Actor and critic outputs for [`LearnedPolicy::inspect_last_step`].
    inspection: ModelWorkspace<f32>,
}

/// What the network saw and answered at one step, for every agent: the inputs and outputs
/// another implementation of the network must reproduce.
pub struct Inspection<'a> {
    /// Every agent's observation, `[agents, channels, side, side]` flat (NCHW).
    pub observations: &'a [f32],
    pub channels: usize,
    pub side: usize,
    /// Every agent's action probabilities, `[agents, 5]` (stay, +y, -x, -y, +x).
    pub probabilities: Vec<f32>,
    /// Every agent's value estimate.
    pub values: &'a [f32],
}

impl LearnedPolicy {
    /// Fails when the model was built for images of another side than `world` gives.
    pub fn new(
        world: &World,
        model: ActorCritic<f32>,
        config: &TrainingConfig,
        choice: ActionChoice,
    ) -> Result<Self, ConfigError> {
        let observer = Observer::new(world, config.observation_config());
        let expected = model.config().image_side;
        if observer.side() != expected {
            return Err(ConfigError::Invalid {
                field: "network",
                reason: format!(
                    "the model was trained on {expected} x {expected} images; map `{}` with \
                     L = {} gives {s} x {s}",
                    world.map().name(),
                    world.params().fov(),
                    s = observer.side()
                ),
            });
        }
        let name = match config.architecture {
            ArchitectureName::MaGPpo => "ma-g-ppo",
            ArchitectureName::MaPpo => "ma-ppo",
        };
        Ok(LearnedPolicy {
            name,
            model,
            neighbours: config.neighbours.to_nn(),
            choice,
            blocked_moves: config.blocked_moves,
            allowed: Vec::new(),
            observer,
            workspace: ModelWorkspace::default(),
            graph: AgentGraph::new(),
            observations: Vec::new(),
            points: Vec::new(),
            streams: Vec::new(),
            inspection: ModelWorkspace::default(),
        })
    }

    /// The observations of the last [`Policy::act`] and the whole network's outputs on them:
    /// the actor's probabilities and the critic's values, on the same attention graph.
    pub fn inspect_last_step(&mut self) -> Inspection<'_> {
        self.inspection.set_action_mask(&self.allowed);
        self.model
            .forward(&mut self.inspection, &self.observations, &self.graph);
        let probabilities = self
            .inspection
            .policy()
            .log_probs()
            .iter()
            .map(|l| l.exp_portable())
            .collect();
        let shape = self.model.config().observation_shape();
        Inspection {
            observations: &self.observations,
            channels: shape.channels,
            side: shape.height,
            probabilities,
            values: self.inspection.values(),
        }
    }
}

impl Policy for LearnedPolicy {
    fn name(&self) -> &str {
        self.name
    }

    fn attention(&self) -> Option<AttentionEdges> {
        if self.model.config().architecture == Architecture::MaPpo {
            return None;
        }
        let weights = self.workspace.attention().attention_weights();
        let heads = weights.nrows() as f32;
        let mut edges = Vec::with_capacity(self.graph.neighbour_rows().len());
        for agent in 0..self.graph.agents() {
            for (edge, neighbour) in self.graph.edges_of(agent) {
                let weight = weights.column(edge).sum() / heads;
                edges.push((agent, neighbour, weight));
            }
        }
        Some(edges)
    }

    fn reset(&mut self, episode: &Episode, seed: Seed) {
        let policy = seed.child(purpose::POLICY);
        self.streams = (0..episode.agents() as u64)
            .map(|agent| policy.child(agent).rng())
            .collect();
        self.observations
            .resize(episode.agents() * self.observer.per_agent(), 0.0);
    }

    fn act(&mut self, episode: &Episode, actions: &mut [Action]) {
        self.observer.write(episode, &mut self.observations);
        self.graph.clear();
        push_agents(
            &mut self.graph,
            self.neighbours,
            episode.positions(),
            &mut self.points,
        );
        if episode.messages_disturbed() {
            // A lost robot sends nothing, a link down carries nothing.
            self.graph
                .retain_from(0, |agent, neighbour| episode.hears(agent, neighbour));
        }
        self.allowed.clear();
        push_allowed_moves(self.blocked_moves, episode, &mut self.allowed);
        self.workspace.set_action_mask(&self.allowed);
        self.model
            .forward_policy(&mut self.workspace, &self.observations, &self.graph);
        let policy = self.workspace.policy();
        for (row, (action, stream)) in actions.iter_mut().zip(&mut self.streams).enumerate() {
            *action = Action::ALL[self.choice.pick(policy, row, stream)];
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::sync::Arc;

    use world::{Cell, Map, WorldParams};

    use super::*;
    use crate::ppo::Profile;

    /// An untrained policy of `profile` with a compact network and `overrides`, its weights
    /// from seed 1.
    fn untrained(
        world: &World,
        profile: Profile,
        overrides: &[&str],
        choice: ActionChoice,
    ) -> LearnedPolicy {
        let overrides = [&["network=compact"], overrides].concat();
        let config = TrainingConfig::profile(profile)
            .with_overrides(&overrides)
            .unwrap();
        let side = Observer::new(world, config.observation_config()).side();
        let model_config = config.model_config(side).unwrap();
        let model = ActorCritic::new(&model_config, &mut Seed::new(1).rng()).unwrap();
        LearnedPolicy::new(world, model, &config, choice).unwrap()
    }

    /// A one-row corridor of ten cells, walls all round.
    fn corridor() -> Arc<World> {
        let map = Map::parse_text("corridor", "..........\n", Path::new("c.txt")).unwrap();
        World::new(map, WorldParams::new(3, 1.0, 40.0).unwrap())
    }

    /// Who hears agent 2: the two others, until it is lost; then nobody, while the others
    /// still hear each other; with every link down, nobody hears anybody.
    #[test]
    fn a_lost_robot_or_a_link_down_carries_no_message() {
        let rows = vec![".".repeat(30); 30].join("\n");
        let map = Map::parse_text("open", &rows, Path::new("open.txt")).unwrap();
        let world = World::new(map, WorldParams::paper());
        let mut policy = untrained(&world, Profile::PaperV1, &[], ActionChoice::Greedy);
        let mut episode = Episode::new(world, 3).unwrap();
        episode.reset(Seed::new(2));
        policy.reset(&episode, Seed::new(3));
        let mut actions = [Action::Stay; 3];
        let senders = |policy: &LearnedPolicy| -> Vec<usize> {
            let edges = policy.attention().unwrap();
            edges.iter().map(|&(_, neighbour, _)| neighbour).collect()
        };
        policy.act(&episode, &mut actions);
        assert_eq!(senders(&policy), [1, 2, 0, 2, 0, 1]);
        episode.stop(2);
        policy.act(&episode, &mut actions);
        assert_eq!(senders(&policy), [1, 0, 0, 1]);
        episode.set_links(world::Links::new(None, 1.0, Seed::new(4)).unwrap());
        policy.act(&episode, &mut actions);
        assert!(senders(&policy).is_empty());
    }

    /// On a corridor with walls all round, an untrained policy that may choose every move is
    /// refused by walls often; with blocked moves masked, never, and its probabilities on
    /// them are exactly 0.
    #[test]
    fn a_policy_with_blocked_moves_masked_never_presses_against_a_wall() {
        let world = corridor();
        let refused = |rule: &str| -> (usize, f32) {
            let rule = format!("blocked_moves={rule}");
            let mut policy = untrained(&world, Profile::FastV1, &[&rule], ActionChoice::Sampled);
            let mut episode = Episode::new(world.clone(), 2).unwrap();
            episode.reset(Seed::new(2));
            policy.reset(&episode, Seed::new(3));
            let (mut walls, mut blocked_probability) = (0, 0.0f32);
            let mut actions = [Action::Stay; 2];
            for _ in 0..200 {
                policy.act(&episode, &mut actions);
                let inspected = policy.inspect_last_step().probabilities;
                // Up (+y) and down (-y) lead off a one-row map.
                blocked_probability += inspected.chunks(5).map(|p| p[1] + p[3]).sum::<f32>();
                episode.step(&actions);
                walls += (episode.refused().iter())
                    .filter(|r| **r == Some(world::Refusal::Wall))
                    .count();
            }
            (walls, blocked_probability)
        };
        let (walls, probability) = refused("allowed");
        assert!(walls > 50 && probability > 10.0, "{walls} {probability}");
        assert_eq!(refused("masked"), (0, 0.0));
    }

    /// Two robots side by side on a corridor: with robots masked too, an untrained policy
    /// puts no probability on a move onto the other's cell, and none on a wall's; with walls
    /// alone masked, some.
    #[test]
    fn a_policy_with_robots_masked_never_chooses_a_standing_robots_cell() {
        let world = corridor();
        let onto_robots = |rule: &str| -> f32 {
            let rule = format!("blocked_moves={rule}");
            let mut policy = untrained(&world, Profile::FastV1, &[&rule], ActionChoice::Sampled);
            let mut episode = Episode::new(world.clone(), 2).unwrap();
            episode
                .reset_at(&[Cell::new(4, 0), Cell::new(5, 0)])
                .unwrap();
            policy.reset(&episode, Seed::new(2));
            policy.act(&episode, &mut [Action::Stay; 2]);
            let inspected = policy.inspect_last_step().probabilities;
            // Robot 0's Right (4) and robot 1's Left (2) lead onto the other; Up and Down
            // (1, 3) off the map.
            let (zero, one) = (&inspected[..5], &inspected[5..]);
            assert_eq!(zero[1] + zero[3] + one[1] + one[3], 0.0, "walls are masked");
            zero[4] + one[2]
        };
        assert!(onto_robots("masked") > 0.1);
        assert_eq!(onto_robots("masked_with_robots"), 0.0);
    }
}
