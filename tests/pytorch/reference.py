"""The paper's network in PyTorch, run on the weights of our checkpoints.

It builds the actor-critic of the authors' released code (amrish1222/rl_multi_agent: the CNN
`embeding_layer.layer1`, the graph attention `GAT.conv1` with `fc`, `attn_l` and `attn_r`, the
actor MLP `reg1`, the critic's CNN `feature2` and MLP `reg2`), loads one of our
`checkpoint.safetensors` into it by renaming tensors only (no reordering: our checkpoints are
stored in PyTorch's layout), and prints its action probabilities and values on a fixed
observation, computed in float64. `policies/tests/pytorch_reference.rs` checks our network
against these numbers.

The graph attention follows DGL's GATConv (which the released code copies): for an edge from
sender j to receiver i and head m, e = LeakyReLU_0.2(attn_l . W h_j + attn_r . W h_i),
softmax over the edges into i, messages averaged over heads. Here every agent hears every
other agent (our default and the paper's text; the released code also adds self-loops).

Made with torch 2.15.0 (CPU) and safetensors from PyPI:

    VPM_REFERENCE_DIR=/tmp/vpm-reference cargo test -p policies --test pytorch_reference \
        -- --ignored --exact write_reference_checkpoints
    python3 tests/pytorch/reference.py /tmp/vpm-reference > policies/tests/pytorch_reference.json
"""

import json
import sys
from pathlib import Path

import torch
from safetensors.torch import load_file
from torch import nn

AGENTS = 4
CHANNELS = 2
SIDE = 25
HEADS = 3
FEATURES = 2 * 2 * 32


def fixed_observation():
    """[agents, channels, side, side]; the same formula as the Rust test."""
    obs = torch.empty(AGENTS, CHANNELS, SIDE, SIDE, dtype=torch.float64)
    for a in range(AGENTS):
        for c in range(CHANNELS):
            for y in range(SIDE):
                for x in range(SIDE):
                    obs[a, c, y, x] = ((a * 37 + c * 11 + y * 5 + x * 3) % 17) / 8.0 - 1.0
    return obs


def cnn():
    return nn.Sequential(
        nn.Conv2d(CHANNELS, 16, (8, 8), 4, 1),
        nn.ReLU(),
        nn.Conv2d(16, 32, (4, 4), 2, 1),
        nn.ReLU(),
        nn.Conv2d(32, 32, (3, 3), 1, 1),
        nn.ReLU(),
        nn.Flatten(),
    )


def mlp(inputs, outputs):
    return nn.Sequential(
        nn.Linear(inputs, 500), nn.ReLU(), nn.Linear(500, 256), nn.ReLU(), nn.Linear(256, outputs)
    )


class EmbeddingLayer(nn.Module):
    def __init__(self):
        super().__init__()
        self.layer1 = cnn()


class GATConv(nn.Module):
    def __init__(self, features, heads):
        super().__init__()
        self.heads, self.features = heads, features
        self.fc = nn.Linear(features, heads * features, bias=False)
        self.attn_l = nn.Parameter(torch.zeros(1, heads, features))
        self.attn_r = nn.Parameter(torch.zeros(1, heads, features))

    def forward(self, h, edges):
        """h [N, in]; edges [(sender, receiver)]; returns [N, heads, features]."""
        ft = self.fc(h).view(-1, self.heads, self.features)
        el = (ft * self.attn_l).sum(-1)
        er = (ft * self.attn_r).sum(-1)
        out = torch.zeros_like(ft)
        for i in range(h.shape[0]):
            senders = [j for (j, r) in edges if r == i]
            e = nn.functional.leaky_relu(el[senders] + er[i], 0.2)
            alpha = torch.softmax(e, dim=0)
            out[i] = (alpha.unsqueeze(-1) * ft[senders]).sum(0)
        return out


class GAT(nn.Module):
    def __init__(self):
        super().__init__()
        self.conv1 = GATConv(FEATURES, HEADS)


class PaperActorCritic(nn.Module):
    def __init__(self, attention):
        super().__init__()
        self.embeding_layer = EmbeddingLayer()
        self.GAT = GAT() if attention else None
        self.reg1 = nn.Sequential(*mlp(2 * FEATURES if attention else FEATURES, 5), nn.Softmax(-1))
        self.feature2 = cnn()
        self.reg2 = mlp(FEATURES, 1)

    def action_layer(self, x, edges):
        h = self.embeding_layer.layer1(x)
        if self.GAT is not None:
            h = torch.cat((h, self.GAT.conv1(h, edges).mean(1)), 1)
        return self.reg1(h)

    def value_layer(self, x):
        return self.reg2(self.feature2(x))


def released_names(ours):
    """Our tensor names -> the released code's state-dict names (the attention vector apart)."""
    sequential = {"0": "0", "1": "2", "2": "4"}
    renamed = {}
    for name, tensor in ours.items():
        part, block, *rest = name.split(".")
        if block == "attention":
            continue
        module = {
            ("actor", "cnn"): "embeding_layer.layer1",
            ("actor", "mlp"): "reg1",
            ("critic", "cnn"): "feature2",
            ("critic", "mlp"): "reg2",
        }[(part, block)]
        renamed[f"{module}.{sequential[rest[0]]}.{rest[1]}"] = tensor
    return renamed


def load(folder, attention):
    ours = load_file(str(folder / "checkpoint.safetensors"))
    state = released_names(ours)
    if attention:
        state["GAT.conv1.fc.weight"] = ours["actor.attention.weight"]
        # Ours is [heads, 2 * features]: the receiver's half, then the sender's.
        vector = ours["actor.attention.attention"]
        state["GAT.conv1.attn_r"] = vector[:, :FEATURES].unsqueeze(0)
        state["GAT.conv1.attn_l"] = vector[:, FEATURES:].unsqueeze(0)
    model = PaperActorCritic(attention).double()
    model.load_state_dict({k: v.double() for k, v in state.items()}, strict=True)
    return model


def main(root):
    edges = [(j, i) for i in range(AGENTS) for j in range(AGENTS) if i != j]
    obs = fixed_observation()
    result = {"torch": torch.__version__}
    for architecture, attention in [("ma_g_ppo", True), ("ma_ppo", False)]:
        folder = root / architecture
        model = load(folder, attention)
        with torch.no_grad():
            probabilities = model.action_layer(obs, edges)
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
