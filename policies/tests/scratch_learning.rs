use policies::ppo::{Profile, Trainer, TrainingConfig};
use policies::{ActionChoice, LearnedPolicy, Policy, RandomPolicy};
use std::path::Path;
use std::time::Instant;
use world::{Action, Episode, Map, Seed, World, WorldParams};

const MAP: &str = "\
.......#........
.......#........
.......#........
.......#........
.......#........
.......#........
.......#........
................
................
.......#........
.......#........
.......#........
.......#........
.......#........
.......#........
.......#........
";

fn mean(
    world: &std::sync::Arc<World>,
    policy: &mut dyn Policy,
    agents: usize,
    steps: usize,
    n: u64,
) -> f64 {
    let mut total = 0.0;
    for k in 0..n {
        let mut ep = Episode::new(world.clone(), agents).unwrap();
        let seed = Seed::new(77).child(k);
        ep.reset(seed);
        policy.reset(&ep, seed);
        let mut actions = vec![Action::Stay; agents];
        for _ in 0..steps {
            policy.act(&ep, &mut actions);
            total -= ep.step(&actions);
        }
    }
    total / n as f64
}

#[test]
fn scratch() {
    let map = Map::parse_text("two_rooms_16", MAP, Path::new("m.txt")).unwrap();
    let world = World::new(map, WorldParams::new(7, 1.0, 400.0).unwrap());
    let sets: Vec<String> = std::env::var("SETS")
        .unwrap_or_default()
        .split_whitespace()
        .map(String::from)
        .collect();
    let mut overrides = vec![
        "network=compact".to_string(),
        "agents={\"min\":2,\"max\":2}".into(),
        "steps_per_episode=200".into(),
        "episodes=400".into(),
    ];
    overrides.extend(sets);
    let config = TrainingConfig::profile(Profile::Fast)
        .with_overrides(&overrides)
        .unwrap();
    let random = mean(&world, &mut RandomPolicy::new(), 2, 200, 10);
    println!("random {random:.0}");
    let start = Instant::now();
    let mut trainer = Trainer::new(world.clone(), config.clone(), 1).unwrap();
    let total = config.episodes;
    let mut next = 0;
    while trainer.state().episodes_done < total {
        next += 40;
        let recs = trainer.train(next, &mut |_| ()).unwrap();
        let p: f64 = recs.iter().map(|r| r.penalty).sum::<f64>() / recs.len() as f64;
        let r = recs.last().unwrap();
        let mut greedy = LearnedPolicy::new(
            &world,
            trainer.state().model.clone(),
            &config,
            ActionChoice::Greedy,
        )
        .unwrap();
        let g = mean(&world, &mut greedy, 2, 200, 10);
        let mut sampled = LearnedPolicy::new(
            &world,
            trainer.state().model.clone(),
            &config,
            ActionChoice::Sampled,
        )
        .unwrap();
        let s = mean(&world, &mut sampled, 2, 200, 10);
        println!(
            "ep {} t {:.1}s train {:.0} greedy {:.0} sampled {:.0} ratio {:.2} ent {:.3} vl {:.3} kl {:.4} roll {:.3} upd {:.3}",
            trainer.state().episodes_done,
            start.elapsed().as_secs_f64(),
            p,
            g,
            s,
            g / random,
            r.update.loss.entropy,
            r.update.loss.value,
            r.update.loss.approx_kl,
            r.rollout_seconds,
            r.update_seconds
        );
    }
}
