"""The PettingZoo ``ParallelEnv``: agent names, spaces, lost robots and truncation at T over
the Rust environment, which does the stepping and writes the observations."""

from __future__ import annotations

import functools
import operator
import secrets

import numpy as np
from gymnasium import logger, spaces
from pettingzoo import ParallelEnv as _ParallelEnv

from . import _core

#: The five actions, by index: the paper's numbering, as the harness.
ACTIONS = ("stay", "+y", "-x", "-y", "+x")


class ParallelEnv(_ParallelEnv):
    """Persistent monitoring on one map: every agent sees the team's reward, the step's sum of
    the cells' penalties (<= 0, unscaled; the harness's trainer scales it by its profile's
    ``reward_scale``). Observations are the network's input, ``C x S x S`` float32 (local view
    then mini-map, divided by Rmax). Episodes are truncated after ``steps`` steps (T).

    ``reset(seed=s)`` plays the episode ``harness run --seed s`` plays; ``reset()`` without a
    seed goes on to the next episode of the last seed's tree (``episode_seed(s, 1)``, 2, ...),
    or draws a seed when none was ever given. ``options`` may hold ``starts`` (an (x, y) per
    agent) and ``lose``, which overrides the constructor's for that episode.

    ``lose={"robots": [1, 3] or 2, "at": 500}`` is the scenario's disturbance: after ``at``
    steps these robots (or that many drawn from the episode's seed, as the harness draws them)
    are lost. They stay on their cells and no longer see; each is terminated at step ``at``
    and leaves ``agents``.

    ``max_memory`` (bytes; None for no limit): a world whose tables would take more (L = 255
    on a large map) is refused with ``MemoryError`` and the figure before it is built.

    Pickling (and ``copy.deepcopy``) copies the environment's specification, its constructor's
    arguments, not the episode in progress: the copy is a new environment, to be reset.
    """

    metadata = {"name": "vpm_v0", "render_modes": ["rgb_array"], "is_parallelizable": True}

    def __init__(self, map: str = "open", n_agents: int = 4, *, fov: int = 25,
                 decay: float = 1.0, rmax: float = 400.0, steps: int = 2000,
                 channels: str = "both", mark_others_on_mini: bool = False,
                 mini_map_block: int | None = None, lose: dict | None = None,
                 render_mode: str | None = None,
                 max_memory: int | None = _core.DEFAULT_MAX_MEMORY):
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self._spec = dict(map=map, n_agents=n_agents, fov=fov, decay=decay, rmax=rmax,
                          steps=steps, channels=channels,
                          mark_others_on_mini=mark_others_on_mini,
                          mini_map_block=mini_map_block, lose=lose, render_mode=render_mode,
                          max_memory=max_memory)
        self.world = _core.World(map, fov=fov, decay=decay, rmax=rmax, channels=channels,
                                 mark_others_on_mini=mark_others_on_mini,
                                 mini_map_block=mini_map_block, max_memory=max_memory)
        self._env = _core.Env(self.world, n_agents, steps)
        self._lose = _check_lose(lose, n_agents)
        self.render_mode = render_mode
        self.possible_agents = [f"agent_{i}" for i in range(n_agents)]
        self.agents = []
        self._index = {agent: i for i, agent in enumerate(self.possible_agents)}
        low, high = self.world.observation_bounds
        self._observation_space = spaces.Box(low=low, high=high,
                                             shape=self.world.observation_shape,
                                             dtype=np.float32)
        self._action_space = spaces.Discrete(len(ACTIONS))
        self.state_space = spaces.Box(low=-rmax, high=150.0,
                                      shape=(self.world.height, self.world.width),
                                      dtype=np.float32)
        self._root = None
        self._episodes = 0
        self._loss = None

    def __reduce__(self):
        """Rebuilt from the constructor's arguments, so that vector environments can send it to
        subprocesses (``multiprocessing``, SuperSuit's ``concat_vec_envs_v1``)."""
        return functools.partial(type(self), **self._spec), ()

    @functools.lru_cache(maxsize=None)
    def observation_space(self, agent):
        return self._observation_space

    @functools.lru_cache(maxsize=None)
    def action_space(self, agent):
        return self._action_space

    def reset(self, seed=None, options=None):
        options = dict(options or {})
        episode = self._next_seed(seed)
        lose = _check_lose(options["lose"], self.num_agents_possible) if "lose" in options \
            else self._lose
        observations = self._env.reset(episode, options.get("starts"))
        self.agents = self.possible_agents[:]
        self._loss = None
        if lose is not None:
            robots = lose["robots"]
            if isinstance(robots, int):
                robots = _core.lost_robots(episode, self.num_agents_possible, robots)
            self._loss = (lose["at"], sorted(set(robots)))
            if lose["at"] == 0:
                self._lose_now()
        self.seed = episode
        infos = self._infos(self.agents)
        return self._observations(observations), infos

    def step(self, actions):
        """Every agent in ``agents`` must have an action (an integer 0 to 4); the actions of
        agents already lost or terminated are ignored."""
        unknown = set(actions) - set(self._index)
        if unknown:
            raise KeyError(f"no such agents: {sorted(unknown)}")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"no actions for {missing}: every agent in env.agents needs one")
        indices = [0] * self.num_agents_possible
        for agent, action in actions.items():
            indices[self._index[agent]] = _integer(action, f"{agent}'s action")
        acting = self.agents[:]
        observations, reward = self._env.step(indices)
        lost = self._lose_now() if self._loss and self._env.time == self._loss[0] else set()
        over = self._env.time >= self._env.steps
        results = (
            {a: observations[self._index[a]] for a in acting},
            {a: reward for a in acting},
            {a: a in lost for a in acting},
            {a: over and a not in lost for a in acting},
            self._infos(acting),
        )
        if over:
            self.agents = []
        return results

    def state(self) -> np.ndarray:
        return self._env.state()

    def render(self):
        if self.render_mode is None:
            logger.warn("render() without a render_mode: make the environment with "
                        "render_mode='rgb_array'")
            return None
        return self._env.render()

    def close(self):
        pass

    @property
    def num_agents_possible(self) -> int:
        return len(self.possible_agents)

    def positions(self) -> list[tuple[int, int]]:
        """Every agent's cell (x, y), lost ones included."""
        return self._env.positions()

    def _next_seed(self, seed):
        if seed is not None:
            self._root, self._episodes = _checked_seed(seed), 0
            return self._root
        if self._root is None:
            self._root, self._episodes = secrets.randbits(64), 0
            return self._root
        self._episodes += 1
        return _core.episode_seed(self._root, self._episodes)

    def _lose_now(self) -> set:
        self._env.lose(self._loss[1])
        lost = {self.possible_agents[i] for i in self._loss[1]}
        self.agents = [a for a in self.agents if a not in lost]
        return lost

    def _observations(self, observations):
        return {a: observations[self._index[a]] for a in self.agents}

    def _infos(self, agents):
        """Each agent's cell, from one read of all the positions (not one per agent)."""
        positions = self._env.positions()
        return {a: {"position": positions[self._index[a]]} for a in agents}


def parallel_env(**kwargs) -> ParallelEnv:
    """PettingZoo's conventional constructor name."""
    return ParallelEnv(**kwargs)


def _integer(value, what: str) -> int:
    """``value`` as a Python int if it is an integer (int, a numpy integer or 0-d integer
    array, as gymnasium's ``Discrete`` takes); floats, strings and booleans are refused rather
    than rounded or parsed."""
    if not isinstance(value, (bool, np.bool_)):
        try:
            return operator.index(value)
        except TypeError:
            pass
    raise TypeError(f"{what} must be an integer, got {value!r} ({type(value).__name__})")


def _checked_seed(seed) -> int:
    """A seed: an integer from 0 to 2^64 - 1."""
    seed = _integer(seed, "seed")
    if not 0 <= seed < 2**64:
        raise ValueError(f"seed must be between 0 and 2^64 - 1, got {seed}")
    return seed


def _check_lose(lose, n_agents):
    """The ``lose`` option checked: robots named in range or a count, and a step."""
    if lose is None:
        return None
    if not isinstance(lose, dict) or set(lose) != {"robots", "at"}:
        raise ValueError(f"lose must be {{'robots': [...] or a count, 'at': step}}, got {lose!r}")
    robots, at = lose["robots"], lose["at"]
    if not isinstance(at, int) or at < 0:
        raise ValueError(f"lose['at'] must be a step >= 0, got {at!r}")
    if isinstance(robots, int):
        if not 0 <= robots <= n_agents:
            raise ValueError(f"lose['robots'] must be a count between 0 and {n_agents}, "
                             f"got {robots}")
    elif not all(isinstance(r, int) and 0 <= r < n_agents for r in robots):
        raise ValueError(f"lose['robots'] must name agents 0 to {n_agents - 1}, got {robots!r}")
    return {"robots": robots, "at": at}
