"""Bad values are refused with the harness's message, as Python exceptions naming the value."""

import numpy as np
import pytest

import vpm_world


@pytest.mark.parametrize("kwargs, words", [
    (dict(fov=24), "fov (L) must be odd"),
    (dict(decay=-1.0), "decay (D) must be finite and >= 0"),
    (dict(decay=float("nan")), "decay (D)"),
    (dict(rmax=0.0), "rmax must be finite and > 0"),
    (dict(map="nowhere"), "map `nowhere` is neither a paper map"),
    (dict(map="nowhere.txt#x"), "nowhere.txt"),
    (dict(n_agents=0), "n_agents must be at least 1"),
    (dict(n_agents=5000), "5000 agents do not fit"),
    (dict(steps=0), "steps (T) must be at least 1"),
    (dict(channels="all"), "channels must be local, mini or both"),
    (dict(mini_map_block=0), "mini_map_block must be at least 1"),
    (dict(lose={"robots": 9, "at": 3}), "lose['robots'] must be a count"),
    (dict(lose={"robots": [0, 7], "at": 3}), "lose['robots'] must name agents"),
    (dict(lose={"robots": 1, "at": -1}), "lose['at'] must be a step"),
    (dict(render_mode="human"), "render_mode"),
])
def test_bad_values_raise_value_errors_that_name_them(kwargs, words):
    with pytest.raises(ValueError, match=None) as error:
        vpm_world.ParallelEnv(**kwargs)
    assert words in str(error.value)


def test_a_wrong_type_is_a_type_error_not_a_crash():
    with pytest.raises(TypeError):
        vpm_world.ParallelEnv(fov="wide")
    with pytest.raises(OverflowError):
        vpm_world.ParallelEnv(n_agents=-1)


def test_bad_actions_starts_and_seeds_are_refused():
    env = vpm_world.ParallelEnv("open", 2, steps=3)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="agent 1's action 5 is not one of 0 to 4"):
        env.step({"agent_0": 0, "agent_1": 5})
    with pytest.raises(KeyError, match="agent_9"):
        env.step({"agent_9": 0})
    with pytest.raises(ValueError, match="start 1 .* is off the map"):
        env.reset(options={"starts": [(1, 1), (-1, 3)]})
    with pytest.raises(ValueError, match="not a free cell|obstacle|free"):
        env.reset(options={"starts": [(10, 8), (11, 8)]})
    with pytest.raises(ValueError, match="seed must be between"):
        env.reset(seed=-1)
    env.reset(seed=0)
    for _ in range(3):
        env.step({a: 0 for a in env.agents})
    assert env.agents == []
    with pytest.raises(ValueError, match="the episode is over"):
        env.step({})


def test_sizes_that_would_exhaust_memory_are_refused_not_allocated():
    with pytest.raises(ValueError, match="more than one call may return"):
        vpm_world.VectorEnv(10**9, "open", 4)
    with pytest.raises(ValueError, match="more than one call may return"):
        vpm_world.VectorEnv(2**62, "open", 4)


def test_vector_env_refuses_wrong_shapes():
    vector = vpm_world.VectorEnv(3, "open", 2, steps=5)
    vector.reset(0)
    with pytest.raises(ValueError, match="actions must be 3 x 2"):
        vector.step([[0, 0]])
    with pytest.raises(ValueError, match="n \\(environments\\) must be at least 1"):
        vpm_world.VectorEnv(0)


@pytest.mark.parametrize("action", [2.7, "3", True, np.float64(1.0), None])
def test_an_action_that_is_not_an_integer_is_a_type_error_naming_the_agent(action):
    env = vpm_world.ParallelEnv("open", 2, steps=3)
    env.reset(seed=0)
    with pytest.raises(TypeError, match="agent_1's action must be an integer"):
        env.step({"agent_0": 0, "agent_1": action})


def test_numpy_integer_actions_are_actions():
    env = vpm_world.ParallelEnv("open", 3, steps=3)
    env.reset(seed=0)
    env.step({"agent_0": np.int32(1), "agent_1": np.uint8(4), "agent_2": np.array(2)})
    assert env.action_space("agent_0").contains(np.int64(3))


@pytest.mark.parametrize("seed", [1.5, "7", True])
def test_a_seed_that_is_not_an_integer_is_a_type_error(seed):
    with pytest.raises(TypeError, match="seed must be an integer"):
        vpm_world.ParallelEnv("open", 2).reset(seed=seed)
    with pytest.raises(TypeError, match="seed must be an integer"):
        vpm_world.VectorEnv(2, "open", 2).reset(seed)


def test_a_numpy_integer_seed_is_the_same_seed():
    env = vpm_world.ParallelEnv("open", 2)
    env.reset(seed=np.uint64(7))
    positions = env.positions()
    env.reset(seed=7)
    assert env.positions() == positions


@pytest.mark.parametrize("actions", [np.full((2, 2), 1.0), [["1", "2"], ["3", "4"]],
                                     np.ones((2, 2), dtype=bool)])
def test_vector_actions_that_are_not_integers_are_type_errors(actions):
    vector = vpm_world.VectorEnv(2, "open", 2, steps=3)
    vector.reset(0)
    with pytest.raises(TypeError, match="actions must be integers"):
        vector.step(actions)


def test_a_step_before_reset_is_refused():
    with pytest.raises(ValueError, match="has not been reset: call reset first"):
        vpm_world.ParallelEnv("open", 2).step({"agent_0": 0, "agent_1": 0})
    with pytest.raises(ValueError, match="has not been reset"):
        vpm_world.Env(vpm_world.World("open"), 2).step([0, 0])
    with pytest.raises(ValueError, match="has not been reset"):
        vpm_world.VectorEnv(2, "open", 2).step(np.zeros((2, 2), dtype=int))


def test_every_agent_needs_an_action():
    env = vpm_world.ParallelEnv("open", 3, steps=3)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"no actions for \['agent_1'\]"):
        env.step({"agent_0": 0, "agent_2": 0})
    with pytest.raises(ValueError, match="no actions for"):
        env.step({})
    env.step({a: 0 for a in env.agents})
