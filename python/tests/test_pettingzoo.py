"""PettingZoo's own API and seed tests, and the spaces the environment declares."""

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test
from pettingzoo.test.seed_test import parallel_seed_test

import vpm_world
from conftest import MAPS


@pytest.mark.parametrize("map_name", ["open", "eight_room"])
def test_pettingzoo_parallel_api(map_name):
    parallel_api_test(vpm_world.ParallelEnv(map_name, 4, steps=300), num_cycles=400)


def test_pettingzoo_parallel_api_with_robots_lost_mid_episode():
    env = vpm_world.ParallelEnv("four_room", 4, steps=200, lose={"robots": 2, "at": 50})
    parallel_api_test(env, num_cycles=300)


def test_pettingzoo_seed_test_over_many_steps():
    parallel_seed_test(lambda: vpm_world.ParallelEnv("eight_room", 3, steps=300), num_cycles=400)


def test_observations_lie_in_their_space_and_the_state_is_the_penalty_map():
    env = vpm_world.ParallelEnv("open", 4, steps=50)
    observations, infos = env.reset(seed=1)
    rng = np.random.default_rng(0)
    while env.agents:
        for agent, observation in observations.items():
            assert observation.shape == (2, 25, 25) and observation.dtype == np.float32
            assert env.observation_space(agent).contains(observation)
        state = env.state()
        assert env.state_space.contains(state)
        actions = {agent: int(rng.integers(5)) for agent in env.agents}
        observations, rewards, *_ = env.step(actions)
        free = state[state <= 0]
        # The team's reward is the sum of the free cells' penalties after the step.
        assert next(iter(rewards.values())) == pytest.approx(env.state()[env.state() <= 0].sum())
        assert len(free) == env.world.free_cells


def test_a_local_view_is_the_state_around_the_agent():
    """The first channel, independently: the 25 x 25 window of the penalty map around the
    agent (obstacles beyond the map's edge), agents marked 200, all times 1 / Rmax in float32
    (the world's scaling, one rounding fewer than a division in float64)."""
    env = vpm_world.ParallelEnv("four_room", 3, steps=40)
    observations, _ = env.reset(seed=11)
    rng = np.random.default_rng(1)
    for _ in range(30):
        observations, *_ = env.step({a: int(rng.integers(5)) for a in env.agents})
    state, positions, half = env.state(), env.positions(), 12
    padded = np.pad(state, half, constant_values=150.0)
    for agent, (x, y) in zip(env.possible_agents, positions):
        window = padded[y:y + 25, x:x + 25].copy()
        for (ox, oy) in positions:
            if abs(ox - x) <= half and abs(oy - y) <= half:
                window[oy - y + half, ox - x + half] = 200.0
        np.testing.assert_array_equal(observations[agent][0], window * (np.float32(1) / np.float32(400)))


def test_rgb_render_draws_every_cell():
    env = vpm_world.ParallelEnv("open", 2, render_mode="rgb_array")
    env.reset(seed=0)
    image = env.render()
    assert image.shape == (50 * 8, 50 * 8, 3) and image.dtype == np.uint8
    assert len(np.unique(image.reshape(-1, 3), axis=0)) >= 3


def test_maps_by_file_and_polygon_name_equal_the_paper_names():
    for spec in [str(MAPS / "open.txt"), f"{MAPS / 'paper-maps.yaml'}#open"]:
        by_file = vpm_world.ParallelEnv(spec, 4)
        by_name = vpm_world.ParallelEnv("open", 4)
        a, _ = by_file.reset(seed=9)
        b, _ = by_name.reset(seed=9)
        assert all(np.array_equal(a[k], b[k]) for k in a)
