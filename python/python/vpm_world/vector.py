"""A vector of environments: n episodes stepped in Rust threads in one call."""

from __future__ import annotations

import numpy as np

from . import _core


class VectorEnv:
    """``n`` environments of ``n_agents`` agents on one map, stepped together.

    ``reset(seed)`` starts environment k from ``episode_seed(seed, k)``, as the harness seeds
    test episode k of a cell; ``step(actions)`` takes an ``n x n_agents`` integer array and
    returns the observations (``n x n_agents x C x S x S``, float32), each environment's
    reward (``n``, the team's, <= 0) and whether the episodes have run their ``steps``.
    """

    def __init__(self, n: int, map: str = "open", n_agents: int = 4, *, steps: int = 2000,
                 **world):
        self.world = _core.World(map, **world)
        self._core = _core.VectorEnv(self.world, n, n_agents, steps)
        self.n, self.n_agents, self.steps = n, n_agents, steps

    def reset(self, seed: int) -> np.ndarray:
        return self._core.reset(seed)

    def step(self, actions) -> tuple[np.ndarray, np.ndarray, bool]:
        return self._core.step(np.asarray(actions, dtype=np.int64))

    def positions(self) -> list[list[tuple[int, int]]]:
        return self._core.positions()
