"""The same episodes as the harness: a seed and a sequence of actions played here and by
`harness run --seed S --actions FILE --trace FILE` give the same reward and positions at every
step, on text and polygon maps, from one environment and from a vector of them."""

import csv
import subprocess

import numpy as np
import pytest

import vpm_world
from conftest import MAPS

CASES = [
    ("open", str(MAPS / "open.txt"), 4, 7),
    ("eight_room", str(MAPS / "eight_room.txt"), 3, 2**63 + 5),
    (f"{MAPS / 'paper-maps.yaml'}#four_room", f"{MAPS / 'paper-maps.yaml'}#four_room", 6, 0),
]


def harness_trace(harness, tmp_path, map_file, agents, seed, actions):
    actions_file, trace_file = tmp_path / "actions.csv", tmp_path / "trace.csv"
    np.savetxt(actions_file, actions, fmt="%d", delimiter=",")
    subprocess.run([harness, "run", "--map", map_file, "--agents", str(agents), "--seed",
                    str(seed), "--actions", actions_file, "--trace", trace_file],
                   check=True, capture_output=True)
    with open(trace_file) as f:
        return list(csv.DictReader(f))


def positions_of(row, agents):
    return [(int(row[f"x{i}"]), int(row[f"y{i}"])) for i in range(agents)]


@pytest.mark.parametrize("map_name, map_file, agents, seed", CASES)
def test_an_episode_equals_the_harness_trace(harness, tmp_path, map_name, map_file, agents, seed):
    steps = 400
    actions = np.random.default_rng(seed % 1000).integers(0, 5, size=(steps, agents))
    trace = harness_trace(harness, tmp_path, map_file, agents, seed, actions)
    env = vpm_world.ParallelEnv(map_name, agents, steps=steps)
    env.reset(seed=seed)
    assert env.positions() == positions_of(trace[0], agents)
    for t in range(steps):
        _, rewards, *_ = env.step({f"agent_{i}": actions[t, i] for i in range(agents)})
        row = trace[t + 1]
        assert set(rewards.values()) == {float(row["reward"])}, f"step {t + 1}"
        assert env.positions() == positions_of(row, agents), f"step {t + 1}"
    assert env.agents == []


def test_a_vector_of_environments_plays_the_harness_episodes_of_each_seed(harness, tmp_path):
    n, agents, steps, root = 5, 3, 120, 42
    actions = np.random.default_rng(3).integers(0, 5, size=(steps, n, agents))
    vector = vpm_world.VectorEnv(n, "open", agents, steps=steps)
    vector.reset(root)
    rewards = []
    for t in range(steps):
        _, step_rewards, truncated = vector.step(actions[t])
        rewards.append(step_rewards)
        assert truncated == (t == steps - 1)
    final = vector.positions()
    for k in range(n):
        seed = vpm_world.episode_seed(root, k)
        trace = harness_trace(harness, tmp_path, str(MAPS / "open.txt"), agents, seed,
                              actions[:, k, :])
        assert [float(row["reward"]) for row in trace[1:]] == [r[k] for r in rewards]
        assert final[k] == positions_of(trace[-1], agents)


def test_unseeded_resets_go_on_down_the_last_seeds_tree():
    env = vpm_world.ParallelEnv("open", 2)
    env.reset(seed=5)
    env.reset()
    second = env.positions()
    env.reset(seed=vpm_world.episode_seed(5, 1))
    assert env.positions() == second
