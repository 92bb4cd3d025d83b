//! Multi-head graph attention as in the paper: per head m, `W^m h`; the score of edge i <- j is
//! `LeakyReLU_0.2(a^m . [W^m h_i || W^m h_j])`, softmax over the neighbours of i; the message is
//! `h_i' = mean_m sum_j alpha_ij^m W^m h_j`. No bias (the paper's formula). The projection of the
//! whole batch is one GEMM; the per-edge work is small (edges x heads x features).
//!
//! `a^m . [x || y]` splits into a receiver part `a_l . x` and a sender part `a_r . y`, computed
//! once per agent instead of once per edge.

use ndarray::{ArrayView2, ArrayViewMut2};
use rand::Rng;

use super::activation::LeakyRelu;
use super::buffer::ReusableBuffer;
use super::error::NnError;
use super::graph::AgentGraph;
use super::init::Init;
use super::matmul::{matmul, matmul_add};
use super::params::{ParamSlot, ParamStore};
use super::real::Real;
use super::softmax::{log_softmax_backward_in_place, log_softmax_in_place};

/// The rectifier of the attention scores (slope 0.2, as GAT).
const SCORE_ACTIVATION: LeakyRelu = LeakyRelu {
    negative_slope: 0.2,
};

/// A graph-attention layer; its parameters are `{name}.weight` `[heads * out, in]` (all heads'
/// `W^m` stacked) and `{name}.attention` `[heads, 2 * out]` (each head's `a^m`).
#[derive(Debug, Clone)]
pub(crate) struct GraphAttention {
    in_features: usize,
    out_features: usize,
    heads: usize,
    weight: ParamSlot,
    attention: ParamSlot,
}

/// Activations of one batch: kept for backward and for reading the attention weights.
#[derive(Debug, Clone, Default)]
pub struct AttentionWorkspace<T> {
    batch: usize,
    heads: usize,
    edges: usize,
    /// `W h`, `[batch, heads * out]`.
    projected: ReusableBuffer<T>,
    /// `a_l^m . W^m h_i` and `a_r^m . W^m h_i`, `[batch, heads]`.
    receiver_scores: ReusableBuffer<T>,
    sender_scores: ReusableBuffer<T>,
    /// `log alpha`, `[heads, edges]` in the graph's edge order.
    log_weights: ReusableBuffer<T>,
    weights: ReusableBuffer<T>,
    entropy: T,
    head_mean_entropy: T,
    d_projected: ReusableBuffer<T>,
    d_log_weights: ReusableBuffer<T>,
    d_receiver_scores: ReusableBuffer<T>,
    d_sender_scores: ReusableBuffer<T>,
    /// One edge's dot products of the message gradient with each head's projected sender.
    head_dots: ReusableBuffer<T>,
}

impl<T: Real> AttentionWorkspace<T> {
    /// The attention weights `alpha_ij^m` of the last forward pass, `[heads, edges]`; edge `e`
    /// is the one of [`AgentGraph::edge_range`] and [`AgentGraph::neighbour_rows`].
    pub fn attention_weights(&self) -> ArrayView2<'_, T> {
        self.weights.matrix(self.heads, self.edges)
    }

    /// Mean over agents (all batch rows) and heads of `-sum_j alpha log alpha`. Agents
    /// without neighbours count as 0.
    pub fn attention_entropy(&self) -> T {
        self.entropy
    }

    /// Mean over agents of the entropy of the heads' averaged weights, `-sum_j abar log abar`
    /// with `abar_ij = mean_m alpha_ij^m`: the released code's `att_entropy`, taken of the
    /// head-averaged attention (`ave_heads`) row by row. Agents without neighbours count as 0.
    pub fn head_mean_attention_entropy(&self) -> T {
        self.head_mean_entropy
    }
}

/// The loss's gradients with respect to the two attention entropies.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EntropyGradients<T> {
    /// With respect to [`AttentionWorkspace::attention_entropy`].
    pub each_head: T,
    /// With respect to [`AttentionWorkspace::head_mean_attention_entropy`].
    pub head_mean: T,
}

impl GraphAttention {
    /// Allocates and draws the parameters; `W` has fan-in `in_features`, each `a^m` fan-in
    /// `2 * out_features`.
    pub(crate) fn new<T: Real, R: Rng + ?Sized>(
        store: &mut ParamStore<T>,
        name: &str,
        in_features: usize,
        out_features: usize,
        heads: usize,
        init: Init,
        rng: &mut R,
    ) -> Result<Self, NnError> {
        if in_features == 0 || out_features == 0 || heads == 0 {
            return Err(NnError::shape(name, "features and heads must be positive"));
        }
        let weight = store.allocate(
            format!("{name}.weight"),
            &[heads * out_features, in_features],
        );
        init.fill_weight(weight.of_mut(store.values_mut()), in_features, rng);
        let attention = store.allocate(format!("{name}.attention"), &[heads, 2 * out_features]);
        init.fill_weight(attention.of_mut(store.values_mut()), 2 * out_features, rng);
        Ok(GraphAttention {
            in_features,
            out_features,
            heads,
            weight,
            attention,
        })
    }

    /// Where `W` `[heads * out, in]` lives in the flat buffers.
    pub(crate) fn weight_slot(&self) -> ParamSlot {
        self.weight
    }

    pub(crate) fn out_features(&self) -> usize {
        self.out_features
    }

    /// Forward FLOPs per agent when every agent has `neighbours` neighbours: the projection,
    /// the two score dot products, and per edge a score, a softmax term and a weighted sum.
    pub(crate) fn forward_flops_per_agent(&self, neighbours: usize) -> u64 {
        let projection = 2 * self.heads * self.out_features * self.in_features;
        let scores = 2 * 2 * self.heads * self.out_features;
        let per_edge = self.heads * (2 * self.out_features + 4);
        (projection + scores + neighbours * per_edge) as u64
    }

    fn weight<'a, T: Real>(&self, flat: &'a [T]) -> ArrayView2<'a, T> {
        let rows = self.heads * self.out_features;
        ArrayView2::from_shape((rows, self.in_features), self.weight.of(flat))
            .expect("slot holds heads * out * in values")
    }

    fn weight_mut<'a, T: Real>(&self, flat: &'a mut [T]) -> ArrayViewMut2<'a, T> {
        let rows = self.heads * self.out_features;
        ArrayViewMut2::from_shape((rows, self.in_features), self.weight.of_mut(flat))
            .expect("slot holds heads * out * in values")
    }

    /// Writes the messages `h' [batch, out]` of `h [batch, in]` over `graph` (whose agents are
    /// the batch rows).
    pub(crate) fn forward<T: Real>(
        &self,
        params: &[T],
        ws: &mut AttentionWorkspace<T>,
        h: ArrayView2<T>,
        graph: &AgentGraph,
        mut out: ArrayViewMut2<T>,
    ) {
        let (batch, width) = (h.nrows(), self.heads * self.out_features);
        (ws.batch, ws.heads, ws.edges) = (batch, self.heads, graph.edges());
        matmul(
            h,
            self.weight(params).t(),
            ws.projected.matrix_mut(batch, width),
        );
        self.project_scores(params, ws);
        self.normalise_scores(ws, graph);
        let projected = ws.projected.slice(batch * width);
        let weights = ws.weights.slice(self.heads * ws.edges);
        let head_share = T::one() / T::from_count(self.heads);
        out.fill(T::zero());
        for (i, mut message) in out.rows_mut().into_iter().enumerate() {
            let message = message.as_slice_mut().expect("rows are contiguous");
            for (e, j) in graph.edges_of(i) {
                for head in 0..self.heads {
                    let w = weights[head * ws.edges + e] * head_share;
                    let sender =
                        &projected[j * width + head * self.out_features..][..self.out_features];
                    message
                        .iter_mut()
                        .zip(sender)
                        .for_each(|(m, &x)| *m += w * x);
                }
            }
        }
    }

    /// The receiver and sender halves of every agent's score, per head.
    fn project_scores<T: Real>(&self, params: &[T], ws: &mut AttentionWorkspace<T>) {
        let (batch, f) = (ws.batch, self.out_features);
        let attention = self.attention.of(params);
        let projected = ws.projected.slice(batch * self.heads * f);
        let receiver = ws.receiver_scores.slice_mut(batch * self.heads);
        let sender = ws.sender_scores.slice_mut(batch * self.heads);
        for (k, (r, s)) in receiver.iter_mut().zip(sender.iter_mut()).enumerate() {
            let x = &projected[k * f..][..f];
            let head = k % self.heads;
            [*r, *s] = dots(&attention[head * 2 * f..][..2 * f], x);
        }
    }

    /// Edge scores, then log-softmax over each agent's neighbours per head, and the entropy.
    fn normalise_scores<T: Real>(&self, ws: &mut AttentionWorkspace<T>, graph: &AgentGraph) {
        let (edges, heads) = (ws.edges, self.heads);
        let receiver = ws.receiver_scores.slice(ws.batch * heads);
        let sender = ws.sender_scores.slice(ws.batch * heads);
        let log_weights = ws.log_weights.slice_mut(heads * edges);
        let mut entropy_sum = T::zero();
        for head in 0..heads {
            for i in 0..ws.batch {
                let range = graph.edge_range(i);
                let row = &mut log_weights[head * edges..][range.clone()];
                for (score, &j) in row.iter_mut().zip(&graph.neighbour_rows()[range]) {
                    let pre = receiver[i * heads + head] + sender[j * heads + head];
                    *score = SCORE_ACTIVATION.apply(pre);
                }
                entropy_sum += log_softmax_in_place(row);
            }
        }
        let weights = ws.weights.slice_mut(heads * edges);
        weights
            .iter_mut()
            .zip(log_weights.iter())
            .for_each(|(w, l)| *w = l.exp_portable());
        ws.entropy = entropy_sum / T::from_count((ws.batch * heads).max(1));
        ws.head_mean_entropy = self.head_mean_entropy(ws, graph);
    }

    /// `mean_i -sum_j abar_ij log abar_ij` over the weights of the forward pass.
    fn head_mean_entropy<T: Real>(&self, ws: &AttentionWorkspace<T>, graph: &AgentGraph) -> T {
        let weights = ws.weights.slice(self.heads * ws.edges);
        let mut sum = T::zero();
        for i in 0..ws.batch {
            for e in graph.edge_range(i) {
                let mean = self.head_mean(weights, ws.edges, e);
                if mean > T::zero() {
                    sum -= mean * mean.ln_portable();
                }
            }
        }
        sum / T::from_count(ws.batch.max(1))
    }

    /// `abar` of edge `e`, summed head by head in order.
    fn head_mean<T: Real>(&self, weights: &[T], edges: usize, e: usize) -> T {
        let sum = (0..self.heads).fold(T::zero(), |s, head| s + weights[head * edges + e]);
        sum / T::from_count(self.heads)
    }

    /// Accumulates parameter gradients and writes `dh [batch, in]`, for the loss gradient
    /// `d_out` with respect to the messages and `entropy_grad` with respect to the attention
    /// entropies. `h` and `graph` must be those of the forward pass.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn backward<T: Real>(
        &self,
        params: &[T],
        grads: &mut [T],
        ws: &mut AttentionWorkspace<T>,
        h: ArrayView2<T>,
        graph: &AgentGraph,
        d_out: ArrayView2<T>,
        entropy_grad: EntropyGradients<T>,
        dh: ArrayViewMut2<T>,
    ) {
        let (batch, width) = (ws.batch, self.heads * self.out_features);
        ws.d_projected.slice_mut(batch * width).fill(T::zero());
        self.backward_messages(ws, graph, d_out);
        self.backward_head_mean_entropy(ws, graph, entropy_grad.head_mean);
        self.backward_scores(ws, graph, entropy_grad.each_head);
        self.backward_score_projections(params, grads, ws);
        let d_projected = ws.d_projected.matrix(batch, width);
        matmul_add(d_projected.t(), h, self.weight_mut(grads));
        matmul(d_projected, self.weight(params), dh);
    }

    /// Through `h_i' = mean_m sum_j alpha W^m h_j`: into `W h` of the senders, and into the
    /// log-weights (`d log alpha = alpha d alpha`).
    fn backward_messages<T: Real>(
        &self,
        ws: &mut AttentionWorkspace<T>,
        graph: &AgentGraph,
        d_out: ArrayView2<T>,
    ) {
        let (edges, f, width) = (ws.edges, self.out_features, self.heads * self.out_features);
        let head_share = T::one() / T::from_count(self.heads);
        let projected = ws.projected.slice(ws.batch * width);
        let weights = ws.weights.slice(self.heads * edges);
        let d_projected = ws.d_projected.slice_mut(ws.batch * width);
        let d_log_weights = ws.d_log_weights.slice_mut(self.heads * edges);
        let head_dots = ws.head_dots.slice_mut(self.heads);
        for (i, d_message) in d_out.rows().into_iter().enumerate() {
            let d_message = d_message.to_slice().expect("rows are contiguous");
            for (e, j) in graph.edges_of(i) {
                dots_into(&projected[j * width..][..width], d_message, head_dots);
                for (head, &head_dot) in head_dots.iter().enumerate() {
                    let w = weights[head * edges + e];
                    let block = j * width + head * f;
                    let d_weight = head_share * head_dot;
                    d_log_weights[head * edges + e] = d_weight * w;
                    let d_sender = &mut d_projected[block..][..f];
                    let scale = head_share * w;
                    d_sender
                        .iter_mut()
                        .zip(d_message)
                        .for_each(|(d, &g)| *d += scale * g);
                }
            }
        }
    }

    /// Adds the head-mean entropy's part to the gradient with respect to the log-weights:
    /// `dH_i / d alpha^m_ij = -(log abar_ij + 1) / heads`, times `alpha` for its logarithm.
    fn backward_head_mean_entropy<T: Real>(
        &self,
        ws: &mut AttentionWorkspace<T>,
        graph: &AgentGraph,
        entropy_grad: T,
    ) {
        if entropy_grad == T::zero() {
            return;
        }
        let edges = ws.edges;
        let per_agent = entropy_grad / T::from_count(ws.batch.max(1));
        let head_share = T::one() / T::from_count(self.heads);
        let weights = ws.weights.slice(self.heads * edges);
        let d_log_weights = ws.d_log_weights.slice_mut(self.heads * edges);
        for i in 0..ws.batch {
            for e in graph.edge_range(i) {
                let mean = self.head_mean(weights, edges, e);
                if mean <= T::zero() {
                    continue;
                }
                let d_weight = -per_agent * head_share * (mean.ln_portable() + T::one());
                for head in 0..self.heads {
                    let k = head * edges + e;
                    d_log_weights[k] += d_weight * weights[k];
                }
            }
        }
    }

    /// Through the softmax (with the entropy term) and the leaky rectifier, into the receiver
    /// and sender score halves.
    fn backward_scores<T: Real>(
        &self,
        ws: &mut AttentionWorkspace<T>,
        graph: &AgentGraph,
        entropy_grad: T,
    ) {
        let (edges, heads) = (ws.edges, self.heads);
        let row_entropy_grad = entropy_grad / T::from_count((ws.batch * heads).max(1));
        let receiver = ws.receiver_scores.slice(ws.batch * heads);
        let sender = ws.sender_scores.slice(ws.batch * heads);
        let log_weights = ws.log_weights.slice(heads * edges);
        let d_log_weights = ws.d_log_weights.slice_mut(heads * edges);
        let d_receiver = ws.d_receiver_scores.slice_mut(ws.batch * heads);
        d_receiver.fill(T::zero());
        let d_sender = ws.d_sender_scores.slice_mut(ws.batch * heads);
        d_sender.fill(T::zero());
        for head in 0..heads {
            for i in 0..ws.batch {
                let range = graph.edge_range(i);
                let row = &mut d_log_weights[head * edges..][range.clone()];
                log_softmax_backward_in_place(
                    &log_weights[head * edges..][range.clone()],
                    row,
                    row_entropy_grad,
                );
                for (d_score, &j) in row.iter().zip(&graph.neighbour_rows()[range]) {
                    let pre = receiver[i * heads + head] + sender[j * heads + head];
                    let d_pre = *d_score * SCORE_ACTIVATION.derivative_at_output(pre);
                    d_receiver[i * heads + head] += d_pre;
                    d_sender[j * heads + head] += d_pre;
                }
            }
        }
    }

    /// Through `a_l . W h_i` and `a_r . W h_j`: into `a` and into `W h`.
    fn backward_score_projections<T: Real>(
        &self,
        params: &[T],
        grads: &mut [T],
        ws: &mut AttentionWorkspace<T>,
    ) {
        let f = self.out_features;
        let attention = self.attention.of(params);
        let d_attention = self.attention.of_mut(grads);
        let projected = ws.projected.slice(ws.batch * self.heads * f);
        let d_projected = ws.d_projected.slice_mut(ws.batch * self.heads * f);
        let d_receiver = ws.d_receiver_scores.slice(ws.batch * self.heads);
        let d_sender = ws.d_sender_scores.slice(ws.batch * self.heads);
        for k in 0..ws.batch * self.heads {
            let head = k % self.heads;
            let x = &projected[k * f..][..f];
            let dx = &mut d_projected[k * f..][..f];
            let (a_receiver, a_sender) = attention[head * 2 * f..][..2 * f].split_at(f);
            let (da_receiver, da_sender) = d_attention[head * 2 * f..][..2 * f].split_at_mut(f);
            for (a, da, d_score) in [
                (a_receiver, da_receiver, d_receiver[k]),
                (a_sender, da_sender, d_sender[k]),
            ] {
                da.iter_mut().zip(x).for_each(|(g, &v)| *g += d_score * v);
                dx.iter_mut().zip(a).for_each(|(g, &v)| *g += d_score * v);
            }
        }
    }
}

/// Dot products computed side by side, at most.
const MAX_CHAINS: usize = 4;

/// `out[r]`: the dot product of block `r` of `blocks` (`out.len()` blocks of `x.len()` values)
/// with `x`, up to `MAX_CHAINS` at once. A dot product is one chain of dependent adds, each
/// waiting for the last; side by side, the chains' latencies overlap. Each chain still adds in
/// order, so every dot product has the bits of the plain sequential sum.
fn dots_into<T: Real>(blocks: &[T], x: &[T], out: &mut [T]) {
    let f = x.len().max(1);
    for (blocks, out) in blocks
        .chunks(MAX_CHAINS * f)
        .zip(out.chunks_mut(MAX_CHAINS))
    {
        match out.len() {
            4 => out.copy_from_slice(&dots::<T, 4>(blocks, x)),
            3 => out.copy_from_slice(&dots::<T, 3>(blocks, x)),
            2 => out.copy_from_slice(&dots::<T, 2>(blocks, x)),
            _ => out.copy_from_slice(&dots::<T, 1>(blocks, x)),
        }
    }
}

/// The dot products of the `R` consecutive blocks of `blocks` with `x`, as [`dots_into`].
fn dots<T: Real, const R: usize>(blocks: &[T], x: &[T]) -> [T; R] {
    let rows: [&[T]; R] = std::array::from_fn(|r| &blocks[r * x.len()..][..x.len()]);
    let mut sums = [T::zero(); R];
    for (k, &value) in x.iter().enumerate() {
        for (sum, row) in sums.iter_mut().zip(&rows) {
            *sum += row[k] * value;
        }
    }
    sums
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gradient_check::{assert_gradients_match, dot as dot64, values_away_from_zero};
    use crate::graph::Neighbours;
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    const IN: usize = 4;
    const OUT: usize = 3;
    const HEADS: usize = 2;

    /// Groups of 3, 1 and 2 agents; the 3-group has a radius graph where agent 2 hears nobody.
    fn graph() -> AgentGraph {
        let mut graph = AgentGraph::new();
        graph.push_group(
            Neighbours::WithinRadius(1.5),
            &[[0.0, 0.0], [1.0, 0.0], [5.0, 0.0]],
        );
        graph.push_group(Neighbours::AllAgents, &[[0.0, 0.0]]);
        graph.push_group(Neighbours::AllOthers, &[[0.0, 0.0]; 2]);
        graph.push_group(Neighbours::AllAgents, &[[0.0, 0.0]; 3]);
        graph
    }

    fn forward(
        layer: &GraphAttention,
        params: &[f64],
        ws: &mut AttentionWorkspace<f64>,
        h: &[f64],
        graph: &AgentGraph,
    ) -> Vec<f64> {
        let batch = graph.agents();
        let mut out = vec![0.0; batch * OUT];
        let h = ArrayView2::from_shape((batch, IN), h).unwrap();
        let out_view = ArrayViewMut2::from_shape((batch, OUT), &mut out[..]).unwrap();
        layer.forward(params, ws, h, graph, out_view);
        out
    }

    /// One to five blocks (side by side in ones, twos, threes and fours): every dot product
    /// has the bits of the sequential sum.
    #[test]
    fn dot_products_side_by_side_have_the_bits_of_sequential_sums() {
        use rand::RngExt;
        let mut rng = Pcg64Mcg::seed_from_u64(31);
        let x: Vec<f32> = (0..37).map(|_| rng.random::<f32>() - 0.5).collect();
        for count in 1..=5 {
            let blocks: Vec<f32> = (0..count * x.len())
                .map(|_| rng.random::<f32>() - 0.5)
                .collect();
            let mut out = vec![f32::NAN; count];
            dots_into(&blocks, &x, &mut out);
            for (block, got) in blocks.chunks(x.len()).zip(&out) {
                let want = block.iter().zip(&x).fold(0.0f32, |s, (&a, &b)| s + a * b);
                assert_eq!(got.to_bits(), want.to_bits(), "{count} blocks");
            }
        }
    }

    #[test]
    fn gradients_match_finite_differences() {
        let mut rng = Pcg64Mcg::seed_from_u64(40);
        let mut store = ParamStore::new();
        let init = Init::Orthogonal { gain: 2.0 };
        let layer = GraphAttention::new(&mut store, "gat", IN, OUT, HEADS, init, &mut rng).unwrap();
        let graph = graph();
        let batch = graph.agents();
        let h = values_away_from_zero(batch * IN, &mut rng);
        let upstream = values_away_from_zero(batch * OUT, &mut rng);
        let entropy_grad = EntropyGradients {
            each_head: 0.8,
            head_mean: -0.6,
        };
        let loss = |p: &[f64], h: &[f64]| {
            let mut ws = AttentionWorkspace::default();
            let out = forward(&layer, p, &mut ws, h, &graph);
            dot64(&out, &upstream)
                + entropy_grad.each_head * ws.attention_entropy()
                + entropy_grad.head_mean * ws.head_mean_attention_entropy()
        };
        let params = store.values().to_vec();
        let mut ws = AttentionWorkspace::default();
        forward(&layer, &params, &mut ws, &h, &graph);
        let mut dh = vec![0.0; batch * IN];
        layer.backward(
            &params,
            store.grads_mut(),
            &mut ws,
            ArrayView2::from_shape((batch, IN), &h[..]).unwrap(),
            &graph,
            ArrayView2::from_shape((batch, OUT), &upstream[..]).unwrap(),
            entropy_grad,
            ArrayViewMut2::from_shape((batch, IN), &mut dh[..]).unwrap(),
        );
        assert_gradients_match(&params, store.grads(), |p| loss(p, &h));
        assert_gradients_match(&h, &dh, |h| loss(&params, h));
    }

    #[test]
    fn messages_follow_the_papers_formula() {
        let mut rng = Pcg64Mcg::seed_from_u64(41);
        let mut store = ParamStore::new();
        let init = Init::PyTorchDefault;
        let layer = GraphAttention::new(&mut store, "gat", IN, OUT, HEADS, init, &mut rng).unwrap();
        let graph = graph();
        let h = values_away_from_zero(graph.agents() * IN, &mut rng);
        let mut ws = AttentionWorkspace::default();
        let out = forward(&layer, store.values(), &mut ws, &h, &graph);
        let (w, a) = store.values().split_at(HEADS * OUT * IN);
        let project = |agent: usize, head: usize| -> Vec<f64> {
            (0..OUT)
                .map(|o| dot64(&w[(head * OUT + o) * IN..][..IN], &h[agent * IN..][..IN]))
                .collect()
        };
        let leaky = |x: f64| if x > 0.0 { x } else { 0.2 * x };
        for i in 0..graph.agents() {
            let mut expected = vec![0.0; OUT];
            for head in 0..HEADS {
                let a_head = &a[head * 2 * OUT..][..2 * OUT];
                let neighbours = &graph.neighbour_rows()[graph.edge_range(i)];
                let scores: Vec<f64> = neighbours
                    .iter()
                    .map(|&j| {
                        let pair = [project(i, head), project(j, head)].concat();
                        leaky(dot64(a_head, &pair)).exp()
                    })
                    .collect();
                let total: f64 = scores.iter().sum();
                for (&j, s) in neighbours.iter().zip(&scores) {
                    let alpha = s / total;
                    for (x, v) in expected.iter_mut().zip(project(j, head)) {
                        *x += alpha * v / HEADS as f64;
                    }
                }
            }
            for (got, want) in out[i * OUT..][..OUT].iter().zip(&expected) {
                assert!((got - want).abs() < 1e-12, "agent {i}: {got} vs {want}");
            }
        }
        assert_eq!(
            &out[2 * OUT..3 * OUT],
            &[0.0; OUT],
            "an agent with no neighbour"
        );
        let weights = ws.attention_weights();
        assert_eq!(weights.dim(), (HEADS, graph.edges()));
        for head in 0..HEADS {
            let sum: f64 = graph.edge_range(6).map(|e| weights[[head, e]]).sum();
            assert!((sum - 1.0).abs() < 1e-12);
        }
    }
}
