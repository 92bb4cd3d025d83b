//! The benchmarks behind `harness bench`: speeds as ratios against references measured in the
//! same process (the machine's GEMM peak, one world step, the authors' environment), because a
//! ratio carries over between machines and a time does not.

pub use engine::cpu_clock;
pub mod network;
pub mod policy;
pub mod quality;
pub mod scale;
pub mod training;
pub mod world_steps;
