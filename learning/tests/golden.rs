//! Golden values: numbers pinned in this file, so that a result that moves with the machine
//! fails here. Our machines change CPU from one day to the next (AVX-512 on some, AVX2 only on
//! others; different cache sizes), so this is a cross-machine check as well as a guard against
//! a change of arithmetic slipping in. A deliberate change of arithmetic (a new summing order)
//! re-pins these values, says so in its commit, and changes every cell key with the code.
//!
//! Pinned on an AMD EPYC with AVX2 and FMA, no AVX-512.

use std::path::Path;
use std::sync::Arc;

use learning::ppo::{Profile, Trainer, TrainingConfig};
use ndarray::{Array2, ShapeBuilder};
use nn::matmul::{matmul, matmul_add};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use world::{Map, World, WorldParams};

/// Shapes `(m, n, k)` that reach every path and edge: one element, the few-rows path (a
/// partial block of rows, a partial chunk of lanes), the packed path with partial tiles, more
/// than one `KC` block and `MC` block, row panels of `b` read in place, and a product large
/// enough to be split among threads.
const SHAPES: [(usize, usize, usize); 8] = [
    (1, 1, 1),
    (5, 17, 3),
    (16, 33, 1000),
    (17, 33, 257),
    (150, 20, 300),
    (20, 130, 600),
    (7, 3, 5000),
    (300, 200, 80),
];

fn random<T: From<f32>>(
    shape: (usize, usize),
    column_major: bool,
    rng: &mut Pcg64Mcg,
) -> Array2<T> {
    let values = (0..shape.0 * shape.1)
        .map(|_| T::from((rng.random::<f32>() - 0.5) * 2f32.powi(rng.random_range(-4..4))))
        .collect();
    Array2::from_shape_vec(shape.set_f(column_major), values).unwrap()
}

/// Every product of `SHAPES` in both memory orders, `c = a b` and `c += a b`, on `threads`
/// threads, hashed bit by bit.
fn products_hash<T>(threads: usize, bits: fn(&T) -> Vec<u8>) -> String
where
    T: nn::Real + From<f32>,
{
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let mut rng = Pcg64Mcg::seed_from_u64(12);
    let mut hasher = blake3::Hasher::new();
    for (m, n, k) in SHAPES {
        for (a_f, b_f) in [(false, false), (true, true), (false, true)] {
            let a = random::<T>((m, k), a_f, &mut rng);
            let b = random::<T>((k, n), b_f, &mut rng);
            let mut c = random::<T>((m, n), false, &mut rng);
            pool.install(|| matmul_add(a.view(), b.view(), c.view_mut()));
            c.iter().for_each(|x| {
                hasher.update(&bits(x));
            });
            pool.install(|| matmul(a.view(), b.view(), c.view_mut()));
            c.iter().for_each(|x| {
                hasher.update(&bits(x));
            });
        }
    }
    hasher.finalize().to_hex()[..16].to_owned()
}

#[test]
fn matrix_products_give_the_pinned_bits_at_any_thread_count() {
    let f32_bits = |x: &f32| x.to_le_bytes().to_vec();
    let f64_bits = |x: &f64| x.to_le_bytes().to_vec();
    for threads in [1, 2, 3] {
        assert_eq!(
            products_hash::<f32>(threads, f32_bits),
            "115ad546a12bd220",
            "f32, {threads} threads"
        );
        assert_eq!(
            products_hash::<f64>(threads, f64_bits),
            "54cc6bf54271644e",
            "f64, {threads} threads"
        );
    }
}

/// A short training run of the paper's network (L = 25) on the four-room map: two updates of
/// the `fast` profile, 2 agents, episodes of 100 steps.
fn train(architecture: &str) -> (Vec<f64>, String) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/maps/four_room.txt");
    let world = World::new(
        Map::load_text(&path).unwrap(),
        WorldParams::new(25, 1.0, 400.0).unwrap(),
    );
    let config = TrainingConfig::profile(Profile::FastV1)
        .with_overrides(&[
            format!("architecture={architecture}"),
            "agents={\"min\":2,\"max\":2}".to_owned(),
            "steps_per_episode=100".to_owned(),
            "episodes=16".to_owned(),
        ])
        .unwrap();
    let mut trainer = Trainer::new(Arc::clone(&world), config.clone(), 7).unwrap();
    let records = trainer.train(config.episodes, &mut |_| ()).unwrap();
    let penalties = records.iter().map(|r| r.penalty).collect();
    let mut hasher = blake3::Hasher::new();
    for value in trainer.state().model.params().values() {
        hasher.update(&value.to_le_bytes());
    }
    (penalties, hasher.finalize().to_hex()[..16].to_owned())
}

#[test]
fn a_short_training_run_gives_the_pinned_penalties_and_weights() {
    for (architecture, pinned_weights, pinned_penalties) in [
        (
            "ma_g_ppo",
            "8e0d35b2fcf9ffca",
            [
                1110926.0, 1315452.0, 1215235.0, 1421926.0, 1766979.0, 1568190.0, 1227929.0,
                1672766.0, 1158771.0, 1514688.0, 1323251.0, 1498403.0, 1979241.0, 1759750.0,
                1764774.0, 1425640.0,
            ],
        ),
        (
            "ma_ppo",
            "67aac3806885fa10",
            [
                1110926.0, 1315452.0, 1215235.0, 1422263.0, 1766979.0, 1568190.0, 1227929.0,
                1672766.0, 1158771.0, 1536495.0, 1257181.0, 1498403.0, 1975893.0, 1838024.0,
                1900309.0, 1405317.0,
            ],
        ),
    ] {
        let (penalties, weights) = train(architecture);
        println!("{architecture}: weights {weights}, penalties {penalties:?}");
        assert_eq!(
            penalties, pinned_penalties,
            "{architecture}: training penalties"
        );
        assert_eq!(weights, pinned_weights, "{architecture}: weights");
    }
}
