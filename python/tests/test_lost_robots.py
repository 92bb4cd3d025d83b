"""Robots lost mid-episode: terminated at the step they are lost, gone from `agents`, left
standing on their cells, and drawn from the episode's seed as the harness draws them."""

import numpy as np

import vpm_world


def test_lost_robots_leave_the_agents_and_stay_where_they_were():
    at, agents = 20, 4
    env = vpm_world.ParallelEnv("open", agents, steps=60, lose={"robots": 2, "at": at})
    env.reset(seed=8)
    lost = vpm_world.lost_robots(8, agents, 2)
    assert len(lost) == 2
    rng = np.random.default_rng(0)
    for t in range(1, at + 1):
        _, _, terminations, _, _ = env.step({a: int(rng.integers(1, 5)) for a in env.agents})
    names = {f"agent_{i}" for i in lost}
    assert {a for a, done in terminations.items() if done} == names
    assert not names & set(env.agents) and len(env.agents) == agents - 2
    where = [env.positions()[i] for i in lost]
    for _ in range(30):
        _, rewards, *_ = env.step({a: int(rng.integers(1, 5)) for a in env.agents})
        assert set(rewards) == set(env.agents)
    assert [env.positions()[i] for i in lost] == where


def test_robots_named_and_lost_from_the_start():
    env = vpm_world.ParallelEnv("open", 3, steps=10)
    observations, _ = env.reset(seed=1, options={"lose": {"robots": [1], "at": 0}})
    assert env.agents == ["agent_0", "agent_2"] and set(observations) == set(env.agents)
