//! Network speed: the `paper` profile's per-episode work on the paper's two models, against the
//! machine's GEMM peak measured in the same process.
//!
//! One training episode of the profile is `ROLLOUT_STEPS` policy forwards of one environment's
//! agents (the rollout) and `UPDATE_PASSES` forward + backward passes of actor and critic over
//! all of the episode's samples (the PPO update: 4 epochs, one minibatch each).
//!
//! Clocks: the rollout and every one-thread figure are this thread's CPU time, which a machine
//! shared with builds does not inflate. Parallel figures (the update and the peak with the
//! pool's threads) can only be wall time; they are the best of several repetitions, and are
//! pessimistic on a busy machine, so they come with the cores the process actually got.

use std::hint::black_box;
use std::time::{Duration, Instant};

use ndarray::Array2;
use nn::matmul::matmul;
use nn::{
    ACTIONS, ActorCritic, AgentGraph, Architecture, ModelConfig, ModelWorkspace, Neighbours,
    OutputGradients,
};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

use crate::cpu_clock::{process_cpu_time, thread_cpu_time};

/// Policy forwards per training episode (T).
pub const ROLLOUT_STEPS: usize = 1000;
/// Forward + backward passes over the episode's samples per update (4 epochs, 1 minibatch).
pub const UPDATE_PASSES: usize = 4;
/// Attention heads of the paper's MA-G-PPO.
const HEADS: usize = 3;
/// Side of the square GEMM that stands for the machine's peak.
const PEAK_SIDE: usize = 2048;

/// Best and median of repeated timings.
#[derive(Debug, Clone, Copy)]
pub struct Timing {
    pub best: Duration,
    pub median: Duration,
    /// For wall-time measurements, the process's CPU time per wall second over all of them:
    /// the cores the work actually got (below the pool size on a busy machine).
    pub cores_used: Option<f64>,
}

impl Timing {
    fn of(mut samples: Vec<Duration>) -> Self {
        samples.sort();
        Timing {
            best: samples[0],
            median: samples[samples.len() / 2],
            cores_used: None,
        }
    }
}

/// One model's figures.
pub struct ModelMeasurement {
    pub name: &'static str,
    /// FLOPs of one update pass, counted as 3 x the forward FLOPs (backward ~ 2 x forward).
    pub update_flops: f64,
    /// One update pass in a one-thread pool, thread CPU time.
    pub update_one_thread: Timing,
    /// One update pass with all the pool's threads, wall time.
    pub update_parallel: Timing,
    /// One rollout step (policy forward of one environment's agents), thread CPU time.
    pub rollout_step: Timing,
}

impl ModelMeasurement {
    /// Seconds per training episode: the rollout (one thread) plus the parallel update, from
    /// the best timings.
    pub fn episode_seconds(&self) -> f64 {
        self.rollout_seconds() + self.update_seconds()
    }

    pub fn rollout_seconds(&self) -> f64 {
        ROLLOUT_STEPS as f64 * self.rollout_step.best.as_secs_f64()
    }

    pub fn update_seconds(&self) -> f64 {
        UPDATE_PASSES as f64 * self.update_parallel.best.as_secs_f64()
    }
}

/// The GEMM peak: GFLOP/s of a large square `f32` product through the library's own GEMM
/// (the best kernel it has for this machine).
pub struct Peak {
    pub one_thread: f64,
    pub parallel: f64,
    pub parallel_cores_used: f64,
}

/// What the benchmark runs on.
pub struct NetworkBench {
    pub agents: usize,
    pub threads: usize,
    pub repeats: usize,
}

impl NetworkBench {
    pub fn measure_peak(&self) -> Peak {
        let a = Array2::from_shape_fn((PEAK_SIDE, PEAK_SIDE), |(i, j)| ((i + j) % 7) as f32);
        let b = a.t().to_owned();
        let mut c = Array2::<f32>::zeros((PEAK_SIDE, PEAK_SIDE));
        let mut product = || matmul(a.view(), b.view(), c.view_mut());
        let flops = 2.0 * (PEAK_SIDE as f64).powi(3);
        let one = self.in_pool(1, || self.cpu_timed(&mut product));
        let parallel = self.in_pool(self.threads, || self.wall_timed(&mut product));
        Peak {
            one_thread: flops / one.best.as_secs_f64() / 1e9,
            parallel: flops / parallel.best.as_secs_f64() / 1e9,
            parallel_cores_used: parallel.cores_used.unwrap_or(1.0),
        }
    }

    pub fn measure_model(&self, architecture: Architecture) -> ModelMeasurement {
        let name = match architecture {
            Architecture::MaPpo => "MA-PPO",
            Architecture::MaGPpo { .. } => "MA-G-PPO",
        };
        let mut rng = Pcg64Mcg::seed_from_u64(0);
        let config = ModelConfig::paper(architecture, 2);
        let mut model = ActorCritic::<f32>::new(&config, &mut rng).expect("paper shapes");
        let update = Batch::new(&config, ROLLOUT_STEPS, self.agents, &mut rng);
        let step = Batch::new(&config, 1, self.agents, &mut rng);
        let neighbours = self.agents - 1;
        let update_flops =
            3.0 * (update.samples() as u64 * model.forward_flops_per_sample(neighbours)) as f64;
        let mut ws = ModelWorkspace::default();
        let mut pass = || update.forward_backward(&mut model, &mut ws);
        let update_one_thread = self.in_pool(1, || self.cpu_timed(&mut pass));
        let update_parallel = self.in_pool(self.threads, || self.wall_timed(&mut pass));
        let mut rollout_ws = ModelWorkspace::default();
        let rollout_step = self.in_pool(1, || {
            self.cpu_timed_per(ROLLOUT_STEPS / 10, || {
                model.forward_policy(&mut rollout_ws, &step.observations, &step.graph);
                black_box(rollout_ws.policy());
            })
        });
        ModelMeasurement {
            name,
            update_flops,
            update_one_thread,
            update_parallel,
            rollout_step,
        }
    }

    pub fn architectures() -> [Architecture; 2] {
        [Architecture::MaPpo, Architecture::MaGPpo { heads: HEADS }]
    }

    fn in_pool<R: Send>(&self, threads: usize, work: impl FnOnce() -> R + Send) -> R {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool")
            .install(work)
    }

    /// One warm-up call, then `repeats` timed calls in this thread's CPU time.
    fn cpu_timed(&self, work: impl FnMut()) -> Timing {
        self.cpu_timed_per(1, work)
    }

    /// As [`NetworkBench::cpu_timed`], each timing being `calls` calls, divided by `calls`.
    fn cpu_timed_per(&self, calls: usize, mut work: impl FnMut()) -> Timing {
        work();
        let samples = (0..self.repeats)
            .map(|_| {
                let start = thread_cpu_time();
                (0..calls).for_each(|_| work());
                (thread_cpu_time() - start) / calls as u32
            })
            .collect();
        Timing::of(samples)
    }

    /// One warm-up call, then `repeats` timed calls in wall time.
    fn wall_timed(&self, mut work: impl FnMut()) -> Timing {
        work();
        let cpu_start = process_cpu_time();
        let samples: Vec<Duration> = (0..self.repeats)
            .map(|_| {
                let start = Instant::now();
                work();
                start.elapsed()
            })
            .collect();
        let cpu = process_cpu_time() - cpu_start;
        let wall: Duration = samples.iter().sum();
        Timing {
            cores_used: Some(cpu.as_secs_f64() / wall.as_secs_f64()),
            ..Timing::of(samples)
        }
    }
}

/// Random observations and output gradients for `groups` environments of `agents` agents, each
/// agent listening to all others (the paper's graph).
struct Batch {
    observations: Vec<f32>,
    graph: AgentGraph,
    output_grads: Vec<f32>,
}

impl Batch {
    fn new(config: &ModelConfig, groups: usize, agents: usize, rng: &mut Pcg64Mcg) -> Self {
        let mut graph = AgentGraph::new();
        for _ in 0..groups {
            graph.push_group(Neighbours::AllOthers, &vec![[0.0, 0.0]; agents]);
        }
        let samples = groups * agents;
        let mut draw = |len: usize| (0..len).map(|_| rng.random::<f32>() - 0.5).collect();
        Batch {
            observations: draw(samples * config.observation_shape().len()),
            graph,
            output_grads: draw(samples * (ACTIONS + 2)),
        }
    }

    fn samples(&self) -> usize {
        self.graph.agents()
    }

    /// One update pass: forward of actor and critic, then backward of a loss with these
    /// output gradients.
    fn forward_backward(&self, model: &mut ActorCritic<f32>, ws: &mut ModelWorkspace<f32>) {
        let batch = self.samples();
        model.params_mut().zero_grads();
        model.forward(ws, &self.observations, &self.graph);
        let (log_probs, rest) = self.output_grads.split_at(batch * ACTIONS);
        let (entropy, values) = rest.split_at(batch);
        let output_grads = OutputGradients {
            log_probs: ndarray::ArrayView2::from_shape((batch, ACTIONS), log_probs)
                .expect("one gradient per action"),
            entropy,
            values,
            attention_entropy: 0.01,
            head_mean_attention_entropy: 0.0,
        };
        model.backward(ws, &self.observations, &self.graph, &output_grads);
        black_box(model.params().grads());
    }
}
