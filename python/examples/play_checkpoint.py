"""Plays the Python environment with a harness checkpoint loaded into the paper's network in
PyTorch, greedily, and checks it against the harness.

    harness run --map scenarios/maps/open.txt --agents 4 --policy checkpoint:DIR --greedy \\
        --seed 1 --steps 200 --probe probe.parquet --probe-steps 0,50,199
    python python/examples/play_checkpoint.py DIR --map open --agents 4 --seed 1 --steps 200 \\
        --probe probe.parquet

The environment starts where `harness run --seed 1` starts, every agent takes its most probable
action; at the probed steps the observations, action probabilities and values are compared with
the harness's (`--probe`, read with pyarrow): it fails if a probability differs by more than
1e-5 or an action or cell differs. Needs torch, safetensors and pyarrow beside vpm_world.
"""

import argparse
import sys

import numpy as np
import torch

import vpm_world
from paper_network import edges, load_checkpoint

TOLERANCE = 1e-5


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoint", help="a harness checkpoint folder")
    parser.add_argument("--map", default="open")
    parser.add_argument("--agents", type=int, default=4)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--probe", help="the harness's --probe file for the same episode")
    args = parser.parse_args()

    model, config = load_checkpoint(args.checkpoint)
    env = vpm_world.ParallelEnv(args.map, args.agents, steps=args.steps,
                                mark_others_on_mini=config["mark_others_on_mini"])
    graph = edges(args.agents, config["neighbours"])
    probes = read_probe(args.probe) if args.probe else {}
    observations, _ = env.reset(seed=args.seed)
    worst, penalty, t = 0.0, 0.0, 0
    while env.agents:
        stacked = np.stack([observations[a] for a in env.possible_agents])
        with torch.no_grad():
            x = torch.from_numpy(stacked).double()
            probabilities = model.action_layer(x, graph).numpy()
            values = model.value_layer(x).squeeze(1).numpy()
        actions = probabilities.argmax(axis=1)
        for agent, row in probes.get(t, {}).items():
            worst = max(worst, check(t, agent, row, stacked[agent], probabilities[agent],
                                     values[agent], actions[agent], env.positions()[agent]))
        observations, rewards, *_ = env.step(dict(zip(env.possible_agents, actions.tolist())))
        penalty -= next(iter(rewards.values()))
        t += 1
    print(f"cumulative penalty: {penalty / 1e6:.6f} x 10^6 ({t} steps, {args.agents} agents, "
          f"greedy, seed {args.seed})")
    if probes:
        rows = sum(len(r) for r in probes.values())
        print(f"probed rows: {rows}, largest probability difference: {worst:.2e}")


def read_probe(path):
    """The probe's rows by step and agent."""
    import pyarrow.parquet as pq

    rows = {}
    for row in pq.read_table(path).to_pylist():
        rows.setdefault(row["step"], {})[row["agent"]] = row
    return rows


def check(t, agent, row, observation, probabilities, value, action, position):
    """The largest probability difference of one probed row; exits on any mismatch."""
    where = f"step {t}, agent {agent}"
    if (row["x"], row["y"]) != tuple(position) or row["action"] != action:
        sys.exit(f"{where}: the harness was at ({row['x']}, {row['y']}) taking {row['action']}, "
                 f"here at {tuple(position)} taking {action}")
    if not np.array_equal(np.asarray(row["observation"], dtype=np.float32), observation.ravel()):
        sys.exit(f"{where}: the observations differ")
    difference = float(np.abs(np.asarray(row["probabilities"]) - probabilities).max())
    if difference > TOLERANCE or abs(row["value"] - value) > TOLERANCE * max(1.0, abs(value)):
        sys.exit(f"{where}: probabilities differ by {difference:.2e} (value {row['value']} "
                 f"against {value})")
    return difference


if __name__ == "__main__":
    main()
