//! The baselines on the shipped maps: legal moves, complete tours, the paper's ordering against
//! Random, and reproducible sweeps.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use baselines::Baseline;
use baselines::Tspc;
use engine::episode::run_episode;
use world::Policy;
use world::paths::move_between;
use world::{Map, Seed, World, WorldParams};

fn maps_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/maps")
}

fn shipped_world(name: &str) -> Arc<World> {
    let map = Map::load_text(&maps_dir().join(format!("{name}.txt"))).unwrap();
    World::new(map, WorldParams::paper())
}

const SHIPPED: [&str; 4] = ["open", "two_room", "four_room", "eight_room"];

/// Mean cumulative penalty over `episodes` seeded episodes.
fn mean_penalty(world: &Arc<World>, policy: &mut dyn Policy, agents: usize, episodes: u64) -> f64 {
    let total: f64 = (0..episodes)
        .map(|e| {
            let seed = Seed::new(0).child(e);
            run_episode(world, agents, policy, seed, None, 2000, &mut |_, _| {})
                .unwrap()
                .cumulative_penalty
        })
        .sum();
    total / episodes as f64
}

#[test]
fn agents_never_enter_obstacles_and_move_one_cell_at_most() {
    for name in SHIPPED {
        let world = shipped_world(name);
        let map = world.map();
        for baseline in Baseline::ALL {
            let mut policy = baseline.build(&world).unwrap();
            for agents in [3, 10] {
                let mut previous: Option<Vec<world::Cell>> = None;
                let mut check = |episode: &world::Episode, _: Option<&[world::Action]>| {
                    let positions = episode.positions();
                    for (agent, &cell) in positions.iter().enumerate() {
                        assert!(map.is_free(cell), "{name} {baseline:?}: {cell:?}");
                        if let Some(before) = &previous {
                            let stayed = before[agent] == cell;
                            assert!(stayed || move_between(before[agent], cell).is_some());
                        }
                    }
                    previous = Some(positions.to_vec());
                };
                run_episode(
                    &world,
                    agents,
                    policy.as_mut(),
                    Seed::new(7),
                    None,
                    300,
                    &mut check,
                )
                .unwrap();
            }
        }
    }
}

#[test]
fn tspc_walk_is_closed_and_sees_every_free_cell() {
    for name in SHIPPED {
        let world = shipped_world(name);
        let walk = Tspc::new(&world).unwrap().walk().clone();
        for position in 0..walk.len() {
            let (here, next) = (walk.cell(position), walk.cell(position + 1));
            assert!(
                move_between(here, next).is_some(),
                "{name}: {here:?} -> {next:?}"
            );
        }
        let visibility = world.visibility();
        for &cell in world.map().free_cells() {
            let seen = walk.cells().iter().any(|&at| visibility.sees(at, cell));
            assert!(seen, "{name}: {cell:?} never seen from the walk");
        }
    }
}

#[test]
fn gcs_and_tspc_beat_random_widely_on_four_room() {
    let world = shipped_world("four_room");
    let mean = |baseline: Baseline| {
        let mut policy = baseline.build(&world).unwrap();
        mean_penalty(&world, policy.as_mut(), 2, 4)
    };
    let random = mean(Baseline::Random);
    let gcs = mean(Baseline::Gcs);
    let tspc = mean(Baseline::Tspc);
    assert!(gcs < 0.5 * random, "gcs {gcs} vs random {random}");
    assert!(tspc < 0.1 * random, "tspc {tspc} vs random {random}");
}

/// The released GCS on `open` with 4 agents, T = 2000, episode seeds 1 to 3 (the starts of
/// `harness run --seed 1..3`), in units of 10^6. The authors' code, ported onto an
/// independent implementation of our world rules, spread over 59 to 77 on these starts.
const GCS_OPEN_4: [f64; 3] = [59.085965, 60.629147, 66.132495];

#[test]
fn gcs_as_released_on_open_with_four_agents_and_the_paper_ordering() {
    let world = shipped_world("open");
    let penalties = |baseline: Baseline| -> Vec<f64> {
        let mut policy = baseline.build(&world).unwrap();
        (1..=3)
            .map(|seed| {
                let seed = Seed::new(seed);
                run_episode(&world, 4, policy.as_mut(), seed, None, 2000, &mut |_, _| {})
                    .unwrap()
                    .cumulative_penalty
                    / 1e6
            })
            .collect()
    };
    let mean = |values: &[f64]| values.iter().sum::<f64>() / values.len() as f64;
    let gcs = penalties(Baseline::Gcs);
    for (value, pinned) in gcs.iter().zip(GCS_OPEN_4) {
        assert!((value - pinned).abs() < 1e-6, "gcs {gcs:?}");
    }
    assert!((59.0..=77.0).contains(&mean(&gcs)), "gcs {gcs:?}");
    let (random, tspc) = (penalties(Baseline::Random), penalties(Baseline::Tspc));
    assert!(
        mean(&gcs) < 0.3 * mean(&random),
        "gcs {gcs:?} random {random:?}"
    );
    assert!(mean(&tspc) < mean(&gcs), "tspc {tspc:?} gcs {gcs:?}");
}

#[test]
fn tours_cannot_be_planned_on_disconnected_maps() {
    let map = Map::parse_text("split", "..#..\n..#..\n", Path::new("split.txt")).unwrap();
    let world = World::new(map, WorldParams::new(3, 1.0, 400.0).unwrap());
    for baseline in [Baseline::Tspc, Baseline::Partition] {
        let error = baseline.build(&world).err().expect("disconnected");
        assert!(error.to_string().contains("connected"), "{error}");
    }
    assert!(Baseline::Gcs.build(&world).is_ok());
}
