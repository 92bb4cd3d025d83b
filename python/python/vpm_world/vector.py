"""A vector of environments: n episodes stepped in Rust threads in one call."""

from __future__ import annotations

import functools

import numpy as np

from . import _core
from .parallel import _checked_seed


class VectorEnv:
    """``n`` environments of ``n_agents`` agents on one map, stepped together.

    ``reset(seed)`` starts environment k from ``episode_seed(seed, k)``, as the harness seeds
    test episode k of a cell; ``step(actions)`` takes an ``n x n_agents`` integer array and
    returns the observations (``n x n_agents x C x S x S``, float32), each environment's
    reward (``n``, the team's, <= 0) and whether the episodes have run their ``steps``.

    ``max_memory`` (bytes; None for no limit) bounds the world and the environments together:
    above it the constructor raises ``MemoryError`` with the figure before building them.

    Pickling copies the specification (the constructor's arguments), not the episodes.
    """

    def __init__(self, n: int, map: str = "open", n_agents: int = 4, *, steps: int = 2000,
                 max_memory: int | None = _core.DEFAULT_MAX_MEMORY, **world):
        self.world = _core.World(map, max_memory=max_memory, **world)
        self._core = _core.VectorEnv(self.world, n, n_agents, steps, max_memory)
        self.n, self.n_agents, self.steps = n, n_agents, steps
        self._spec = dict(n=n, map=map, n_agents=n_agents, steps=steps, max_memory=max_memory,
                          **world)

    def __reduce__(self):
        return functools.partial(type(self), **self._spec), ()

    def reset(self, seed: int) -> np.ndarray:
        return self._core.reset(_checked_seed(seed))

    def step(self, actions) -> tuple[np.ndarray, np.ndarray, bool]:
        """``actions``: integers (any numpy integer type); floats, strings and booleans are
        refused, not rounded or parsed."""
        actions = np.asarray(actions)
        if not np.issubdtype(actions.dtype, np.integer):
            raise TypeError(f"actions must be integers, got an array of {actions.dtype}")
        return self._core.step(actions.astype(np.int64, copy=False))

    def positions(self) -> list[list[tuple[int, int]]]:
        return self._core.positions()
