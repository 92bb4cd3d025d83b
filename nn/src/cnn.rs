//! The feature extractor: convolutions, each followed by ReLU, flattened (channels-last) into
//! one feature vector per sample.

use ndarray::ArrayView2;
use rand::Rng;

use super::activation::RELU;
use super::buffer::{AlternatingBuffers, ReusableBuffer};
use super::conv::{self, Conv2d, ConvSpec, ConvWorkspace, ImageShape};
use super::error::NnError;
use super::init::Init;
use super::params::ParamStore;
use super::real::Real;

/// The released code's extractor: 25 x 25 -> 16 x 5 x 5 -> 32 x 2 x 2 -> 32 x 2 x 2 = 128.
pub const PAPER_CONVOLUTIONS: [ConvSpec; 3] = [
    ConvSpec {
        out_channels: 16,
        kernel: 8,
        stride: 4,
        padding: 1,
    },
    ConvSpec {
        out_channels: 32,
        kernel: 4,
        stride: 2,
        padding: 1,
    },
    ConvSpec {
        out_channels: 32,
        kernel: 3,
        stride: 1,
        padding: 1,
    },
];

/// Convolutions with ReLU after each.
#[derive(Debug, Clone)]
pub(crate) struct CnnEncoder {
    convs: Vec<Conv2d>,
}

/// Every convolution's workspace and output, and the gradient buffers of the backward pass.
#[derive(Debug, Clone, Default)]
pub(crate) struct CnnWorkspace<T> {
    batch: usize,
    convs: Vec<ConvWorkspace<T>>,
    outputs: Vec<ReusableBuffer<T>>,
    grads: AlternatingBuffers<T>,
}

impl CnnEncoder {
    /// Convolutions named `{name}.0`, `{name}.1`, ...
    pub(crate) fn new<T: Real, R: Rng + ?Sized>(
        store: &mut ParamStore<T>,
        name: &str,
        input: ImageShape,
        specs: &[ConvSpec],
        init: Init,
        rng: &mut R,
    ) -> Result<Self, NnError> {
        if specs.is_empty() {
            return Err(NnError::shape(name, "needs at least one convolution"));
        }
        let mut convs: Vec<Conv2d> = Vec::with_capacity(specs.len());
        for (k, &spec) in specs.iter().enumerate() {
            let shape = convs.last().map_or(input, Conv2d::output_shape);
            convs.push(Conv2d::new(
                store,
                &format!("{name}.{k}"),
                shape,
                spec,
                init,
                rng,
            )?);
        }
        Ok(CnnEncoder { convs })
    }

    /// Values per input sample.
    pub(crate) fn input_len(&self) -> usize {
        self.convs[0].input_shape().len()
    }

    /// The shape of the last convolution's output, which the features flatten channels-last.
    pub(crate) fn output_shape(&self) -> ImageShape {
        self.convs[self.convs.len() - 1].output_shape()
    }

    /// Features per sample.
    pub(crate) fn features(&self) -> usize {
        self.output_shape().len()
    }

    pub(crate) fn forward_flops_per_sample(&self) -> u64 {
        self.convs
            .iter()
            .map(Conv2d::forward_flops_per_sample)
            .sum()
    }

    /// The features `[batch, features]` of `x` (`batch` images of the input shape).
    pub(crate) fn forward<'w, T: Real>(
        &self,
        params: &[T],
        ws: &'w mut CnnWorkspace<T>,
        x: &[T],
        batch: usize,
    ) -> ArrayView2<'w, T> {
        Self::forward_sharing_input(params, x, batch, [(self, &mut *ws)]);
        self.output(ws)
    }

    /// Encoders of one input shape and first convolution on the same `x` (the actor's and the
    /// critic's, on the observations): their first layers write the patches of `x` once
    /// ([`conv::forward_sharing_input`]), every other layer runs on its own. Each encoder's
    /// features, read with [`CnnEncoder::output`], have the bits of its own forward pass.
    pub(crate) fn forward_sharing_input<T: Real, const N: usize>(
        params: &[T],
        x: &[T],
        batch: usize,
        mut encoders: [(&CnnEncoder, &mut CnnWorkspace<T>); N],
    ) {
        for (encoder, ws) in &mut encoders {
            ws.batch = batch;
            ws.convs.resize_with(encoder.convs.len(), Default::default);
            ws.outputs
                .resize_with(encoder.convs.len(), Default::default);
        }
        let first_layers = encoders.each_mut().map(|(encoder, ws)| {
            let out = encoder.convs[0].output_shape();
            let y = ws.outputs[0].matrix_mut(batch * out.height * out.width, out.channels);
            (&encoder.convs[0], &mut ws.convs[0], y)
        });
        conv::forward_sharing_input(params, x, first_layers);
        for (encoder, ws) in &mut encoders {
            for k in 0..encoder.convs.len() {
                encoder.forward_layer(params, ws, k);
            }
        }
    }

    /// Layer `k` on the output of the layer below (its product already made for `k = 0`),
    /// then its ReLU.
    fn forward_layer<T: Real>(&self, params: &[T], ws: &mut CnnWorkspace<T>, k: usize) {
        let (conv, batch) = (&self.convs[k], ws.batch);
        let out = conv.output_shape();
        let (done, rest) = ws.outputs.split_at_mut(k);
        let mut y = rest[0].matrix_mut(batch * out.height * out.width, out.channels);
        if let Some(previous) = done.last() {
            let input = previous.slice(batch * conv.input_shape().len());
            conv.forward(params, input, &mut ws.convs[k], y.view_mut());
        }
        RELU.forward_in_place(y.as_slice_mut().expect("buffer views are contiguous"));
    }

    /// The features of the last forward pass.
    pub(crate) fn output<'w, T: Real>(&self, ws: &'w CnnWorkspace<T>) -> ArrayView2<'w, T> {
        ws.outputs[self.convs.len() - 1].matrix(ws.batch, self.features())
    }

    /// Accumulates parameter gradients for the feature gradient `d_features`, and writes the
    /// input gradient to `dx` when given. `x` is the input of the last forward pass.
    #[cfg(test)]
    fn backward<T: Real>(
        &self,
        grads: &mut [T],
        ws: &mut CnnWorkspace<T>,
        x: &[T],
        d_features: ArrayView2<T>,
        dx: Option<&mut [T]>,
    ) {
        Self::backward_sharing_input(grads, x, [(self, ws, d_features)], dx);
    }

    /// The backward pass of [`CnnEncoder::forward_sharing_input`], each encoder with its
    /// feature gradient; `dx`, when given, gets the input gradient through every encoder.
    pub(crate) fn backward_sharing_input<T: Real, const N: usize>(
        grads: &mut [T],
        x: &[T],
        mut encoders: [(&CnnEncoder, &mut CnnWorkspace<T>, ArrayView2<T>); N],
        dx: Option<&mut [T]>,
    ) {
        for (encoder, ws, d_features) in &mut encoders {
            encoder.backward_above_first(grads, ws, *d_features);
        }
        let first_layers = encoders.each_mut().map(|(encoder, ws, _)| {
            let conv = &encoder.convs[0];
            let out = conv.output_shape();
            let rows = ws.batch * out.height * out.width;
            let (d_output, _) = ws.grads.output_and_input_grads(0);
            (conv, &mut ws.convs[0], d_output.matrix(rows, out.channels))
        });
        conv::backward_sharing_input(grads, x, first_layers, dx);
    }

    /// Every layer's backward pass but the first's, whose output gradient (through its ReLU)
    /// it leaves in the gradient buffers.
    fn backward_above_first<T: Real>(
        &self,
        grads: &mut [T],
        ws: &mut CnnWorkspace<T>,
        d_features: ArrayView2<T>,
    ) {
        let batch = ws.batch;
        let last = self.convs.len() - 1;
        let d_top = ws
            .grads
            .output_grad_mut(last)
            .slice_mut(batch * self.features());
        d_top.copy_from_slice(
            d_features
                .as_slice()
                .expect("feature gradients are contiguous"),
        );
        RELU.backward_in_place(ws.outputs[last].slice(d_top.len()), d_top);
        for (k, conv) in self.convs.iter().enumerate().skip(1).rev() {
            // `current`: the gradient of conv k's output, already through its ReLU.
            let (current, previous) = ws.grads.output_and_input_grads(k);
            let out = conv.output_shape();
            let d_output = current.matrix(batch * out.height * out.width, out.channels);
            let input_len = batch * conv.input_shape().len();
            let d_input = previous.slice_mut(input_len);
            let below = k - 1;
            let input = ws.outputs[below].slice(input_len);
            conv.backward(
                grads,
                &mut ws.convs[k],
                input,
                d_output,
                Some(&mut *d_input),
            );
            RELU.backward_in_place(ws.outputs[below].slice(d_input.len()), d_input);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conv::ChannelOrder;
    use crate::gradient_check::{assert_gradients_match, dot, values_away_from_zero};
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    #[test]
    fn the_papers_extractor_gives_128_features() {
        let mut rng = Pcg64Mcg::seed_from_u64(0);
        let mut store = ParamStore::<f32>::new();
        let input = ImageShape {
            channels: 2,
            height: 25,
            width: 25,
            order: ChannelOrder::First,
        };
        let cnn = CnnEncoder::new(
            &mut store,
            "cnn",
            input,
            &PAPER_CONVOLUTIONS,
            Init::PyTorchDefault,
            &mut rng,
        );
        assert_eq!(cnn.unwrap().features(), 128);
    }

    #[test]
    fn gradients_match_finite_differences() {
        let mut rng = Pcg64Mcg::seed_from_u64(60);
        let mut store = ParamStore::new();
        let input = ImageShape {
            channels: 2,
            height: 9,
            width: 9,
            order: ChannelOrder::First,
        };
        let specs = [
            ConvSpec {
                out_channels: 3,
                kernel: 3,
                stride: 2,
                padding: 1,
            },
            ConvSpec {
                out_channels: 4,
                kernel: 2,
                stride: 1,
                padding: 0,
            },
        ];
        // Not orthogonal: its zero biases would put all-zero patches exactly on the ReLU kink.
        let init = Init::PyTorchDefault;
        let cnn = CnnEncoder::new(&mut store, "cnn", input, &specs, init, &mut rng).unwrap();
        let batch = 3;
        let features = cnn.features();
        assert_eq!(features, 4 * 4 * 4);
        let x = values_away_from_zero(batch * input.len(), &mut rng);
        let upstream = values_away_from_zero(batch * features, &mut rng);
        let loss = |p: &[f64], x: &[f64]| {
            let mut ws = CnnWorkspace::default();
            let y = cnn.forward(p, &mut ws, x, batch);
            dot(y.as_slice().unwrap(), &upstream)
        };
        let params = store.values().to_vec();
        let mut ws = CnnWorkspace::default();
        cnn.forward(&params, &mut ws, &x, batch);
        let mut dx = vec![0.0; x.len()];
        let dy = ArrayView2::from_shape((batch, features), &upstream[..]).unwrap();
        cnn.backward(store.grads_mut(), &mut ws, &x, dy, Some(&mut dx));
        assert_gradients_match(&params, store.grads(), |p| loss(p, &x));
        assert_gradients_match(&x, &dx, |x| loss(&params, x));
    }
}
