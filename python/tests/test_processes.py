"""Environments in other processes: a forked child (multiprocessing's default start method on
Linux) builds and steps worlds without hanging, and environments pickle from their
specification, as subprocess vector environments send them."""

import copy
import os
import pickle
import signal
import time
import traceback

import numpy as np
import pytest

import vpm_world
from conftest import MAPS

#: Seconds a forked child may take before it counts as hung (a step takes milliseconds).
CHILD_DEADLINE = 120


def exit_code_in_forked_child(work) -> int:
    """Runs `work` in a child made by `os.fork` and returns its exit code (0 when `work`
    returned); a child still running after `CHILD_DEADLINE` is killed and fails the test."""
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            work()
            code = 0
        except BaseException:
            traceback.print_exc()
        finally:
            os._exit(code)
    deadline = time.monotonic() + CHILD_DEADLINE
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return os.waitstatus_to_exitcode(status)
        time.sleep(0.05)
    os.kill(pid, signal.SIGKILL)
    os.waitpid(pid, 0)
    pytest.fail(f"the forked child did not finish in {CHILD_DEADLINE} s: it hangs")


def test_a_forked_child_builds_and_steps_a_world():
    vpm_world.World("open")  # the parent's threads, which the child does not inherit

    def child():
        env = vpm_world.ParallelEnv("four_room", 2, steps=3)
        env.reset(seed=1)
        env.step({a: 1 for a in env.agents})

    assert exit_code_in_forked_child(child) == 0


def test_a_vector_env_made_before_fork_steps_in_the_child_as_in_the_parent():
    vector = vpm_world.VectorEnv(4, "open", 2, steps=5)
    actions = np.ones((4, 2), dtype=np.int64)
    vector.reset(3)
    expected = vector.step(actions)

    def child():
        vector.reset(3)
        observations, rewards, _ = vector.step(actions)
        assert np.array_equal(observations, expected[0])
        assert np.array_equal(rewards, expected[1])

    assert exit_code_in_forked_child(child) == 0


def play(env, seed, steps=5):
    """The observations and rewards of `steps` steps from `reset(seed=seed)`."""
    observations, _ = env.reset(seed=seed)
    played = [observations]
    for t in range(steps):
        observations, rewards, *_ = env.step({a: (t + i) % 5 for i, a in
                                              enumerate(env.agents)})
        played += [observations, rewards]
    return played


def assert_same_play(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert x.keys() == y.keys()
        assert all(np.array_equal(x[k], y[k]) for k in x)


@pytest.mark.parametrize("restore", [lambda env: pickle.loads(pickle.dumps(env)), copy.deepcopy],
                         ids=["pickle", "deepcopy"])
def test_a_restored_parallel_env_plays_the_original_episodes(restore):
    env = vpm_world.ParallelEnv("four_room", 3, fov=15, decay=0.5, steps=30, channels="local",
                                mini_map_block=2, lose={"robots": 1, "at": 2})
    play(env, seed=8)
    restored = restore(env)
    assert type(restored) is vpm_world.ParallelEnv and restored is not env
    assert restored.world.observation_shape == env.world.observation_shape
    assert restored.world.observation_shape[0] == 1  # channels="local" came through
    assert_same_play(play(restored, seed=9), play(env, seed=9))


def test_a_parallel_env_on_a_map_file_pickles():
    env = vpm_world.ParallelEnv(f"{MAPS / 'paper-maps.yaml'}#open", 2, steps=10)
    assert_same_play(play(pickle.loads(pickle.dumps(env)), seed=4), play(env, seed=4))


def test_a_world_pickles_with_its_parameters():
    world = vpm_world.World("two_room", fov=9, decay=0.1, rmax=300.0, channels="mini",
                            mark_others_on_mini=True, mini_map_block=3)
    restored = pickle.loads(pickle.dumps(world))
    for name in ["map", "width", "height", "free_cells", "rmax", "observation_shape",
                 "observation_bounds"]:
        assert getattr(restored, name) == getattr(world, name), name
    a, b = vpm_world.Env(world, 2), vpm_world.Env(restored, 2)
    assert np.array_equal(a.reset(6), b.reset(6))
    assert np.array_equal(a.step([1, 4])[0], b.step([1, 4])[0])


def test_a_vector_env_pickles():
    vector = vpm_world.VectorEnv(3, "open", 2, steps=4, fov=11)
    restored = copy.deepcopy(vector)
    assert np.array_equal(restored.reset(2), vector.reset(2))
    actions = np.full((3, 2), 4)
    assert np.array_equal(restored.step(actions)[0], vector.step(actions)[0])


def supersuit_rewards(num_cpus: int) -> np.ndarray:
    """The rewards of 6 steps of SuperSuit's common recipe: the environment as a vector of its
    agents, two copies of it concatenated, in `num_cpus` subprocesses (0: in this one)."""
    import supersuit

    env = vpm_world.ParallelEnv("open", 2, steps=5, fov=11, channels="local")
    vector = supersuit.pettingzoo_env_to_vec_env_v1(env)
    vector = supersuit.concat_vec_envs_v1(vector, 2, num_cpus=num_cpus, base_class="gymnasium")
    try:
        observations, _ = vector.reset(seed=3)
        assert observations.shape == (4, 1, 11, 11)
        rewards = []
        for _ in range(6):  # past T = 5: the vector resets the episodes itself
            _, reward, _, _, _ = vector.step(np.ones(vector.num_envs, dtype=np.int64))
            rewards.append(reward)
        return np.array(rewards)
    finally:
        vector.close()


def test_supersuit_steps_the_environments_in_two_processes_as_in_one():
    assert np.array_equal(supersuit_rewards(num_cpus=2), supersuit_rewards(num_cpus=0))
