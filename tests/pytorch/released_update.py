"""Does our PPO update equal the authors' released one?  `python released_update.py DIR`

DIR is a trace of one update written by `harness train ... --trace-update DIR` (trace.json,
before.safetensors, rollout.safetensors, ours.safetensors). The released code is
amrish1222/rl_multi_agent, branch `diff_agents_training` (commit e87235316b01), `source/`:

1. Observations. From each step's penalty map and the agents' cells this rebuilds what the
   released env feeds the network and requires ours to equal it exactly: `env.py` step()
   line 186 marks every agent 100 on `current_map_state` (indexed [x][y], obstacles 150);
   get_local_heatmap_list (346-367) cuts the 25 x 25 view around each agent from
   `current_map.T`, 150 beyond the map, and returns its `.T`, so [x][y] again with the agent
   at [12][12]; get_mini_map (369-395) takes obstacle blocks from an area resize of the static
   obstacle map (`> 0`: any obstacle cell of the 2 x 2 block, 150), the penalty as the block
   minimum of the negative cells (which wins over an obstacle in the same block), and marks
   only the agent's own block, 200; `ppo_agent.py` formatInput (345-350) stacks
   [local, mini]; act() (193) casts to float32. Ours is [y][x] (row 0 = lowest y), so each
   released image is transposed before the exact comparison.
2. The update. `ppo_agent.py` ActorCritic.action_layer (148-181): the embedding CNN, the GAT of
   `embedding_graph.py` (GAT 83-120: DGL's GATConv of `GAT_MOD.py` 105-171 with 3 heads,
   messages and attention averaged over heads by ave_heads 46-53) on a batch of FC_graph
   (132-140: every sender 0..n-1 into each receiver i, self-loops included, edges grouped by
   receiver), then reg1 on [h_i, h_i']; evaluate (222-238): attention entropy of
   `attention_mat.view(-1, n)`, the head-averaged weights of each receiver's incoming edges;
   PPO.update (276-341): Monte-Carlo returns per agent backwards with the last step terminal,
   normalised with torch's unbiased std + 1e-5, K epochs on one minibatch, the loss of line
   332, `- c_e H + c_a H_att` (the released c_e = c_a = 0.01), Adam (254). Here the graph
   attention is written with index operations instead of DGL (same edges, same order, the
   softmax over each receiver's incoming edges), and `torch.diag(dist.log_prob(action[B, 1]))`
   (231) is taken as the equal `dist.log_prob(action[B])`; the released minibatch is
   n x LEN_EPISODE (1000) samples, so a shorter rollout would not be learned from at all, and
   here the one minibatch is all S x n samples. lr, betas, eps, gamma, clip, K,
   c_e and c_a come from the trace's config; the config's switches that the released update
   cannot express (no self-loops, other advantages, clipping, ...) are checks of their own.
   The states are the trace's observations (step 1 checks them); the released code stores
   them as float32 and, its rewards being numpy float64, computes returns, advantages and the
   loss in float64 (type promotion).
3. Comparison, against the port run in float64 (weights and observations cast from float32):
   ours' returns, old log-probs (against the port's epoch-0 log-probs: the rollout's policy is
   the weights before the update), loss terms on epoch 0 (`value` is the unhalved MSE), each
   gradient on epoch 0 and each weight change (after - before) after all epochs.

Tolerances. A measure is per tensor and relative: max |ours - ref| / max |ref| (a scalar:
|ours - ref| / |ref|). The same port also runs wholly in float32 (returns included: the
precision our side works in); its own distance from float64, measured the same way, is the
float32 rounding of that quantity, and tolerance = max(10 x that rounding, floor). The
floor, 10 sqrt(B) u with u = 2^-24 and B samples, is ten times the random-walk rounding of a
float32 sum over the batch in another order: it keeps a quantity that the float32 run
happens to round well from asking more of ours than float32 gives. Observations and config
switches must be equal.

Kinks. A ReLU (or GATConv's LeakyReLU) input z within rounding of 0 takes its derivative
from the side rounding puts it on, so a float32 gradient can differ from float64's by one
unit's whole contribution, up to ~1/sqrt(B) of a tensor's largest element: not rounding (on
1000 x 4 samples, one or two such flips per float32 run). So each run's epoch-0 gradient
difference is first explained by flips: every unit with |z| <= 10 x its layer's largest
float32 rounding of z is a candidate, its jump (d' - d) dL/da dz/dtheta taken on its step's
graph; greedily, a jump that moves some tensor by more than the floor and lies at least 3/4
inside what is left of the difference (<r, j> >= 3/4 <j, j>, each tensor weighted by
1 / max |ref|^2) counts as flipped and is added to the reference, for ours and for the
float32 run apart. The flips taken are printed and written out.

Weight changes. Three more things make a max over the final weights meaningless: Adam's
first step is lr g / (|g| + eps), about lr sign(g), so an element whose gradient is within
rounding of 0 can move by up to 2 lr per step differently; such steps move more inputs
across kinks in later epochs (on 200 x 4 samples the float32 run's epoch-2 gradients differ
from float64's by ~1e-3 of their largest element), and with them a few percent of the
changes; and the weights are float32, each of the K steps rounding them by up to half an ulp
(about 1e-3 of a change of lr at |w| ~ 0.05). So each element's excess,
max(0, |ours - ref| - K/2 ulp(|w|)) / max |ref|, is measured, and:
- `change.NAME` takes its median over the well-determined elements: at every epoch of the
  float64 run |g| >= 100 x the epoch-0 gradient tolerance (in absolute terms), so that
  Adam's step there is known to about 1 % of lr or better; tolerance max(10 x the float32
  run's median, floor). A fault of the update rule (lr, betas, eps, bias correction, an
  epoch too few, a tensor not stepped) moves every element and shows in the median; kinks
  move a minority, which the median ignores up to half (the note gives the share beyond the
  tolerance, ours and the float32 run's).
- `change.NAME.bound` requires every element's excess to be within what Adam can do in K
  steps on either side: 2 lr sum_t c_t, where c_t = sqrt(sum_k w_k^2 / v_k) bounds
  |m_hat / sqrt(v_hat)| at step t (Cauchy-Schwarz over the bias-corrected moment weights w
  of beta1 and v of beta2; c_1 = 1).

Prints a table (check, error, float32 rounding, tolerance, result, note) and
`released update: N checks, N passed, N failed` (then `FAILED: ...`), writes the same to
DIR/comparison.json; exits 0 when all pass, 1 when any fails, 2 on input it cannot judge.
Needs torch, numpy and safetensors only.
"""

import json
import math
import sys
from pathlib import Path

import numpy as np
import torch
from safetensors.torch import load_file
from torch import nn
from torch.distributions import Categorical

HEADS = 3
FEATURES = 2 * 2 * 32
ACTIONS = 5
OBSTACLE = 150.0
AGENT = 100.0
OWN_BLOCK = 200.0
MINI_RATIO = 0.5
TIMES = 10.0
DETERMINED = 100.0
U32 = 2.0**-24
SEQUENTIAL = {"0": "0", "1": "2", "2": "4"}
MODULES = {
    "actor.cnn": "embeding_layer.layer1",
    "actor.mlp": "reg1",
    "critic.cnn": "feature2",
    "critic.mlp": "reg2",
}
ATTENTION_FC = ("actor.attention.weight", "GAT.conv1.fc.weight")
ATTENTION_VECTOR = "actor.attention.attention"
CONFIG_KEYS = ("learning_rate", "adam_beta1", "adam_beta2", "adam_epsilon", "gamma", "epochs",
               "clip", "entropy_coefficient", "attention_entropy_coefficient")
TERMS = ("policy", "value", "entropy", "attention_entropy", "total")
# Config switches the released update has one value of (the default when absent).
RELEASED_CONFIG = {
    "architecture": ("ma_g_ppo", None),
    "network": ("paper", None),
    "heads": (HEADS, None),
    "neighbours": ("all_agents", None),
    "attention_entropy_term": ("penalty", "bonus"),
    "attention_entropy_of": ("head_mean", "each_head"),
    "environments": (1, None),
    "minibatches": (1, None),
    "advantage": ("monte_carlo", None),
    "normalise_returns": (True, None),
    "normalise_advantages": (False, None),
    "value_coefficient": (0.5, None),
    "max_grad_norm": (None, None),
    "anneal_learning_rate": (False, None),
    "learning_rate_half_life": (None, None),
    "value_normalisation": (None, None),
}


class BadInput(Exception):
    pass


# ---------------------------------------------------------------- the trace


def our_names():
    names = [f"{m}.{k}.{w}" for m in MODULES for k in SEQUENTIAL for w in ("weight", "bias")]
    return sorted(names + [ATTENTION_FC[0], ATTENTION_VECTOR])


def load_tensors(path):
    if not path.is_file():
        raise BadInput(f"{path}: missing")
    return load_file(str(path))


def read_trace(folder):
    try:
        meta = json.loads((folder / "trace.json").read_text())
    except (OSError, ValueError) as error:
        raise BadInput(f"{folder / 'trace.json'}: {error}") from error
    if meta.get("format") != 1:
        raise BadInput(f"trace.json: format {meta.get('format')!r}, this reads 1")
    trace = {"meta": meta, "config": meta["config"], "terms": meta["terms"]}
    absent = [k for k in CONFIG_KEYS if k not in meta["config"]]
    absent += [f"terms.{k}" for k in TERMS if k not in meta["terms"]]
    if absent:
        raise BadInput(f"trace.json: missing {absent}")
    trace["before"] = load_tensors(folder / "before.safetensors")
    trace["rollout"] = load_tensors(folder / "rollout.safetensors")
    ours = load_tensors(folder / "ours.safetensors")
    names = our_names()
    found = sorted(trace["before"])
    if found != names:
        raise BadInput(f"before.safetensors: missing {sorted(set(names) - set(found))}, "
                       f"unknown {sorted(set(found) - set(names))}")
    wanted = ["returns"] + [f"{p}.{n}" for p in ("grad", "after") for n in names]
    missing = [k for k in wanted if k not in ours]
    if missing:
        raise BadInput(f"ours.safetensors: missing {missing}")
    trace["ours"] = ours
    check_shapes(trace)
    return trace


def check_shapes(trace):
    m, r = trace["meta"], trace["rollout"]
    steps, agents, side, fov = m["steps"], m["agents"], m["side"], m["fov"]
    width, height = m["map_width"], m["map_height"]
    if width != height or int(width * MINI_RATIO) != side or fov != side or m["channels"] != 2:
        raise BadInput(f"map {width} x {height}, side {side}, fov {fov}, channels "
                       f"{m['channels']}: the released env is square, its mini-map "
                       f"{MINI_RATIO} of the map, stacked on a local view of the same side")
    shapes = {
        "observations": (steps * agents, 2, side, side),
        "actions": (steps * agents,),
        "old_log_probs": (steps * agents,),
        "rewards": (steps,),
        "penalty": (steps, height, width),
        "positions": (steps, agents, 2),
    }
    for name, shape in shapes.items():
        if name not in r or tuple(r[name].shape) != shape:
            got = tuple(r[name].shape) if name in r else "missing"
            raise BadInput(f"rollout.safetensors: {name} {got}, expected {shape}")
    if tuple(trace["ours"]["returns"].shape) != (steps * agents,):
        raise BadInput(f"ours.safetensors: returns {tuple(trace['ours']['returns'].shape)}")
    positions = r["positions"]
    if positions.numel() and (positions.min() < 0 or positions.max() >= width):
        raise BadInput(f"rollout.safetensors: positions outside the {width} x {height} map")


# ---------------------------------------------------------- 1. observations


def local_heatmap(current, g, size):
    """env.py get_local_heatmap_list for one agent at cell g = (x, y): [x][y]."""
    r = (size - 1) // 2
    map_size = current.shape[0]
    lx, hx = max(0, g[1] - r), min(map_size, r + g[1] + 1)
    ly, hy = max(0, g[0] - r), min(map_size, r + g[0] + 1)
    view = np.ones((size, size)) * OBSTACLE
    view[lx - (g[1] - r): hx - g[1] + r, ly - (g[0] - r): hy - g[0] + r] = \
        current.T[lx:hx, ly:hy]
    return view.T


def mini_maps(current, obstacle_map, cells):
    """env.py get_mini_map with ratio 0.5: [x][y], one per agent."""
    windows = int(current.shape[0] * MINI_RATIO)
    w = int(1 / MINI_RATIO)
    # cv2.resize INTER_AREA by an integer factor is the block mean.
    area = obstacle_map.reshape(windows, w, windows, w).mean(axis=(1, 3))
    mini_obs = np.where(area > 0, OBSTACLE, 0)
    decay = np.where(current < 0, current, 0)
    mini_decay = decay.reshape(windows, w, windows, w).min(axis=(1, 3))
    mini = np.where(mini_decay < 0, mini_decay, mini_obs)
    out = []
    for g in cells:
        own = np.copy(mini)
        own[int(g[0] * MINI_RATIO), int(g[1] * MINI_RATIO)] = OWN_BLOCK
        out.append(own)
    return out


def released_step_state(penalty_yx, cells, size):
    """One step's [agents, 2, size, size] as formatInput stacks it, in [x][y], float32."""
    obstacle_map = np.where(penalty_yx.T == OBSTACLE, OBSTACLE, 0.0)
    current = np.array(penalty_yx.T, dtype=np.float64)
    for x, y in cells:
        current[x, y] = AGENT
    locals_ = [local_heatmap(current, g, size) for g in cells]
    minis = mini_maps(current, obstacle_map, cells)
    return np.array([[lv, mm] for lv, mm in zip(locals_, minis)]).astype(np.float32)


def released_observations(rollout, size):
    """All steps, transposed to our [y][x]: [steps * agents, 2, size, size]."""
    penalty = rollout["penalty"].double().numpy()
    positions = rollout["positions"].numpy()
    states = [released_step_state(penalty[s], [tuple(map(int, c)) for c in positions[s]], size)
              for s in range(penalty.shape[0])]
    return np.concatenate(states).transpose(0, 1, 3, 2)


def observation_check(trace):
    ours = trace["rollout"]["observations"].numpy()
    released = released_observations(trace["rollout"], trace["meta"]["fov"])
    differ = ours != released
    count = int(differ.sum())
    note = f"{ours.size} values equal"
    if count:
        i, c, y, x = (int(v) for v in np.argwhere(differ)[0])
        agents = trace["meta"]["agents"]
        note = (f"{count} values differ; first step {i // agents} agent {i % agents} "
                f"channel {c} row {y} col {x}: ours {ours[i, c, y, x]}, released "
                f"{released[i, c, y, x]}")
    return row("observations", float(np.abs(ours - released).max()), None, 0.0, note)


# ---------------------------------------------------------- 2. the released network


def cnn():
    return nn.Sequential(
        nn.Conv2d(2, 16, (8, 8), 4, 1), nn.ReLU(),
        nn.Conv2d(16, 32, (4, 4), 2, 1), nn.ReLU(),
        nn.Conv2d(32, 32, (3, 3), 1, 1), nn.ReLU(),
        nn.Flatten(),
    )


def mlp(inputs, outputs):
    return nn.Sequential(
        nn.Linear(inputs, 500), nn.ReLU(), nn.Linear(500, 256), nn.ReLU(), nn.Linear(256, outputs)
    )


def fc_graph(n):
    """embedding_graph.py FC_graph: for each receiver i, edges from senders 0..n-1."""
    src = [j for _ in range(n) for j in range(n)]
    dst = [i for i in range(n) for _ in range(n)]
    return src, dst


def batched(graph, n, copies):
    """dgl.batch([graph] * copies): node ids offset by n per copy, edges copy by copy."""
    src, dst = (torch.tensor(e) for e in graph)
    offset = (torch.arange(copies) * n).repeat_interleave(len(src))
    return src.repeat(copies) + offset, dst.repeat(copies) + offset


def edge_softmax(e, dst, nodes):
    """DGL's edge_softmax: over each receiver's incoming edges, per head. e [E, H, 1]."""
    index = dst.view(-1, 1, 1).expand_as(e)
    top = torch.full((nodes,) + e.shape[1:], -math.inf, dtype=e.dtype)
    top = top.scatter_reduce(0, index, e.detach(), "amax")
    ex = torch.exp(e - top[dst])
    total = torch.zeros_like(top).index_add(0, dst, ex)
    return ex / total[dst]


def ave_heads(h, heads):
    """embedding_graph.py ave_heads, in its order of additions."""
    res = 0.0
    for i in range(heads):
        res = res + h[:, i, :]
    return res / float(heads)


class GATConv(nn.Module):
    """GAT_MOD.py GATConv as used: no bias, dropout, residual or activation."""

    def __init__(self, features, heads):
        super().__init__()
        self._num_heads, self._out_feats = heads, features
        self.fc = nn.Linear(features, features * heads, bias=False)
        self.attn_l = nn.Parameter(torch.zeros(1, heads, features))
        self.attn_r = nn.Parameter(torch.zeros(1, heads, features))
        self.leaky_relu = nn.LeakyReLU(0.2)

    def forward(self, feat, src, dst):
        ft = self.fc(feat).view(-1, self._num_heads, self._out_feats)
        el = (ft * self.attn_l).sum(dim=-1).unsqueeze(-1)
        er = (ft * self.attn_r).sum(dim=-1).unsqueeze(-1)
        e = self.leaky_relu(el[src] + er[dst])
        a = edge_softmax(e, dst, feat.shape[0])
        rst = torch.zeros_like(ft).index_add(0, dst, ft[src] * a)
        return rst, a


class GAT(nn.Module):
    def __init__(self):
        super().__init__()
        self.heads = HEADS
        self.conv1 = GATConv(FEATURES, HEADS)

    def forward(self, inputs, src, dst):
        l1, attention = self.conv1(inputs, src, dst)
        return ave_heads(l1, self.heads), ave_heads(attention, self.heads)


class EmbeddingLayer(nn.Module):
    def __init__(self):
        super().__init__()
        self.layer1 = cnn()


class ActorCritic(nn.Module):
    """ppo_agent.py ActorCritic on a batch of copies of `graph` (FC_graph's order)."""

    def __init__(self, agents, graph):
        super().__init__()
        self.agents, self.graph = agents, graph
        self.embeding_layer = EmbeddingLayer()
        self.GAT = GAT()
        self.reg1 = nn.Sequential(*mlp(2 * FEATURES, ACTIONS), nn.Softmax(dim=-1))
        self.feature2 = cnn()
        self.reg2 = mlp(FEATURES, 1)

    def action_layer(self, x1):
        x = self.embeding_layer.layer1(x1)
        src, dst = batched(self.graph, self.agents, x.shape[0] // self.agents)
        h, self.attention_mat = self.GAT(x, src, dst)
        return self.reg1(torch.cat((x, h), 1))

    def value_layer(self, x1):
        return self.reg2(self.feature2(x1))

    def evaluate(self, state, action):
        dist = Categorical(self.action_layer(state))
        # view(-1, n): a row per receiver, its incoming edges (n of them with self-loops).
        att_entropy = Categorical(self.attention_mat.view(state.shape[0], -1)).entropy()
        return (dist.log_prob(action), torch.squeeze(self.value_layer(state)),
                dist.entropy(), att_entropy)


def released_state_dict(ours):
    """Our tensor names -> the released state dict (docs/pytorch.md)."""
    state = {}
    for name, tensor in ours.items():
        if name == ATTENTION_VECTOR:
            state["GAT.conv1.attn_r"] = tensor[:, :FEATURES].unsqueeze(0)
            state["GAT.conv1.attn_l"] = tensor[:, FEATURES:].unsqueeze(0)
        elif name == ATTENTION_FC[0]:
            state[ATTENTION_FC[1]] = tensor
        else:
            module, k, kind = name.rsplit(".", 2)
            state[f"{MODULES[module]}.{SEQUENTIAL[k]}.{kind}"] = tensor
    return state


def in_our_names(released):
    """The released state dict (or its gradients) -> our names and layout."""
    ours = {}
    for name in our_names():
        if name == ATTENTION_VECTOR:
            ours[name] = torch.cat((released["GAT.conv1.attn_r"][0],
                                    released["GAT.conv1.attn_l"][0]), 1)
        elif name == ATTENTION_FC[0]:
            ours[name] = released[ATTENTION_FC[1]]
        else:
            module, k, kind = name.rsplit(".", 2)
            ours[name] = released[f"{MODULES[module]}.{SEQUENTIAL[k]}.{kind}"]
    return ours


def build_model(before, agents, dtype):
    model = ActorCritic(agents, fc_graph(agents)).to(dtype)
    try:
        model.load_state_dict({k: v.to(dtype) for k, v in released_state_dict(before).items()})
    except RuntimeError as error:
        raise BadInput(f"before.safetensors: {error}") from error
    return model


# ---------------------------------------------------------------- PPO.update


def monte_carlo(rewards, agents, gamma):
    """PPO.update's returns: each agent backwards, the last step terminal, normalised."""
    running = torch.zeros(agents, dtype=rewards.dtype)
    returns = []
    for s in reversed(range(rewards.shape[0])):
        if s == rewards.shape[0] - 1:  # is_terminal
            running = torch.zeros_like(running)
        running = rewards[s] + gamma * running
        returns.insert(0, running)
    returns = torch.stack(returns).reshape(-1)
    return (returns - returns.mean()) / (returns.std() + 1e-5)


def loss_terms(model, states, actions, old_logprobs, returns, c):
    logprobs, values, dist_entropy, att_entropy = model.evaluate(states, actions)
    ratios = torch.exp(logprobs.view(-1, 1) - old_logprobs.view(-1, 1).detach())
    advantages = (returns - values.detach()).view(-1, 1)
    surr1 = ratios * advantages
    surr2 = torch.clamp(ratios, 1 - c["clip"], 1 + c["clip"]) * advantages
    terms = {
        "policy": -torch.min(surr1, surr2).mean(),
        "value": nn.functional.mse_loss(values, returns),
        "entropy": dist_entropy.mean(),
        "attention_entropy": att_entropy.mean(),
    }
    terms["total"] = (terms["policy"] + 0.5 * terms["value"]
                      - c["entropy_coefficient"] * terms["entropy"]
                      + c["attention_entropy_coefficient"] * terms["attention_entropy"])
    return terms, logprobs


def released_update(trace, dtype):
    """PPO.update on the trace in `dtype`: what epoch 0 saw and the weights after."""
    m, c, r = trace["meta"], trace["config"], trace["rollout"]
    agents = m["agents"]
    model = build_model(trace["before"], agents, dtype)
    states = r["observations"].to(dtype)
    returns = monte_carlo(r["rewards"].to(dtype), agents, c["gamma"])
    optimizer = torch.optim.Adam(model.parameters(), lr=c["learning_rate"],
                                 betas=(c["adam_beta1"], c["adam_beta2"]), eps=c["adam_epsilon"])
    record = {"returns": returns, "grads": []}
    for epoch in range(c["epochs"]):
        kinks, handles = watch_kinks(model) if epoch == 0 else ({}, [])
        terms, logprobs = loss_terms(model, states, r["actions"].long(),
                                     r["old_log_probs"].to(dtype), returns, c)
        optimizer.zero_grad()
        terms["total"].backward()
        for handle in handles:
            handle.remove()
        grads = in_our_names({k: p.grad.detach().clone() for k, p in model.named_parameters()})
        record["grads"].append(grads)
        if epoch == 0:
            record["terms"] = {k: v.item() for k, v in terms.items()}
            record["logprobs"] = logprobs.detach()
            record["kinks"] = kinks
        optimizer.step()
    record["after"] = in_our_names({k: p.detach().clone() for k, p in model.named_parameters()})
    return record


def kink_modules(model):
    return [(name, module) for name, module in model.named_modules()
            if isinstance(module, (nn.ReLU, nn.LeakyReLU))]


def watch_kinks(model):
    """Hooks that record, on the next forward and backward, each (leaky) ReLU's input z and
    the gradient of the loss at its output."""
    seen, handles = {}, []
    for name, module in kink_modules(model):
        seen[name] = {}
        handles.append(module.register_forward_hook(
            lambda _m, i, _o, at=seen[name]: at.update(z=i[0].detach())))
        handles.append(module.register_full_backward_hook(
            lambda _m, _gi, go, at=seen[name]: at.update(g=go[0].detach())))
    return seen, handles


def kink_jumps(trace, r64, r32):
    """Each (leaky) ReLU unit whose epoch-0 input z lies within 10 x its layer's float32
    rounding of 0, as (label, jump): what flipping its derivative (1 <-> slope) changes the
    epoch-0 gradient by, (d' - d) dL/da dz/dtheta, taken on its step's graph; our names."""
    agents, steps = trace["meta"]["agents"], trace["meta"]["steps"]
    model = build_model(trace["before"], agents, torch.float64)
    params = dict(model.named_parameters())
    states = trace["rollout"]["observations"].double()
    for name, module in kink_modules(model):
        z, g = r64["kinks"][name]["z"], r64["kinks"][name]["g"]
        rounding = (r32["kinks"][name]["z"].double() - z).abs().max().item()
        near = (z.abs() <= TIMES * rounding).nonzero()
        slope = getattr(module, "negative_slope", 0.0)
        rows = z.shape[0] // steps
        for step in (near[:, 0] // rows).unique().tolist():
            z_step = step_input(model, module, states[step * agents:(step + 1) * agents])
            for unit in near[near[:, 0] // rows == step].tolist():
                local = (unit[0] - step * rows,) + tuple(unit[1:])
                grads = torch.autograd.grad(z_step[local], list(params.values()),
                                            retain_graph=True, allow_unused=True)
                flip = (slope - 1 if z[tuple(unit)] > 0 else 1 - slope) * g[tuple(unit)]
                jump = {k: flip * (d if d is not None else torch.zeros_like(p))
                        for (k, p), d in zip(params.items(), grads)}
                yield f"{name}[step {step}, {tuple(local)}]", in_our_names(jump)


def step_input(model, module, states):
    """The input of `module` when the actor and the critic see one step's agents."""
    seen = {}
    handle = module.register_forward_hook(lambda _m, i, _o: seen.update(z=i[0]))
    model.action_layer(states)
    model.value_layer(states)
    handle.remove()
    return seen["z"]


# ------------------------------------------------------------- 3. comparison


def distance(a, ref):
    """max |a - ref| / max |ref|, in float64; a reference all 0 leaves it absolute."""
    a, ref = torch.as_tensor(a, dtype=torch.float64), torch.as_tensor(ref, dtype=torch.float64)
    scale = ref.abs().max().item() or 1.0
    return (a - ref).abs().max().item() / scale


def row(name, error, f32, tolerance, note=""):
    passed = bool(error <= tolerance)  # NaN fails
    return {"name": name, "error": error, "f32": f32, "tolerance": tolerance,
            "passed": passed, "note": note}


def compared(name, ours, ref, f32_run, floor, note=""):
    f32 = distance(f32_run, ref)
    return row(name, distance(ours, ref), f32, max(TIMES * f32, floor), note)


def batch_floor(trace):
    return TIMES * math.sqrt(trace["meta"]["steps"] * trace["meta"]["agents"]) * U32


def config_checks(config):
    rows = []
    for key, (released, default) in RELEASED_CONFIG.items():
        value = config.get(key, default)
        rows.append({"name": f"config.{key}", "error": None, "f32": None, "tolerance": None,
                     "passed": value == released,
                     "note": f"ours {json.dumps(value)}, released {json.dumps(released)}"})
    return rows


def weighted_dot(a, b, scales):
    return sum((a[k] * b[k]).sum().item() / scales[k] ** 2 for k in scales)


def flips(residuals, jumps, scales, floor, keep=32):
    """For each residual (ours - ref, float32 run - ref: gradients in our names), the flips
    of units near a kink that explain it: among the `keep` jumps that would reduce it most
    and move some tensor by more than `floor` of its max |ref|, greedily each jump that is at
    least 3/4 contained in what is left (<r, j> >= 3/4 <j, j>, each tensor relative to its
    max |ref|). Returns [(labels, sum of their jumps)] and the number of jumps."""
    best = [[] for _ in residuals]
    count = 0
    for label, jump in jumps:
        count += 1
        norm = weighted_dot(jump, jump, scales)
        if max(jump[k].abs().max().item() / scales[k] for k in scales) < floor:
            continue
        for residual, top in zip(residuals, best):
            gain = 2 * weighted_dot(residual, jump, scales) - norm
            if gain > 0:
                top.append((gain, label, jump, norm))
                top.sort(key=lambda t: -t[0])
                del top[keep:]
    return [explain(residual, top, scales) for residual, top in zip(residuals, best)], count


def explain(residual, top, scales):
    left, chosen = dict(residual), []
    remaining = [(label, jump, norm) for _gain, label, jump, norm in top]
    while remaining:
        ratios = [weighted_dot(left, jump, scales) / norm for _label, jump, norm in remaining]
        pick = max(range(len(ratios)), key=ratios.__getitem__)
        if ratios[pick] < 0.75:
            break
        chosen.append(remaining.pop(pick))
        left = {k: left[k] - chosen[-1][1][k] for k in left}
    total = {k: sum((jump[k] for _label, jump, _norm in chosen), torch.zeros_like(v))
             for k, v in residual.items()}
    return [label for label, _jump, _norm in chosen], total


def gradient_rows(trace, r64, r32, floor):
    """Epoch-0 gradients, each run's flips of units near a kink added to the reference."""
    ref = {k: v.double() for k, v in r64["grads"][0].items()}
    scales = {k: v.abs().max().item() or 1.0 for k, v in ref.items()}
    runs = ({k: trace["ours"][f"grad.{k}"].double() for k in ref},
            {k: v.double() for k, v in r32["grads"][0].items()})
    explained, candidates = flips([{k: run[k] - ref[k] for k in ref} for run in runs],
                                  kink_jumps(trace, r64, r32), scales, floor)
    (ours_flips, ours_jump), (f32_flips, f32_jump) = explained
    note = f"{len(ours_flips)} kink flips (float32 run {len(f32_flips)})"
    rows = []
    for name in our_names():
        f32 = distance(runs[1][name], ref[name] + f32_jump[name])
        rows.append(row(f"grad.{name}", distance(runs[0][name], ref[name] + ours_jump[name]),
                        f32, max(TIMES * f32, floor), note))
    kinks = {"candidates": candidates, "ours": ours_flips, "float32": f32_flips}
    return rows, kinks


def adam_bound(config):
    """lr sum_t c_t: the most |m_hat / (sqrt(v_hat) + eps)| x lr can add up to over K steps."""
    b1, b2 = config["adam_beta1"], config["adam_beta2"]
    total = 0.0
    for t in range(1, config["epochs"] + 1):
        w = [(1 - b1) * b1 ** (t - k) / (1 - b1 ** t) for k in range(1, t + 1)]
        v = [(1 - b2) * b2 ** (t - k) / (1 - b2 ** t) for k in range(1, t + 1)]
        total += math.sqrt(sum(wk * wk / vk for wk, vk in zip(w, v)))
    return config["learning_rate"] * total


def determined(name, r64, grad_tolerance):
    """Elements whose gradient is at least DETERMINED x the epoch-0 gradient tolerance at
    every epoch (in the float64 run)."""
    g0 = r64["grads"][0][name]
    threshold = DETERMINED * grad_tolerance * (g0.abs().max().item() or 1.0)
    mask = torch.ones_like(g0, dtype=torch.bool)
    for grads in r64["grads"]:
        mask &= grads[name].abs() >= threshold
    return mask


def storage_rounding(before, after, config):
    """Per element, the most K float32 roundings of the weight (half an ulp each) can add to
    its change: K/2 ulp of the largest magnitude it can pass through."""
    largest = torch.maximum(before.abs(), after.abs()) + adam_bound(config)
    ulp = np.spacing(largest.numpy().astype(np.float32)).astype(np.float64)
    return config["epochs"] / 2 * torch.from_numpy(ulp)


def excess(delta, ref, slack, scale):
    """Per element, what |delta - ref| exceeds `slack` by, relative to `scale`."""
    return ((delta - ref).abs() - slack).clamp(min=0) / scale


def median(values):
    return values.median().item() if values.numel() else 0.0


def change_rows(name, trace, r64, r32, grad_tolerance):
    """`change.NAME`: the median excess over the well-determined elements; `.bound`: every
    element within Adam's bound."""
    config = trace["config"]
    before = trace["before"][name].double()
    after, after32 = trace["ours"][f"after.{name}"].double(), r32["after"][name].double()
    ref = r64["after"][name] - before
    mask = determined(name, r64, grad_tolerance)
    scale = ref.abs().max().item() or config["learning_rate"]
    ours = excess(after - before, ref, storage_rounding(before, after, config), scale)
    f32_run = excess(after32 - before, ref, storage_rounding(before, after32, config), scale)
    f32 = median(f32_run[mask])
    tolerance = max(TIMES * f32, batch_floor(trace))
    beyond = [(e[mask] > tolerance).double().mean().item() if mask.any() else 0.0
              for e in (ours, f32_run)]
    note = (f"median of {mask.double().mean().item():.1%} of {mask.numel()}; beyond the "
            f"tolerance {beyond[0]:.1%} (float32 run {beyond[1]:.1%})")
    bound = 2 * adam_bound(config) / scale
    return [
        row(f"change.{name}", median(ours[mask]), f32, tolerance, note),
        row(f"change.{name}.bound", (ours - bound).clamp(min=0).max().item(), None, 0.0,
            f"beyond 2 x Adam's bound ({bound:.3g})"),
    ]


def comparisons(trace, r64, r32):
    ours = trace["ours"]
    floor = batch_floor(trace)
    rows = config_checks(trace["config"])
    rows.append(compared("returns", ours["returns"], r64["returns"], r32["returns"], floor))
    rows.append(compared("old_log_probs", trace["rollout"]["old_log_probs"], r64["logprobs"],
                         r32["logprobs"], floor, note="against the port's epoch-0 log-probs"))
    for key in TERMS:
        rows.append(compared(f"term.{key}", float(trace["terms"][key]), r64["terms"][key],
                             r32["terms"][key], floor))
    grads, kinks = gradient_rows(trace, r64, r32, floor)
    rows += grads
    for g in grads:
        rows.extend(change_rows(g["name"][len("grad."):], trace, r64, r32, g["tolerance"]))
    return rows, kinks


# ------------------------------------------------------------------- report


def cell(value):
    return "-" if value is None else f"{value:.3e}"


def report(rows, kinks, folder):
    print(f"kinks: {kinks['candidates']} (leaky) ReLU inputs within 10 x float32 rounding of 0; "
          f"flips taken for ours: {kinks['ours'] or 'none'}, for the float32 run: "
          f"{kinks['float32'] or 'none'}")
    width = max(len(r["name"]) for r in rows)
    print(f"{'check':<{width}}  {'error':>10}  {'f32 round':>10}  {'tolerance':>10}  result")
    for r in rows:
        print(f"{r['name']:<{width}}  {cell(r['error']):>10}  {cell(r['f32']):>10}  "
              f"{cell(r['tolerance']):>10}  {'pass' if r['passed'] else 'FAIL'}  {r['note']}")
    failed = [r["name"] for r in rows if not r["passed"]]
    summary = {"checks": len(rows), "passed": len(rows) - len(failed), "failed": len(failed),
               "failed_names": failed, "kinks": kinks, "rows": rows}
    print(f"released update: {len(rows)} checks, {len(rows) - len(failed)} passed, "
          f"{len(failed)} failed")
    if failed:
        more = f" and {len(failed) - 10} more" if len(failed) > 10 else ""
        print(f"FAILED: {', '.join(failed[:10])}{more}")
    (folder / "comparison.json").write_text(json.dumps(summary, indent=1) + "\n")
    return not failed


def main(argv):
    if len(argv) != 2:
        print("usage: released_update.py DIR", file=sys.stderr)
        return 2
    folder = Path(argv[1])
    try:
        trace = read_trace(folder)
        rows = [observation_check(trace)]
        r64 = released_update(trace, torch.float64)
        r32 = released_update(trace, torch.float32)
    except (BadInput, KeyError) as error:
        print(f"released_update: bad input: {error}", file=sys.stderr)
        return 2
    more, kinks = comparisons(trace, r64, r32)
    return 0 if report(rows + more, kinks, folder) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
