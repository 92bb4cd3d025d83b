//! A stack of fully connected layers with ReLU between them (none after the last), as the
//! actor and critic heads.

use ndarray::{ArrayView2, ArrayViewMut2};
use rand::Rng;

use super::activation::RELU;
use super::buffer::{AlternatingBuffers, ReusableBuffer};
use super::error::NnError;
use super::init::Init;
use super::linear::Linear;
use super::params::{ParamSlot, ParamStore};
use super::real::Real;

/// Fully connected layers `sizes[0] -> sizes[1] -> ... -> sizes[n]`.
#[derive(Debug, Clone)]
pub(crate) struct Mlp {
    layers: Vec<Linear>,
}

/// Each layer's output (after its ReLU) from the last forward pass, and the gradient buffers
/// of the backward pass.
#[derive(Debug, Clone, Default)]
pub(crate) struct MlpWorkspace<T> {
    batch: usize,
    outputs: Vec<ReusableBuffer<T>>,
    grads: AlternatingBuffers<T>,
}

impl Mlp {
    /// Layers are named `{name}.0`, `{name}.1`, ...; the last one is drawn with `output_init`
    /// (PPO codes often shrink the policy and value outputs).
    pub(crate) fn new<T: Real, R: Rng + ?Sized>(
        store: &mut ParamStore<T>,
        name: &str,
        sizes: &[usize],
        hidden_init: Init,
        output_init: Init,
        rng: &mut R,
    ) -> Result<Self, NnError> {
        if sizes.len() < 2 {
            return Err(NnError::shape(name, "needs an input and an output size"));
        }
        let last = sizes.len() - 2;
        let layers = sizes
            .windows(2)
            .enumerate()
            .map(|(k, pair)| {
                let init = if k == last { output_init } else { hidden_init };
                Linear::new(store, &format!("{name}.{k}"), pair[0], pair[1], init, rng)
            })
            .collect::<Result<_, _>>()?;
        Ok(Mlp { layers })
    }

    /// Where the first layer's weight `[outputs, inputs]` lives in the flat buffers.
    pub(crate) fn first_weight_slot(&self) -> ParamSlot {
        self.layers[0].weight_slot()
    }

    fn outputs(&self) -> usize {
        self.layers[self.layers.len() - 1].outputs()
    }

    pub(crate) fn forward_flops_per_row(&self) -> u64 {
        self.layers.iter().map(Linear::forward_flops_per_row).sum()
    }

    /// The output `[batch, outputs]` of `x [batch, inputs]`.
    pub(crate) fn forward<'w, T: Real>(
        &self,
        params: &[T],
        ws: &'w mut MlpWorkspace<T>,
        x: ArrayView2<T>,
    ) -> ArrayView2<'w, T> {
        let batch = x.nrows();
        ws.batch = batch;
        ws.outputs.resize_with(self.layers.len(), Default::default);
        for (k, layer) in self.layers.iter().enumerate() {
            let (done, rest) = ws.outputs.split_at_mut(k);
            let input = match done.last() {
                Some(previous) => previous.matrix(batch, layer.inputs()),
                None => x.view(),
            };
            let mut y = rest[0].matrix_mut(batch, layer.outputs());
            layer.forward(params, input, y.view_mut());
            if k + 1 < self.layers.len() {
                RELU.forward_in_place(y.as_slice_mut().expect("buffer views are contiguous"));
            }
        }
        self.output(ws)
    }

    /// The output of the last forward pass.
    fn output<'w, T: Real>(&self, ws: &'w MlpWorkspace<T>) -> ArrayView2<'w, T> {
        ws.outputs[self.layers.len() - 1].matrix(ws.batch, self.outputs())
    }

    /// Accumulates parameter gradients for the output gradient `dy`, and writes the input
    /// gradient to `dx` when given. `x` must be the forward pass's input.
    pub(crate) fn backward<T: Real>(
        &self,
        params: &[T],
        grads: &mut [T],
        ws: &mut MlpWorkspace<T>,
        x: ArrayView2<T>,
        dy: ArrayView2<T>,
        mut dx: Option<ArrayViewMut2<T>>,
    ) {
        let batch = ws.batch;
        for (k, layer) in self.layers.iter().enumerate().rev() {
            let (current, previous) = ws.grads.output_and_input_grads(k);
            let d_output = if k + 1 == self.layers.len() {
                dy.view()
            } else {
                current.matrix(batch, layer.outputs())
            };
            let input = match k.checked_sub(1) {
                Some(below) => ws.outputs[below].matrix(batch, layer.inputs()),
                None => x.view(),
            };
            layer.accumulate_param_grads(grads, input, d_output);
            if k == 0 {
                if let Some(dx) = dx.take() {
                    layer.input_grad(params, d_output, dx);
                }
                continue;
            }
            let mut d_input = previous.matrix_mut(batch, layer.inputs());
            layer.input_grad(params, d_output, d_input.view_mut());
            RELU.backward_in_place(
                input.as_slice().expect("buffer views are contiguous"),
                d_input.as_slice_mut().expect("buffer views are contiguous"),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gradient_check::{assert_gradients_match, dot, values_away_from_zero};
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    #[test]
    fn gradients_match_finite_differences() {
        let mut rng = Pcg64Mcg::seed_from_u64(50);
        let mut store = ParamStore::new();
        let init = Init::PyTorchDefault;
        let mlp = Mlp::new(&mut store, "mlp", &[4, 6, 5, 3], init, init, &mut rng).unwrap();
        let batch = 4;
        let x = values_away_from_zero(batch * 4, &mut rng);
        let upstream = values_away_from_zero(batch * 3, &mut rng);
        let loss = |p: &[f64], x: &[f64]| {
            let mut ws = MlpWorkspace::default();
            let x = ArrayView2::from_shape((batch, 4), x).unwrap();
            let y = mlp.forward(p, &mut ws, x);
            dot(y.as_slice().unwrap(), &upstream)
        };
        let params = store.values().to_vec();
        let mut ws = MlpWorkspace::default();
        let x_view = ArrayView2::from_shape((batch, 4), &x[..]).unwrap();
        mlp.forward(&params, &mut ws, x_view);
        let mut dx = vec![0.0; x.len()];
        let dy = ArrayView2::from_shape((batch, 3), &upstream[..]).unwrap();
        let dx_view = ArrayViewMut2::from_shape((batch, 4), &mut dx[..]).unwrap();
        mlp.backward(
            &params,
            store.grads_mut(),
            &mut ws,
            x_view,
            dy,
            Some(dx_view),
        );
        assert_gradients_match(&params, store.grads(), |p| loss(p, &x));
        assert_gradients_match(&x, &dx, |x| loss(&params, x));
    }
}
