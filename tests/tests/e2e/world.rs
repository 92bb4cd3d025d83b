//! The world against its definition: the paper's maps, the reference simulator, invariants.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use proptest::prelude::*;
use world::reference::ReferenceEpisode;
use world::{
    Action, Cell, Channels, Episode, Map, ObservationCodes, ObservationConfig, ObservationScale,
    Observer, Seed, World, WorldParams,
};

fn maps_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/maps")
}

const PAPER_MAPS: [(&str, usize); 4] = [
    ("open", 2142),
    ("four_room", 570),
    ("eight_room", 1410),
    ("two_room", 360),
];

#[test]
fn polygons_rasterise_to_the_text_grids_with_the_papers_free_counts() {
    for (name, free) in PAPER_MAPS {
        let text = Map::load_text(&maps_dir().join(format!("{name}.txt"))).unwrap();
        let spec = format!("{}#{name}", maps_dir().join("paper-maps.yaml").display());
        let polygon = Map::load(&spec).unwrap();
        assert_eq!(polygon.to_text(), text.to_text(), "{name}");
        assert_eq!(text.free_cells().len(), free, "{name}");
        assert_eq!((text.width(), text.height()), (50, 50));
    }
}

fn random_actions(rng: &mut impl rand::Rng, agents: usize) -> Vec<Action> {
    use rand::RngExt;
    (0..agents)
        .map(|_| Action::ALL[rng.random_range(0..5)])
        .collect()
}

/// Steps the fast and the reference simulator side by side and compares everything.
fn assert_same_as_reference(world: &Arc<World>, agents: usize, steps: usize, seed: u64) {
    let mut fast = Episode::new(world.clone(), agents).unwrap();
    let start_reward = fast.reset(Seed::new(seed));
    let (mut slow, slow_start) =
        ReferenceEpisode::new(world.map().clone(), *world.params(), fast.positions());
    assert_eq!(start_reward, slow_start, "step 0");
    let configs = [
        ObservationConfig::default(),
        ObservationConfig {
            channels: Channels::Mini,
            mark_others_on_mini: true,
            mini_map_block: Some(3),
            ..ObservationConfig::default()
        },
        ObservationConfig {
            codes: ObservationCodes::Released,
            scale: ObservationScale::Raw,
            ..ObservationConfig::default()
        },
        ObservationConfig {
            channels: Channels::Local,
            ..ObservationConfig::default()
        },
        ObservationConfig {
            mini_map_block: Some(1),
            ..ObservationConfig::default()
        },
    ];
    let mut observers: Vec<Observer> = configs.iter().map(|&c| Observer::new(world, c)).collect();
    let mut rng = Seed::new(seed).child(99).rng();
    for t in 1..=steps {
        let actions = random_actions(&mut rng, agents);
        let (a, b) = (fast.step(&actions), slow.step(&actions));
        assert_eq!(a, b, "reward at step {t}");
        assert_eq!(fast.positions(), slow.positions(), "positions at step {t}");
        if t % 25 == 0 || t == steps {
            for &cell in world.map().free_cells() {
                assert_eq!(
                    fast.penalty().at(cell),
                    slow.penalty(cell),
                    "{cell:?} at {t}"
                );
            }
            for observer in &mut observers {
                let mut buffer = vec![f32::NAN; agents * observer.per_agent()];
                observer.write(&fast, &mut buffer);
                let expected = slow.observe(observer.config(), observer.side());
                assert!(
                    buffer == expected,
                    "observation {:?} at step {t}",
                    observer.config()
                );
            }
        }
    }
}

#[test]
fn fast_simulator_matches_the_reference_on_the_paper_maps() {
    for (name, _) in PAPER_MAPS {
        let map = Map::load_text(&maps_dir().join(format!("{name}.txt"))).unwrap();
        let world = World::new(map, WorldParams::paper());
        assert_same_as_reference(&world, 4, 150, 11);
    }
}

#[test]
fn fast_simulator_matches_the_reference_with_odd_sides_and_small_windows() {
    let text = "#......#.\n..##.....\n.....#...\n...#.....\n.........\n#....##..\n.........\n";
    let map = Map::parse_text("odd", text, Path::new("odd.txt")).unwrap();
    for (fov, decay, rmax) in [(1, 1.0, 5.0), (3, 2.0, 7.0), (5, 0.5, 3.0), (9, 1.0, 400.0)] {
        let world = World::new(map.clone(), WorldParams::new(fov, decay, rmax).unwrap());
        assert_same_as_reference(&world, 5, 60, fov as u64);
    }
}

#[test]
fn fast_simulator_matches_the_reference_when_lane_sums_are_flushed_every_row() {
    // 1000 columns with Rmax = 10^6 could overflow exact f32 lane sums within one row, so the
    // update moves them into f64 after every row.
    let row: String = (0..1000)
        .map(|x| if x % 97 == 13 { '#' } else { '.' })
        .collect();
    let text = format!("{row}\n{row}\n{row}\n");
    let map = Map::parse_text("wide", &text, Path::new("wide.txt")).unwrap();
    let world = World::new(map, WorldParams::new(3, 1.0, 1e6).unwrap());
    assert_same_as_reference(&world, 3, 40, 5);
}

/// A random map: a grid of the given size with obstacles, at least `agents` free cells.
fn arbitrary_world() -> impl Strategy<Value = (Arc<World>, usize, u64)> {
    (
        3usize..14,
        3usize..14,
        0.0f64..0.45,
        0usize..4,
        1usize..6,
        any::<u64>(),
    )
        .prop_filter_map(
            "enough free cells",
            |(w, h, density, half, agents, seed)| {
                use rand::RngExt;
                let mut rng = Seed::new(seed).rng();
                let obstacle: Vec<bool> = (0..w * h).map(|_| rng.random_bool(density)).collect();
                let map = Map::from_obstacles("p", w, h, obstacle, Path::new("p")).ok()?;
                (map.free_cells().len() >= agents).then_some(())?;
                let params = WorldParams::new(2 * half + 1, 1.0, 6.0).unwrap();
                Some((World::new(map, params), agents, seed))
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn world_invariants_hold((world, agents, seed) in arbitrary_world()) {
        let mut episode = Episode::new(world.clone(), agents).unwrap();
        episode.reset(Seed::new(seed));
        let mut rng = Seed::new(seed).child(1).rng();
        let map = world.map();
        let rmax = world.params().rmax();
        for _ in 0..40 {
            episode.step(&random_actions(&mut rng, agents));
            let positions = episode.positions();
            for (i, &p) in positions.iter().enumerate() {
                prop_assert!(map.is_free(p), "agent on an obstacle");
                prop_assert!(!positions[..i].contains(&p), "two agents share a cell");
            }
            let mut total = 0.0;
            for &cell in map.free_cells() {
                let r = episode.penalty().at(cell);
                prop_assert!((-rmax..=0.0).contains(&r), "penalty {r} out of range");
                if positions.iter().any(|&a| world.visibility().sees(a, cell)) {
                    prop_assert_eq!(r.to_bits(), 0.0f32.to_bits(), "a seen cell is +0");
                }
                total += r as f64;
            }
            prop_assert_eq!(total, episode.reward());
        }
    }

    #[test]
    fn visibility_is_symmetric((world, _, _) in arbitrary_world()) {
        let (map, vis) = (world.map(), world.visibility());
        for &a in map.free_cells() {
            for b in vis.visible_cells(a) {
                prop_assert!(vis.sees(b, a), "{:?} sees {:?} but not back", a, b);
            }
        }
    }
}

/// Runs seeded episodes on a pool of `threads` threads and returns every reward and position.
fn traces_on(threads: usize, world: &Arc<World>) -> Vec<Vec<(u64, Vec<Cell>)>> {
    use rayon::prelude::*;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        (0..6u64)
            .into_par_iter()
            .map(|seed| {
                let mut episode = Episode::new(world.clone(), 4).unwrap();
                episode.reset(Seed::new(seed));
                let mut rng = Seed::new(seed).child(7).rng();
                (0..200)
                    .map(|_| {
                        let reward = episode.step(&random_actions(&mut rng, 4));
                        (reward.to_bits(), episode.positions().to_vec())
                    })
                    .collect()
            })
            .collect()
    })
}

#[test]
fn same_seed_gives_the_same_trace_whatever_the_thread_count() {
    let map = Map::load_text(&maps_dir().join("four_room.txt")).unwrap();
    let build = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| World::new(map.clone(), WorldParams::paper()))
    };
    let (one, two) = (build(1), build(2));
    assert_eq!(one.visibility(), two.visibility());
    assert_eq!(traces_on(1, &one), traces_on(2, &two));
}
