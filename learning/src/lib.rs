//! The learned policies, MA-G-PPO and MA-PPO: PPO's training (`ppo`: rollouts, the update, its
//! profiles), checkpoints in safetensors that PyTorch loads (`checkpoint`), and the trained
//! network acting as a `world::Policy` (`LearnedPolicy`), on the network library `nn`. The
//! façade is what the plan and the engine build and act with; `ppo` and `checkpoint` are what
//! the engine, the benches and PyTorch interop reach into; `update_trace` writes one update
//! out whole for another implementation to recompute.
mod acting;
pub mod checkpoint;
mod learned;
pub mod ppo;
pub mod update_trace;

pub use acting::ActionChoice;
pub use learned::Inspection;
pub use learned::LearnedPolicy;
