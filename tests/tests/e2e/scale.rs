//! Scale: a map four times the paper's side and a team of dozens train and run with the
//! paper's network unchanged. The mini-map is pooled to the L x L input (blocks of 4 on a
//! 100 x 100 map), and attention within a radius links near agents only.

use std::path::Path;
use std::sync::Arc;

use engine::episode::mean_penalty;
use learning::ppo::{Profile, Trainer, TrainingConfig};
use learning::{ActionChoice, LearnedPolicy};
use world::{Map, Seed, World, WorldParams};

/// 100 x 100 with rows of shelves (2 cells deep, gaps every 20 cells).
fn shelves() -> Arc<World> {
    let rows: Vec<String> = (0..100)
        .map(|y| {
            (0..100)
                .map(|x| {
                    let shelf = y % 12 == 5 || y % 12 == 6;
                    if shelf && (10..90).contains(&x) && x % 20 >= 4 {
                        '#'
                    } else {
                        '.'
                    }
                })
                .collect()
        })
        .collect();
    let map = Map::parse_text("shelves", &rows.join("\n"), Path::new("shelves.txt")).unwrap();
    World::new(map, WorldParams::paper())
}

fn config(overrides: &[&str]) -> TrainingConfig {
    let base = [
        "agents={\"min\":24,\"max\":24}",
        "steps_per_episode=3",
        "environments=2",
        "episodes=2",
        "neighbours={\"within_radius\":20}",
    ];
    let all: Vec<&str> = base.iter().chain(overrides).copied().collect();
    TrainingConfig::profile(Profile::FAST)
        .with_overrides(&all)
        .unwrap()
}

#[test]
fn a_large_map_and_team_train_and_run_with_the_papers_input_size() {
    let world = shelves();
    let config = config(&[]);
    let mut trainer = Trainer::new(world.clone(), config.clone(), 3).unwrap();
    assert_eq!(trainer.state().model.config().image_side, 25);
    let records = trainer.train(config.episodes, &mut |_| ()).unwrap();
    assert_eq!(records.len(), 2);
    assert!(
        records
            .iter()
            .all(|r| r.penalty.is_finite() && r.penalty > 0.0)
    );

    let model = trainer.state().model.clone();
    let mut policy = LearnedPolicy::new(&world, model, &config, ActionChoice::Greedy).unwrap();
    let penalty = mean_penalty(&world, 40, &mut policy, 5, 1, Seed::new(1)).unwrap();
    assert!(penalty.is_finite() && penalty > 0.0, "{penalty}");
}

#[test]
fn a_chosen_mini_map_block_sets_the_input_size() {
    let world = shelves();
    let config = config(&["mini_map_block=2"]);
    let trainer = Trainer::new(world, config, 3).unwrap();
    assert_eq!(trainer.state().model.config().image_side, 50);
    let zero = TrainingConfig::profile(Profile::FAST).with_overrides(&["mini_map_block=0"]);
    let message = zero.unwrap_err().to_string();
    assert!(
        message.contains("mini_map_block: must be at least 1"),
        "{message}"
    );
}
