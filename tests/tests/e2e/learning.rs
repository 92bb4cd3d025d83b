//! Learning, shown: the `fast` profile trains MA-G-PPO on a small two-room map (16 x 16,
//! L = 7, T = 200, 2 agents) to at most half of Random's mean test penalty, seeded.

use std::path::Path;
use std::sync::Arc;

use baselines::RandomPolicy;
use engine::episode::mean_penalty;
use learning::ppo::{Profile, Trainer, TrainingConfig};
use learning::{ActionChoice, LearnedPolicy};
use world::{Map, Seed, World, WorldParams};

const AGENTS: usize = 2;
const STEPS: usize = 200;
const TEST_EPISODES: u64 = 10;

fn small_two_room() -> Arc<World> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/maps/small_two_room.txt");
    let map = Map::load_text(&path).unwrap();
    assert_eq!((map.width(), map.height()), (16, 16));
    World::new(map, WorldParams::new(7, 1.0, 400.0).unwrap())
}

#[test]
fn the_fast_profile_halves_randoms_penalty_on_a_small_two_room_map() {
    if !crate::common::slow_test_runs("learning on a small two-room map") {
        return;
    }
    let world = small_two_room();
    let config = TrainingConfig::profile(Profile::FAST)
        .with_overrides(&[
            "network=compact",
            "agents={\"min\":2,\"max\":2}",
            "steps_per_episode=200",
            "episodes=400",
        ])
        .unwrap();
    let mut trainer = Trainer::new(world.clone(), config.clone(), 1).unwrap();
    let records = trainer.train(config.episodes, &mut |_| ()).unwrap();
    assert_eq!(records.len(), 400);

    let test_seed = Seed::new(2024);
    let evaluate = |policy: &mut dyn world::Policy| {
        mean_penalty(&world, AGENTS, policy, STEPS, TEST_EPISODES, test_seed).unwrap()
    };
    let random = evaluate(&mut RandomPolicy::new());
    let model = trainer.state().model.clone();
    let mut learned = LearnedPolicy::new(&world, model, &config, ActionChoice::Sampled).unwrap();
    let trained = evaluate(&mut learned);
    let first_rounds: f64 = records[..40].iter().map(|r| r.penalty).sum::<f64>() / 40.0;
    let last_rounds: f64 = records[360..].iter().map(|r| r.penalty).sum::<f64>() / 40.0;
    println!(
        "random {random:.0}, trained {trained:.0} ({:.2} of random); training penalty {first_rounds:.0} -> {last_rounds:.0}",
        trained / random
    );
    assert!(
        trained <= 0.5 * random,
        "trained {trained:.0} vs random {random:.0}"
    );
    assert!(last_rounds < first_rounds);
}
