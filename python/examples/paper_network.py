"""The paper's network in PyTorch, as the authors' released code builds it, and the loading of
a harness checkpoint into it by renaming tensors only (docs/pytorch.md has the table).

The released code (amrish1222/rl_multi_agent): the CNN `embeding_layer.layer1`, the graph
attention `GAT.conv1` with `fc`, `attn_l` and `attn_r`, the actor MLP `reg1`, the critic's CNN
`feature2` and MLP `reg2`. Our checkpoints are stored in PyTorch's layout, so nothing is
reordered. The graph attention follows DGL's GATConv (which the released code copies): for an
edge from sender j to receiver i and head m, e = LeakyReLU_0.2(attn_l . W h_j + attn_r . W h_i),
softmax over the edges into i, messages averaged over heads.

Used by `play_checkpoint.py` beside it and by `tests/pytorch/reference.py`.
"""

import json
from pathlib import Path

import torch
from safetensors.torch import load_file
from torch import nn

CHANNELS = 2
SIDE = 25
HEADS = 3
FEATURES = 2 * 2 * 32


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
    """The network of the checkpoint in `folder`, in float64."""
    ours = load_file(str(Path(folder) / "checkpoint.safetensors"))
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


def load_checkpoint(folder):
    """The network of a harness checkpoint folder and the configuration it was trained with;
    refuses what this module does not build (other networks, attention within a radius)."""
    config = json.loads((Path(folder) / "checkpoint.json").read_text())["config"]
    wanted = {"network": "paper", "heads": HEADS, "channels": "both"}
    for key, value in wanted.items():
        if config.get(key) != value:
            raise ValueError(f"{folder}: {key} is {config.get(key)!r}; this example builds {value!r}")
    architecture = config["architecture"]
    if architecture not in ("ma_g_ppo", "ma_ppo"):
        raise ValueError(f"{folder}: architecture {architecture!r} is not ma_g_ppo or ma_ppo")
    if config["neighbours"] not in ("all_others", "all_agents"):
        raise ValueError(f"{folder}: neighbours {config['neighbours']!r}: this example builds "
                         "all_others and all_agents")
    return load(folder, architecture == "ma_g_ppo"), config


def edges(agents, neighbours="all_others"):
    """Who hears whom, as (sender, receiver): every other agent, and with `all_agents` (the
    released code's self-loops) each agent itself too."""
    return [(j, i) for i in range(agents) for j in range(agents)
            if i != j or neighbours == "all_agents"]
