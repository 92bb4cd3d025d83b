//! 2-D convolution as im2col + one GEMM for the whole batch, the patch matrix written band by
//! band just before its band is multiplied, while it is in the caches, and written again in
//! the backward pass rather than kept. Outputs are channels-last (`[batch, out_h, out_w,
//! channels]`, which is the GEMM's natural `[batch * positions, channels]` result); inputs may
//! be either order, so observations can arrive as channel planes. The weight keeps PyTorch's
//! `[out, in, kh, kw]` layout.
//!
//! A patch's columns follow the input's memory order, `(channel, ky, kx)` for channel planes
//! and `(ky, kx, channel)` for channels-last inputs, so that im2col copies long contiguous runs
//! (a whole kernel row of every channel at once for channels-last) instead of single values.
//! The GEMM reads a copy of the weight permuted to that order, and the weight gradient is
//! permuted back; both copies are a few thousand values per batch.

use ndarray::{ArrayView2, ArrayViewMut2, s};
use rand::Rng;
use rayon::prelude::*;

use super::buffer::ReusableBuffer;
use super::error::NnError;
use super::init::Init;
use super::linear::Linear;
use super::matmul::{matmul_add_banded, matmul_transposed_banded, row_band_product};
use super::params::ParamStore;
use super::real::Real;

/// Samples per rayon task when scattering patches.
const SAMPLES_PER_TASK: usize = 32;

/// Patch values written and multiplied as one band (256 KiB of `f32`): a band stays in L2
/// between im2col and the GEMM. The whole patch matrix (51 MB for the paper's first layer at
/// 4000 samples) is never kept: the backward pass writes each band again from the input.
const PATCH_BAND_VALUES: usize = 1 << 16;

/// Where the channel index sits in one sample's memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ChannelOrder {
    /// `[channels, height, width]`, as observation planes.
    First,
    /// `[height, width, channels]`, as this module's outputs.
    Last,
}

/// The shape of one sample's image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageShape {
    pub channels: usize,
    pub height: usize,
    pub width: usize,
    pub(crate) order: ChannelOrder,
}

impl ImageShape {
    /// Values per sample.
    pub fn len(&self) -> usize {
        self.channels * self.height * self.width
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Offset of element (channel, y, x) in one sample.
    fn offset(&self, channel: usize, y: usize, x: usize) -> usize {
        match self.order {
            ChannelOrder::First => (channel * self.height + y) * self.width + x,
            ChannelOrder::Last => (y * self.width + x) * self.channels + channel,
        }
    }
}

/// A square kernel's hyper-parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConvSpec {
    pub out_channels: usize,
    pub kernel: usize,
    pub stride: usize,
    pub padding: usize,
}

/// A 2-D convolution layer.
#[derive(Debug, Clone)]
pub(crate) struct Conv2d {
    input: ImageShape,
    output: ImageShape,
    /// One sample's patch matrix (`[positions, in * kh * kw]`, row-major) as consecutive runs
    /// copied from consecutive input elements, or zero where they fall in the padding.
    /// Computed once so that im2col is a series of slice copies and its adjoint of slice sums.
    patch_runs: Vec<PatchRun>,
    patch_len_per_sample: usize,
    /// For each element of the GEMM's weight `[patch columns, out]` (row-major), its position
    /// in the stored `[out, in, kh, kw]` weight.
    weight_order: Vec<usize>,
    dense: Linear,
}

/// One convolution's scratch: bands of patches (or of their gradients), and the weight and its
/// gradient in the GEMM's order.
#[derive(Debug, Clone, Default)]
pub(crate) struct ConvWorkspace<T> {
    patch_bands: ReusableBuffer<T>,
    weight: ReusableBuffer<T>,
    weight_grad: ReusableBuffer<T>,
}

impl Conv2d {
    /// Allocates `{name}.weight` `[out, in, k, k]` and `{name}.bias` and draws them.
    pub(crate) fn new<T: Real, R: Rng + ?Sized>(
        store: &mut ParamStore<T>,
        name: &str,
        input: ImageShape,
        spec: ConvSpec,
        init: Init,
        rng: &mut R,
    ) -> Result<Self, NnError> {
        let output = output_shape(name, input, spec)?;
        let patch_len = input.channels * spec.kernel * spec.kernel;
        let weight_shape = [spec.out_channels, input.channels, spec.kernel, spec.kernel];
        let dense = Linear::with_weight_shape(
            store,
            name,
            patch_len,
            spec.out_channels,
            &weight_shape,
            init,
            rng,
        )?;
        let taps = patch_taps(input, spec);
        Ok(Conv2d {
            input,
            output,
            patch_runs: patch_runs(input, output, spec, &taps),
            patch_len_per_sample: output.height * output.width * patch_len,
            weight_order: weight_order(input, spec, &taps),
            dense,
        })
    }

    pub(crate) fn input_shape(&self) -> ImageShape {
        self.input
    }

    pub(crate) fn output_shape(&self) -> ImageShape {
        self.output
    }

    fn positions(&self) -> usize {
        self.output.height * self.output.width
    }

    pub(crate) fn forward_flops_per_sample(&self) -> u64 {
        self.positions() as u64 * self.dense.forward_flops_per_row()
    }

    /// `y [batch * positions, out_channels]` from `x` (`batch` samples of the input shape, as
    /// many as `y`'s rows say). Keeps the weight in the GEMM's order in `ws` for the backward
    /// pass.
    pub(crate) fn forward<T: Real>(
        &self,
        params: &[T],
        x: &[T],
        ws: &mut ConvWorkspace<T>,
        y: ArrayViewMut2<T>,
    ) {
        forward_sharing_input(params, x, [(self, ws, y)]);
    }

    /// Copies the stored weight into `ws` in the GEMM's order.
    fn stage_weight<T: Real>(&self, params: &[T], ws: &mut ConvWorkspace<T>) {
        let stored = self.dense.weight_slot().of(params);
        let weight = ws.weight.slice_mut(self.weight_order.len());
        weight
            .iter_mut()
            .zip(&self.weight_order)
            .for_each(|(w, &source)| *w = stored[source]);
    }

    /// Whether this layer's patches of an input are `other`'s: one input shape and kernel.
    fn shares_patches_with(&self, other: &Conv2d) -> bool {
        self.input == other.input && self.patch_runs == other.patch_runs
    }

    /// Rows of the patch matrix per band: whole samples, about `PATCH_BAND_VALUES` values.
    fn band_rows(&self) -> usize {
        (PATCH_BAND_VALUES / self.patch_len_per_sample).max(1) * self.positions()
    }

    /// im2col of the samples of `x` whose patch rows start at `first_row`, into `band`.
    fn write_patch_rows<T: Real>(&self, x: &[T], first_row: usize, band: &mut [T]) {
        let samples = x[first_row / self.positions() * self.input.len()..].chunks(self.input.len());
        for (patches, sample) in band.chunks_mut(self.patch_len_per_sample).zip(samples) {
            let mut rest = patches;
            for run in &self.patch_runs {
                write_run(rest, *run, sample);
                rest = &mut rest[run.len..];
            }
        }
    }

    /// Accumulates the parameter gradients from `dy` (as `y`) and, when `dx` is given, writes
    /// the input gradient there. `x` is the input of the forward pass, whose patches are
    /// written again band by band.
    pub(crate) fn backward<T: Real>(
        &self,
        grads: &mut [T],
        ws: &mut ConvWorkspace<T>,
        x: &[T],
        dy: ArrayView2<T>,
        dx: Option<&mut [T]>,
    ) {
        backward_sharing_input(grads, x, [(self, ws, dy)], dx);
    }

    /// Adds the gradient of the weight in the GEMM's order, `[out, patch columns]` in `ws`,
    /// to the stored weight's gradient in its own order, and the bias gradient from `dy`.
    fn accumulate_grads<T: Real>(&self, grads: &mut [T], ws: &ConvWorkspace<T>, dy: ArrayView2<T>) {
        let weight_grad = ws
            .weight_grad
            .matrix(self.dense.outputs(), self.dense.inputs());
        let stored = self.dense.weight_slot().of_mut(grads);
        weight_grad
            .t()
            .iter()
            .zip(&self.weight_order)
            .for_each(|(&g, &target)| stored[target] += g);
        self.dense.accumulate_bias_grad(grads, dy);
    }

    /// col2im: the input gradient of whole samples from the gradients of their patches.
    fn add_patch_grads<T: Real>(&self, patch_grads: &[T], dx: &mut [T]) {
        dx.par_chunks_mut(self.input.len())
            .zip(patch_grads.par_chunks(self.patch_len_per_sample))
            .with_min_len(SAMPLES_PER_TASK)
            .for_each(|(sample_dx, sample_patches)| {
                sample_dx.fill(T::zero());
                let mut rest = sample_patches;
                for run in &self.patch_runs {
                    let (grads, tail) = rest.split_at(run.len);
                    if let Some(start) = run.source {
                        let target = &mut sample_dx[start..start + run.len];
                        target.iter_mut().zip(grads).for_each(|(d, &g)| *d += g);
                    }
                    rest = tail;
                }
            });
    }
}

/// Convolutions of one input shape and kernel on the same `x`, each `(layer, workspace,
/// output)` as [`Conv2d::forward`]: the actor's and the critic's first layers read the same
/// observations, so each band of patches is written once and multiplied by every layer's
/// weight. Each output gets the bits of its layer's own forward pass.
pub(crate) fn forward_sharing_input<T: Real, const N: usize>(
    params: &[T],
    x: &[T],
    mut layers: [(&Conv2d, &mut ConvWorkspace<T>, ArrayViewMut2<T>); N],
) {
    let Some(first) = patch_writer(&layers) else {
        return;
    };
    for (layer, ws, y) in &mut layers {
        layer.stage_weight(params, ws);
        layer.dense.fill_with_bias(params, y.view_mut());
    }
    let mut scratch = std::mem::take(&mut layers[0].1.patch_bands);
    let products = layers.each_mut().map(|(layer, ws, y)| {
        let weight = ws
            .weight
            .matrix(layer.dense.inputs(), layer.dense.outputs());
        (weight, y.view_mut())
    });
    matmul_add_banded(
        &mut scratch,
        first.dense.inputs(),
        first.band_rows(),
        products,
        |first_row, band| first.write_patch_rows(x, first_row, band),
    );
    layers[0].1.patch_bands = scratch;
}

/// The first of layers that read their input alike (checked in debug builds), which writes
/// the patches for all of them.
fn patch_writer<'c, T, Y>(layers: &[(&'c Conv2d, &mut ConvWorkspace<T>, Y)]) -> Option<&'c Conv2d> {
    let first = layers.first()?.0;
    debug_assert!(
        layers
            .iter()
            .all(|layer| layer.0.shares_patches_with(first))
    );
    Some(first)
}

/// The backward pass of [`forward_sharing_input`], each `(layer, workspace, dy)` as
/// [`Conv2d::backward`]: the patches of `x` are written again once per band for every layer's
/// weight gradient, and `dx`, when given, gets the input gradient through every layer.
pub(crate) fn backward_sharing_input<T: Real, const N: usize>(
    grads: &mut [T],
    x: &[T],
    mut layers: [(&Conv2d, &mut ConvWorkspace<T>, ArrayView2<T>); N],
    mut dx: Option<&mut [T]>,
) {
    let Some(first) = patch_writer(&layers) else {
        return;
    };
    let (patch_len, positions) = (first.dense.inputs(), first.positions());
    let rows = layers[0].2.nrows();
    let mut scratch = std::mem::take(&mut layers[0].1.patch_bands);
    let staged = layers
        .each_mut()
        .map(|(_, ws, _)| std::mem::take(&mut ws.weight));
    let weights: [ArrayView2<T>; N] =
        std::array::from_fn(|i| staged[i].matrix(patch_len, layers[i].0.dense.outputs()));
    let dys = layers.each_ref().map(|layer| layer.2);
    // Computed as `[out, patch columns]`, then added to each stored weight's gradient in its
    // own order.
    let products = layers.each_mut().map(|(layer, ws, dy)| {
        let weight_grad = ws.weight_grad.matrix_mut(layer.dense.outputs(), patch_len);
        (dy.view(), weight_grad)
    });
    matmul_transposed_banded(
        &mut scratch,
        products,
        (first.band_rows(), positions),
        |first_row, band| first.write_patch_rows(x, first_row, band),
        |first_row, band| {
            let Some(dx) = dx.as_deref_mut() else { return };
            let band_rows = band.len() / patch_len.max(1);
            let mut patch_grads =
                ArrayViewMut2::from_shape((band_rows, patch_len), &mut *band).expect("band shape");
            for (k, (dy, weight)) in dys.iter().zip(&weights).enumerate() {
                let dy = dy.slice(s![first_row..first_row + band_rows, ..]);
                row_band_product(dy, weight.t(), patch_grads.view_mut(), k > 0, rows);
            }
            let (first_sample, samples) = (first_row / positions, band_rows / positions);
            let sample_len = first.input.len();
            first.add_patch_grads(
                band,
                &mut dx[first_sample * sample_len..][..samples * sample_len],
            );
        },
    );
    for ((_, ws, _), weight) in layers.iter_mut().zip(staged) {
        ws.weight = weight;
    }
    layers[0].1.patch_bands = scratch;
    for (layer, ws, dy) in &layers {
        layer.accumulate_grads(grads, ws, *dy);
    }
}

fn output_shape(name: &str, input: ImageShape, spec: ConvSpec) -> Result<ImageShape, NnError> {
    let side = |size: usize| {
        (size + 2 * spec.padding)
            .checked_sub(spec.kernel)
            .map(|room| room / spec.stride + 1)
    };
    if input.is_empty() || spec.out_channels == 0 || spec.kernel == 0 || spec.stride == 0 {
        return Err(NnError::shape(
            name,
            "sizes, kernel and stride must be positive",
        ));
    }
    match (side(input.height), side(input.width)) {
        (Some(height), Some(width)) => Ok(ImageShape {
            channels: spec.out_channels,
            height,
            width,
            order: ChannelOrder::Last,
        }),
        _ => Err(NnError::shape(name, "kernel larger than the padded input")),
    }
}

/// Runs of at most this many values are written as one fixed-size block, whose spill past the
/// run is overwritten by the runs after it. A `memcpy` call per run (16 runs of a kernel row of
/// 8 values per patch row in the paper's first layer) took longer than the layer's product.
const SHORT_RUN: usize = 8;

/// Writes `run` at the front of `target`, which holds the rest of its sample's patches.
fn write_run<T: Real>(target: &mut [T], run: PatchRun, sample: &[T]) {
    if run.len <= SHORT_RUN
        && let Some(block) = target.first_chunk_mut::<SHORT_RUN>()
    {
        match run
            .source
            .map(|start| sample[start..].first_chunk::<SHORT_RUN>())
        {
            Some(Some(values)) => return *block = *values,
            None => return *block = [T::zero(); SHORT_RUN],
            Some(None) => {}
        }
    }
    let target = &mut target[..run.len];
    match run.source {
        Some(start) => target.copy_from_slice(&sample[start..start + run.len]),
        None => target.fill(T::zero()),
    }
}

/// A stretch of a patch matrix: `len` elements copied from the input starting at `source`, or
/// zeros.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct PatchRun {
    source: Option<usize>,
    len: usize,
}

/// A kernel tap: (channel, ky, kx).
type Tap = (usize, usize, usize);

/// The taps in patch column order: the input's memory order, so that consecutive columns read
/// consecutive input elements wherever they can.
fn patch_taps(input: ImageShape, spec: ConvSpec) -> Vec<Tap> {
    let (channels, k) = (input.channels, spec.kernel);
    let mut taps = Vec::with_capacity(channels * k * k);
    match input.order {
        ChannelOrder::First => {
            for c in 0..channels {
                for ky in 0..k {
                    taps.extend((0..k).map(|kx| (c, ky, kx)));
                }
            }
        }
        ChannelOrder::Last => {
            for ky in 0..k {
                for kx in 0..k {
                    taps.extend((0..channels).map(|c| (c, ky, kx)));
                }
            }
        }
    }
    taps
}

/// Elements are merged into a run while both they and their sources are consecutive.
fn patch_runs(
    input: ImageShape,
    output: ImageShape,
    spec: ConvSpec,
    taps: &[Tap],
) -> Vec<PatchRun> {
    let inside = |position: usize, tap: usize, size: usize| {
        (position * spec.stride + tap)
            .checked_sub(spec.padding)
            .filter(|&i| i < size)
    };
    let mut runs: Vec<PatchRun> = Vec::new();
    for oy in 0..output.height {
        for ox in 0..output.width {
            for &(c, ky, kx) in taps {
                let source = inside(oy, ky, input.height)
                    .zip(inside(ox, kx, input.width))
                    .map(|(y, x)| input.offset(c, y, x));
                extend_runs(&mut runs, source);
            }
        }
    }
    runs
}

/// The stored weight's index of each element of the GEMM weight `[taps, out]`.
fn weight_order(input: ImageShape, spec: ConvSpec, taps: &[Tap]) -> Vec<usize> {
    let k = spec.kernel;
    taps.iter()
        .flat_map(|&(c, ky, kx)| {
            (0..spec.out_channels).map(move |o| ((o * input.channels + c) * k + ky) * k + kx)
        })
        .collect()
}

fn extend_runs(runs: &mut Vec<PatchRun>, source: Option<usize>) {
    if let Some(last) = runs.last_mut() {
        let continues = match (last.source, source) {
            (Some(start), Some(next)) => start + last.len == next,
            (None, None) => true,
            _ => false,
        };
        if continues {
            last.len += 1;
            return;
        }
    }
    runs.push(PatchRun { source, len: 1 });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gradient_check::{assert_gradients_match, dot, values_away_from_zero};
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    const SPEC: ConvSpec = ConvSpec {
        out_channels: 3,
        kernel: 3,
        stride: 2,
        padding: 1,
    };

    fn layer(order: ChannelOrder, store: &mut ParamStore<f64>, rng: &mut Pcg64Mcg) -> Conv2d {
        let input = ImageShape {
            channels: 2,
            height: 6,
            width: 5,
            order,
        };
        Conv2d::new(store, "conv", input, SPEC, Init::PyTorchDefault, rng).unwrap()
    }

    fn forward(conv: &Conv2d, params: &[f64], x: &[f64], batch: usize) -> Vec<f64> {
        let out = conv.output_shape();
        let mut y = vec![0.0; batch * out.len()];
        let view = ArrayViewMut2::from_shape((batch * out.height * out.width, 3), &mut y[..]);
        conv.forward(params, x, &mut ConvWorkspace::default(), view.unwrap());
        y
    }

    #[test]
    fn matches_a_direct_convolution_in_both_channel_orders() {
        for order in [ChannelOrder::First, ChannelOrder::Last] {
            let mut rng = Pcg64Mcg::seed_from_u64(20);
            let mut store = ParamStore::new();
            let conv = layer(order, &mut store, &mut rng);
            let x = values_away_from_zero(2 * 60, &mut rng);
            let y = forward(&conv, store.values(), &x, 2);
            let (w, b) = store.values().split_at(3 * 2 * 9);
            let out = conv.output_shape();
            assert_eq!((out.height, out.width), (3, 3));
            for (s, o, oy, ox) in (0..2).flat_map(|s| {
                (0..3).flat_map(move |o| {
                    (0..3).flat_map(move |oy| (0..3).map(move |ox| (s, o, oy, ox)))
                })
            }) {
                let mut expected = b[o];
                for (c, ky, kx) in patch_taps(conv.input_shape(), SPEC) {
                    let (iy, ix) = ((oy * 2 + ky) as isize - 1, (ox * 2 + kx) as isize - 1);
                    if (0..6).contains(&iy) && (0..5).contains(&ix) {
                        let offset = conv.input_shape().offset(c, iy as usize, ix as usize);
                        expected += w[((o * 2 + c) * 3 + ky) * 3 + kx] * x[s * 60 + offset];
                    }
                }
                let got = y[((s * 3 + oy) * 3 + ox) * 3 + o];
                assert!((got - expected).abs() < 1e-12, "{got} vs {expected}");
            }
        }
    }

    /// The paper's first two layers at a batch of many bands: the backward pass, which writes
    /// the patches again band by band, gives the bits of products over the whole patch matrix.
    #[test]
    fn a_backward_pass_by_bands_has_the_bits_of_the_whole_patch_matrix() {
        let mut rng = Pcg64Mcg::seed_from_u64(22);
        let mut store = ParamStore::<f32>::new();
        let paper = crate::model::ModelConfig::paper(crate::model::Architecture::MaPpo, 2);
        let input = paper.observation_shape();
        let init = Init::PyTorchDefault;
        let [first, second, ..] = crate::cnn::PAPER_CONVOLUTIONS;
        let conv = Conv2d::new(&mut store, "c0", input, first, init, &mut rng).unwrap();
        let next = conv.output_shape();
        let conv_last = Conv2d::new(&mut store, "c1", next, second, init, &mut rng).unwrap();
        for (conv, batch) in [(&conv, 47), (&conv_last, 301)] {
            assert!(
                batch * conv.positions() > 2 * conv.band_rows(),
                "several bands"
            );
            let mut draw =
                |len: usize| -> Vec<f32> { (0..len).map(|_| rng.random::<f32>() - 0.5).collect() };
            let x = draw(batch * conv.input.len());
            let rows = batch * conv.positions();
            let outputs = conv.dense.outputs();
            let dy_values = draw(rows * outputs);
            let dy = ArrayView2::from_shape((rows, outputs), &dy_values[..]).unwrap();
            let params = store.values().to_vec();
            let mut ws = ConvWorkspace::default();
            let mut y = vec![0.0; rows * outputs];
            let y_view = ArrayViewMut2::from_shape((rows, outputs), &mut y[..]).unwrap();
            conv.forward(&params, &x, &mut ws, y_view);
            store.zero_grads();
            let mut dx = vec![f32::NAN; x.len()];
            conv.backward(store.grads_mut(), &mut ws, &x, dy, Some(&mut dx));

            let patch_len = conv.dense.inputs();
            let mut patches = vec![0.0; rows * patch_len];
            conv.write_patch_rows(&x, 0, &mut patches);
            let patches = ndarray::Array2::from_shape_vec((rows, patch_len), patches).unwrap();
            let mut weight_grad = ndarray::Array2::zeros((outputs, patch_len));
            crate::matmul::matmul(dy.t(), patches.view(), weight_grad.view_mut());
            let weight = ws.weight.matrix(patch_len, outputs);
            let mut patch_grads = ndarray::Array2::zeros((rows, patch_len));
            crate::matmul::matmul(dy, weight.t(), patch_grads.view_mut());
            let mut whole_dx = vec![0.0; x.len()];
            conv.add_patch_grads(patch_grads.as_slice().unwrap(), &mut whole_dx);

            let stored = conv.dense.weight_slot().of(store.grads());
            let same = |a: f32, b: f32| a.to_bits() == b.to_bits();
            let by_order = weight_grad.t();
            let mut by_order = by_order.iter().zip(&conv.weight_order);
            assert!(by_order.all(|(&g, &at)| same(g, stored[at])));
            assert!(dx.iter().zip(&whole_dx).all(|(&a, &b)| same(a, b)));
        }
    }

    /// The actor's and the critic's first layers, each band of patches shared: every output
    /// and weight gradient has the bits of the layer's own pass, and the input gradient those
    /// of the products over the whole patch matrix.
    #[test]
    fn layers_sharing_their_input_have_the_bits_of_their_own_passes() {
        let mut rng = Pcg64Mcg::seed_from_u64(23);
        let mut store = ParamStore::<f32>::new();
        let paper = crate::model::ModelConfig::paper(crate::model::Architecture::MaPpo, 2);
        let (input, spec) = (paper.observation_shape(), crate::cnn::PAPER_CONVOLUTIONS[0]);
        let init = Init::PyTorchDefault;
        let layers = ["actor", "critic"]
            .map(|name| Conv2d::new(&mut store, name, input, spec, init, &mut rng).unwrap());
        let batch = 47;
        let rows = batch * layers[0].positions();
        let (patch_len, outputs) = (layers[0].dense.inputs(), layers[0].dense.outputs());
        let mut draw =
            |len: usize| -> Vec<f32> { (0..len).map(|_| rng.random::<f32>() - 0.5).collect() };
        let x = draw(batch * input.len());
        let dy_values = [draw(rows * outputs), draw(rows * outputs)];
        let dy = dy_values
            .each_ref()
            .map(|d| ArrayView2::from_shape((rows, outputs), &d[..]).unwrap());
        let params = store.values().to_vec();
        let same = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(a, b)| a.to_bits() == b.to_bits());
        fn matrix(values: &mut [f32], outputs: usize) -> ArrayViewMut2<'_, f32> {
            ArrayViewMut2::from_shape((values.len() / outputs, outputs), values).unwrap()
        }

        let mut alone = [vec![0.0; rows * outputs], vec![0.0; rows * outputs]];
        let mut alone_ws = [ConvWorkspace::default(), ConvWorkspace::default()];
        store.zero_grads();
        for ((layer, ws), (y, dy)) in layers
            .iter()
            .zip(&mut alone_ws)
            .zip(alone.iter_mut().zip(dy))
        {
            layer.forward(&params, &x, ws, matrix(y, outputs));
            layer.backward(store.grads_mut(), ws, &x, dy, None);
        }
        let alone_grads = store.grads().to_vec();

        let mut shared = [vec![0.0; rows * outputs], vec![0.0; rows * outputs]];
        let mut ws = [ConvWorkspace::default(), ConvWorkspace::default()];
        let [y0, y1] = shared.each_mut().map(|y| matrix(y, outputs));
        let [ws0, ws1] = ws.each_mut();
        forward_sharing_input(
            &params,
            &x,
            [(&layers[0], &mut *ws0, y0), (&layers[1], &mut *ws1, y1)],
        );
        store.zero_grads();
        let mut dx = vec![f32::NAN; x.len()];
        let pairs = [(&layers[0], ws0, dy[0]), (&layers[1], ws1, dy[1])];
        backward_sharing_input(store.grads_mut(), &x, pairs, Some(&mut dx));
        assert!(
            alone.iter().zip(&shared).all(|(a, b)| same(a, b)),
            "outputs"
        );
        assert!(
            same(&alone_grads, store.grads()),
            "weight and bias gradients"
        );

        let mut patch_grads = ndarray::Array2::zeros((rows, patch_len));
        for (k, (dy, ws)) in dy.iter().zip(&ws).enumerate() {
            let weight = ws.weight.matrix(patch_len, outputs);
            if k == 0 {
                crate::matmul::matmul(*dy, weight.t(), patch_grads.view_mut());
            } else {
                crate::matmul::matmul_add(*dy, weight.t(), patch_grads.view_mut());
            }
        }
        let mut whole_dx = vec![0.0; x.len()];
        layers[0].add_patch_grads(patch_grads.as_slice().unwrap(), &mut whole_dx);
        assert!(same(&dx, &whole_dx), "input gradient");
    }

    #[test]
    fn gradients_match_finite_differences_in_both_channel_orders() {
        for order in [ChannelOrder::First, ChannelOrder::Last] {
            let mut rng = Pcg64Mcg::seed_from_u64(21);
            let mut store = ParamStore::new();
            let conv = layer(order, &mut store, &mut rng);
            let batch = 3;
            let x = values_away_from_zero(batch * 60, &mut rng);
            let upstream = values_away_from_zero(batch * 27, &mut rng);
            let params = store.values().to_vec();
            let mut ws = ConvWorkspace::default();
            let mut y = vec![0.0; batch * 27];
            let y_view = ArrayViewMut2::from_shape((batch * 9, 3), &mut y[..]).unwrap();
            conv.forward(&params, &x, &mut ws, y_view);
            let dy = ArrayView2::from_shape((batch * 9, 3), &upstream[..]).unwrap();
            let mut dx = vec![0.0; x.len()];
            conv.backward(store.grads_mut(), &mut ws, &x, dy, Some(&mut dx));
            let loss = |p: &[f64], x: &[f64]| dot(&forward(&conv, p, x, batch), &upstream);
            assert_gradients_match(&params, store.grads(), |p| loss(p, &x));
            assert_gradients_match(&x, &dx, |x| loss(&params, x));
        }
    }

    #[test]
    fn the_papers_first_layer_maps_25_to_5() {
        let mut rng = Pcg64Mcg::seed_from_u64(0);
        let input = ImageShape {
            channels: 2,
            height: 25,
            width: 25,
            order: ChannelOrder::First,
        };
        let spec = ConvSpec {
            out_channels: 16,
            kernel: 8,
            stride: 4,
            padding: 1,
        };
        let mut store = ParamStore::<f32>::new();
        let conv = Conv2d::new(&mut store, "c", input, spec, Init::PyTorchDefault, &mut rng);
        assert_eq!(conv.unwrap().output_shape().height, 5);
        let too_big = ConvSpec { kernel: 30, ..spec };
        let conv = Conv2d::new(
            &mut store,
            "d",
            input,
            too_big,
            Init::PyTorchDefault,
            &mut rng,
        );
        assert!(conv.is_err());
    }
}
