//! Episodes of several environments run side by side: every step, the environments observe
//! and step in parallel (rayon), and the actor runs once on all agents of all environments.
//!
//! Every environment owns its episode's record, so parallel writes never share a buffer, and
//! its random streams come from its episode's seed, so the thread count changes nothing.

use std::sync::Arc;

use rand::RngExt;
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use world::seed::purpose;
use world::{Action, Episode, Observer, Seed, StartError, World};

use crate::acting::{ActionChoice, push_agents, push_allowed_moves};
use crate::ppo::config::{BlockedMoves, RewardScale, TrainingConfig};
use nn::{ActorCritic, AgentGraph, ModelWorkspace, Neighbours};

/// One environment's episode and its record, `[step][agent]` throughout.
#[derive(Debug)]
pub(crate) struct EnvironmentRollout {
    episode: Episode,
    observer: Observer,
    streams: Vec<Pcg64Mcg>,
    current: Vec<Action>,
    reward_scale: f32,
    /// The robot this episode loses and the step after which it stops (`loss_probability`).
    loss: Option<(usize, usize)>,
    pub(crate) agents: usize,
    pub(crate) steps: usize,
    /// `steps + 1` observations per agent: the last one bootstraps GAE.
    pub(crate) observations: Vec<f32>,
    /// Agent positions at each of the `steps + 1` observations, for the attention graph.
    positions: Vec<world::Cell>,
    /// Where blocked moves are masked, the moves each agent may choose at each of the
    /// `steps + 1` observations (`acting::push_allowed_moves`); else empty.
    blocked_moves: BlockedMoves,
    allowed: Vec<u8>,
    pub(crate) actions: Vec<u8>,
    pub(crate) log_probs: Vec<f32>,
    /// One scaled reward per step, shared by the team.
    pub(crate) rewards: Vec<f32>,
    /// The paper's metric: the sum of |reward| over steps 1..=T.
    pub(crate) penalty: f64,
    /// When recorded (an update's trace): the map of every observation, `[step][y][x]`,
    /// obstacles 150 and free cells their penalty.
    pub(crate) penalty_maps: Option<Vec<f32>>,
}

impl EnvironmentRollout {
    /// An episode of training episode index `seed`, with its agent count drawn from the
    /// configured range, reset to its start.
    pub(crate) fn new(
        world: &Arc<World>,
        config: &TrainingConfig,
        seed: Seed,
    ) -> Result<Self, StartError> {
        let (min, max) = (config.agents.min, config.agents.max);
        let agents = seed
            .child(purpose::AGENT_COUNT)
            .rng()
            .random_range(min..=max);
        let mut episode = Episode::new(world.clone(), agents)?;
        episode.reset(seed);
        let observer = Observer::new(world, config.observation_config());
        let policy = seed.child(purpose::POLICY);
        let streams = (0..agents as u64).map(|a| policy.child(a).rng()).collect();
        let steps = config.steps_per_episode;
        let loss = (config.loss_probability > 0.0)
            .then(|| {
                let mut rng = seed.child(purpose::LOST_ROBOTS).rng();
                (rng.random::<f64>() < config.loss_probability)
                    .then(|| (rng.random_range(0..agents), rng.random_range(1..steps)))
            })
            .flatten();
        let reward_scale = match config.reward_scale {
            RewardScale::Raw => 1.0,
            RewardScale::PerCell => {
                1.0 / (world.map().free_cells().len() as f32 * world.params().rmax())
            }
        };
        let mut rollout = EnvironmentRollout {
            observations: vec![0.0; (steps + 1) * agents * observer.per_agent()],
            positions: Vec::with_capacity((steps + 1) * agents),
            blocked_moves: config.blocked_moves,
            allowed: Vec::new(),
            actions: vec![0; steps * agents],
            log_probs: vec![0.0; steps * agents],
            rewards: vec![0.0; steps],
            penalty: 0.0,
            penalty_maps: None,
            episode,
            observer,
            streams,
            current: vec![Action::Stay; agents],
            reward_scale,
            loss,
            agents,
            steps,
        };
        rollout.observe(0);
        Ok(rollout)
    }

    /// Floats per agent observation.
    pub(crate) fn per_agent(&self) -> usize {
        self.observer.per_agent()
    }

    /// The side of every image.
    pub(crate) fn side(&self) -> usize {
        self.observer.side()
    }

    /// All agents' observations at step `t`.
    fn observation(&self, t: usize) -> &[f32] {
        let len = self.agents * self.per_agent();
        &self.observations[t * len..(t + 1) * len]
    }

    /// Starts recording the map of every observation, the one already made included.
    pub(crate) fn record_penalty_maps(&mut self) {
        self.penalty_maps = Some(Vec::new());
        self.record_penalty_map();
    }

    fn record_penalty_map(&mut self) {
        let Some(maps) = self.penalty_maps.as_mut() else {
            return;
        };
        let map = self.episode.world().map();
        for y in 0..map.height() {
            for x in 0..map.width() {
                let cell = world::Cell::new(x as u16, y as u16);
                maps.push(self.episode.penalty().at(cell));
            }
        }
    }

    pub(crate) fn positions_at(&self, t: usize) -> &[world::Cell] {
        &self.positions[t * self.agents..(t + 1) * self.agents]
    }

    /// Appends step `t`'s observations, the moves its agents may choose (where masked) and its
    /// group of agents to a batch being assembled (the rollout's policy batch, the update's
    /// minibatches).
    pub(crate) fn push_step(
        &self,
        t: usize,
        neighbours: Neighbours,
        (observations, allowed): (&mut Vec<f32>, &mut Vec<u8>),
        graph: &mut AgentGraph,
        points: &mut Vec<[f64; 2]>,
    ) {
        observations.extend_from_slice(self.observation(t));
        if !self.allowed.is_empty() {
            allowed.extend_from_slice(&self.allowed[t * self.agents..(t + 1) * self.agents]);
        }
        let first = graph.agents();
        push_agents(graph, neighbours, self.positions_at(t), points);
        // As at test time: nobody hears a robot from the step it is lost.
        if let Some((robot, at)) = self.loss
            && t >= at
        {
            graph.retain_from(first, |_, neighbour| neighbour != first + robot);
        }
    }

    fn observe(&mut self, t: usize) {
        let len = self.agents * self.observer.per_agent();
        let out = &mut self.observations[t * len..(t + 1) * len];
        self.observer.write(&self.episode, out);
        self.positions.extend_from_slice(self.episode.positions());
        push_allowed_moves(self.blocked_moves, &self.episode, &mut self.allowed);
        self.record_penalty_map();
    }

    /// Draws step `t`'s actions from rows `first..` of the batch's policy.
    fn choose(&mut self, t: usize, policy: &nn::CategoricalBatch<f32>, first: usize) {
        let log_probs = policy.log_probs();
        for agent in 0..self.agents {
            let row = first + agent;
            let action = ActionChoice::Sampled.pick(policy, row, &mut self.streams[agent]);
            self.current[agent] = Action::ALL[action];
            self.actions[t * self.agents + agent] = action as u8;
            self.log_probs[t * self.agents + agent] = log_probs[[row, action]];
        }
    }

    fn advance(&mut self, t: usize) {
        let reward = self.episode.step(&self.current);
        self.penalty -= reward;
        self.rewards[t] = reward as f32 * self.reward_scale;
        if let Some((robot, at)) = self.loss
            && at == t + 1
        {
            self.episode.stop(robot);
        }
        self.observe(t + 1);
    }
}

/// The actor's batch buffers, reused across steps and rounds.
#[derive(Debug, Default)]
pub(crate) struct RolloutWorkspace {
    observations: Vec<f32>,
    allowed: Vec<u8>,
    graph: AgentGraph,
    points: Vec<[f64; 2]>,
    model: ModelWorkspace<f32>,
}

impl RolloutWorkspace {
    /// Runs every environment to the end of its episode.
    pub(crate) fn run(
        &mut self,
        model: &ActorCritic<f32>,
        neighbours: Neighbours,
        environments: &mut [EnvironmentRollout],
    ) {
        let steps = environments.first().map_or(0, |e| e.steps);
        for t in 0..steps {
            self.observations.clear();
            self.allowed.clear();
            self.graph.clear();
            for env in environments.iter() {
                env.push_step(
                    t,
                    neighbours,
                    (&mut self.observations, &mut self.allowed),
                    &mut self.graph,
                    &mut self.points,
                );
            }
            self.model.set_action_mask(&self.allowed);
            model.forward_policy(&mut self.model, &self.observations, &self.graph);
            let mut first = 0;
            for env in environments.iter_mut() {
                env.choose(t, self.model.policy(), first);
                first += env.agents;
            }
            environments.par_iter_mut().for_each(|env| env.advance(t));
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use world::{Map, WorldParams};

    use super::*;

    #[test]
    fn a_training_episode_with_a_loss_stops_the_robot_and_cuts_its_messages() {
        let text = "########\n#..#...#\n#......#\n#..#...#\n#..#...#\n########\n";
        let map = Map::parse_text("tiny", text, Path::new("tiny.txt")).unwrap();
        let world = World::new(map, WorldParams::new(5, 1.0, 40.0).unwrap());
        let config = crate::ppo::TrainingParams {
            agents: crate::ppo::AgentCount::fixed(3),
            steps_per_episode: 10,
            loss_probability: 1.0,
            ..TrainingConfig::profile(crate::ppo::Profile::FastV1).params()
        };
        let config = config.check().unwrap();
        let mut rollout = EnvironmentRollout::new(&world, &config, Seed::new(4)).unwrap();
        let (robot, at) = rollout.loss.expect("a loss with probability 1");
        assert!(robot < 3 && (1..10).contains(&at), "{robot} after {at}");
        for t in 0..10 {
            rollout.current = vec![Action::Right; 3];
            rollout.advance(t);
        }
        assert!(rollout.episode.stopped()[robot]);
        let (mut observations, mut graph, mut points) = (Vec::new(), AgentGraph::new(), Vec::new());
        let hearers = |graph: &AgentGraph, first: usize| -> usize {
            (first..first + 3)
                .filter(|&a| graph.edges_of(a).any(|(_, n)| n == first + robot))
                .count()
        };
        rollout.push_step(
            at - 1,
            Neighbours::AllOthers,
            (&mut observations, &mut Vec::new()),
            &mut graph,
            &mut points,
        );
        assert_eq!(hearers(&graph, 0), 2, "heard before the loss");
        rollout.push_step(
            at,
            Neighbours::AllOthers,
            (&mut observations, &mut Vec::new()),
            &mut graph,
            &mut points,
        );
        assert_eq!(hearers(&graph, 3), 0, "nobody hears it from the loss on");
        // The others still hear each other (2 edges), and the lost robot them (2; what it
        // does no longer matters).
        assert_eq!(graph.edges(), 6 + 4);
        let again = EnvironmentRollout::new(&world, &config, Seed::new(4)).unwrap();
        assert_eq!(again.loss, rollout.loss, "drawn from the episode's seed");
        let never = crate::ppo::TrainingParams {
            loss_probability: 0.0,
            ..config.params()
        };
        let never = never.check().unwrap();
        assert_eq!(
            EnvironmentRollout::new(&world, &never, Seed::new(4))
                .unwrap()
                .loss,
            None
        );
    }
}
