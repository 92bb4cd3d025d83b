"""The paper's network in PyTorch, run on the weights of our checkpoints.

It loads one of our `checkpoint.safetensors` into the actor-critic of the authors' released
code (`python/examples/paper_network.py`: renaming tensors only, no reordering) and prints its
action probabilities and values on a fixed observation, computed in float64.
`policies/tests/pytorch_reference.rs` checks our network against these numbers. Here every
agent hears every other agent (our default and the paper's text; the released code also adds
self-loops).

Made with torch 2.15.0 (CPU) and safetensors from PyPI:

    VPM_REFERENCE_DIR=/tmp/vpm-reference cargo test -p policies --test pytorch_reference \
        -- --ignored --exact write_reference_checkpoints
    python3 tests/pytorch/reference.py /tmp/vpm-reference > policies/tests/pytorch_reference.json
"""

import json
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "python" / "examples"))
from paper_network import CHANNELS, SIDE, edges, load  # noqa: E402

AGENTS = 4


def fixed_observation():
    """[agents, channels, side, side]; the same formula as the Rust test."""
    obs = torch.empty(AGENTS, CHANNELS, SIDE, SIDE, dtype=torch.float64)
    for a in range(AGENTS):
        for c in range(CHANNELS):
            for y in range(SIDE):
                for x in range(SIDE):
                    obs[a, c, y, x] = ((a * 37 + c * 11 + y * 5 + x * 3) % 17) / 8.0 - 1.0
    return obs


def main(root):
    graph = edges(AGENTS)
    obs = fixed_observation()
    result = {"torch": torch.__version__}
    for architecture, attention in [("ma_g_ppo", True), ("ma_ppo", False)]:
        folder = root / architecture
        model = load(folder, attention)
        with torch.no_grad():
            probabilities = model.action_layer(obs, graph)
            values = model.value_layer(obs).squeeze(1)
        result[architecture] = {
            "weights_blake3": (folder / "weights.blake3").read_text().strip(),
            "probabilities": probabilities.tolist(),
            "values": values.tolist(),
        }
    json.dump(result, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main(Path(sys.argv[1]))
