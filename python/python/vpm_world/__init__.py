"""Visibility-based persistent monitoring from Python.

The world of vpm-harness (exact visibility, seeded starts, the same bits on every x86-64-v3
CPU) as a PettingZoo ``ParallelEnv`` and as a vector of environments stepped in Rust threads.
An episode played here with a seed and actions is the episode ``harness run --seed SEED
--actions FILE`` plays: the same rewards and positions at every step.
"""

from ._core import PAPER_MAPS, Env, VectorEnv as _VectorEnv, World, episode_seed, lost_robots
from .parallel import ACTIONS, ParallelEnv, parallel_env
from .vector import VectorEnv

__all__ = [
    "ACTIONS",
    "PAPER_MAPS",
    "Env",
    "ParallelEnv",
    "VectorEnv",
    "World",
    "episode_seed",
    "lost_robots",
    "parallel_env",
]

del _VectorEnv
