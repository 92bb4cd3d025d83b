//! Fully connected layer `y = x W^T + b` on a whole batch at once (one GEMM). It also holds the
//! convolution's parameters, whose GEMM runs on image patches.

use ndarray::{ArrayView2, ArrayViewMut2, Axis};
use rand::Rng;

use super::error::NnError;
use super::init::Init;
use super::matmul::LANES;
use super::matmul::{matmul, matmul_add};
use super::params::{ParamSlot, ParamStore};
use super::real::Real;

/// A fully connected layer; the weight is stored `[outputs, inputs]` as in PyTorch.
#[derive(Debug, Clone)]
pub(crate) struct Linear {
    inputs: usize,
    outputs: usize,
    weight: ParamSlot,
    bias: ParamSlot,
}

impl Linear {
    /// Allocates `{name}.weight` and `{name}.bias` in `store` and draws them.
    pub(crate) fn new<T: Real, R: Rng + ?Sized>(
        store: &mut ParamStore<T>,
        name: &str,
        inputs: usize,
        outputs: usize,
        init: Init,
        rng: &mut R,
    ) -> Result<Self, NnError> {
        Self::with_weight_shape(store, name, inputs, outputs, &[outputs, inputs], init, rng)
    }

    /// As [`Linear::new`], recording the weight under another shape of the same size (a
    /// convolution's `[out, in, kh, kw]`).
    pub(crate) fn with_weight_shape<T: Real, R: Rng + ?Sized>(
        store: &mut ParamStore<T>,
        name: &str,
        inputs: usize,
        outputs: usize,
        weight_shape: &[usize],
        init: Init,
        rng: &mut R,
    ) -> Result<Self, NnError> {
        if inputs == 0 || outputs == 0 {
            return Err(NnError::shape(name, "inputs and outputs must be positive"));
        }
        let weight = store.allocate(format!("{name}.weight"), weight_shape);
        init.fill_weight(weight.of_mut(store.values_mut()), inputs, rng);
        let bias = store.allocate(format!("{name}.bias"), &[outputs]);
        init.fill_bias(bias.of_mut(store.values_mut()), inputs, rng);
        Ok(Linear {
            inputs,
            outputs,
            weight,
            bias,
        })
    }

    pub(crate) fn inputs(&self) -> usize {
        self.inputs
    }

    pub(crate) fn outputs(&self) -> usize {
        self.outputs
    }

    /// Multiply-adds count twice.
    pub(crate) fn forward_flops_per_row(&self) -> u64 {
        2 * (self.inputs * self.outputs) as u64
    }

    fn weight<'a, T: Real>(&self, flat: &'a [T]) -> ArrayView2<'a, T> {
        ArrayView2::from_shape((self.outputs, self.inputs), self.weight.of(flat))
            .expect("slot holds outputs * inputs values")
    }

    fn weight_mut<'a, T: Real>(&self, flat: &'a mut [T]) -> ArrayViewMut2<'a, T> {
        ArrayViewMut2::from_shape((self.outputs, self.inputs), self.weight.of_mut(flat))
            .expect("slot holds outputs * inputs values")
    }

    /// `y [batch, outputs] = x [batch, inputs] W^T + b`.
    pub(crate) fn forward<T: Real>(&self, params: &[T], x: ArrayView2<T>, mut y: ArrayViewMut2<T>) {
        self.fill_with_bias(params, y.view_mut());
        matmul_add(x, self.weight(params).t(), y);
    }

    /// Writes the bias into every row of `y [batch, outputs]`, for a product to add to.
    pub(crate) fn fill_with_bias<T: Real>(&self, params: &[T], mut y: ArrayViewMut2<T>) {
        let bias = self.bias.of(params);
        match y.as_slice_mut() {
            Some(values) => fill_repeating(values, bias),
            None => y
                .rows_mut()
                .into_iter()
                .for_each(|mut row| row.as_slice_mut().unwrap().copy_from_slice(bias)),
        }
    }

    /// Adds `dy^T x` to the weight gradient and the column sums of `dy` to the bias gradient.
    pub(crate) fn accumulate_param_grads<T: Real>(
        &self,
        grads: &mut [T],
        x: ArrayView2<T>,
        dy: ArrayView2<T>,
    ) {
        matmul_add(dy.t(), x, self.weight_mut(grads));
        self.accumulate_bias_grad(grads, dy);
    }

    /// Adds the column sums of `dy [batch, outputs]` to the bias gradient.
    pub(crate) fn accumulate_bias_grad<T: Real>(&self, grads: &mut [T], dy: ArrayView2<T>) {
        let bias_grad = self.bias.of_mut(grads);
        match dy.as_slice() {
            Some(rows) => add_column_sums(bias_grad, rows),
            None => {
                for row in dy.axis_iter(Axis(0)) {
                    bias_grad.iter_mut().zip(row).for_each(|(g, &d)| *g += d);
                }
            }
        }
    }

    /// Where the weight `[outputs, inputs]` lives in the flat buffers.
    pub(crate) fn weight_slot(&self) -> ParamSlot {
        self.weight
    }

    /// Writes `dx = dy W`.
    pub(crate) fn input_grad<T: Real>(
        &self,
        params: &[T],
        dy: ArrayView2<T>,
        dx: ArrayViewMut2<T>,
    ) {
        matmul(dy, self.weight(params), dx);
    }
}

/// Fills `values` with copies of `pattern` (a bias in every row of a batch): the first copy,
/// then ever larger copies of what is written. A copy per row was a call to `memcpy` per row
/// (100,000 of 16 values for the first convolution of an update's batch).
fn fill_repeating<T: Copy>(values: &mut [T], pattern: &[T]) {
    if pattern.is_empty() {
        return;
    }
    let Some(first) = values.get_mut(..pattern.len()) else {
        return;
    };
    first.copy_from_slice(pattern);
    let mut filled = pattern.len();
    while filled < values.len() {
        let copied = filled.min(values.len() - filled);
        values.copy_within(..copied, filled);
        filled += copied;
    }
}

/// Adds each column of `rows` (row-major, `sums.len()` columns) to its sum, row after row, as
/// adding the rows one by one does, with a block of sums held in registers meanwhile rather
/// than stored and loaded again for every row.
fn add_column_sums<T: Real>(sums: &mut [T], rows: &[T]) {
    let columns = sums.len();
    if columns == 0 {
        return;
    }
    for (block, sums) in sums.chunks_mut(LANES).enumerate() {
        let start = block * LANES;
        let mut block_sums = [T::zero(); LANES];
        block_sums[..sums.len()].copy_from_slice(sums);
        for row in rows.chunks_exact(columns) {
            match row[start..].first_chunk::<LANES>() {
                Some(values) => {
                    for (sum, &value) in block_sums.iter_mut().zip(values) {
                        *sum += value;
                    }
                }
                None => {
                    for (sum, &value) in block_sums.iter_mut().zip(&row[start..]) {
                        *sum += value;
                    }
                }
            }
        }
        sums.copy_from_slice(&block_sums[..sums.len()]);
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
        let mut rng = Pcg64Mcg::seed_from_u64(10);
        let mut store = ParamStore::<f64>::new();
        let layer = Linear::new(&mut store, "fc", 4, 3, Init::PyTorchDefault, &mut rng).unwrap();
        let batch = 5;
        let x = values_away_from_zero(batch * 4, &mut rng);
        let upstream = values_away_from_zero(batch * 3, &mut rng);
        let loss = |params: &[f64], x: &[f64]| {
            let mut y = vec![0.0; batch * 3];
            let x = ArrayView2::from_shape((batch, 4), x).unwrap();
            layer.forward(
                params,
                x,
                ArrayViewMut2::from_shape((batch, 3), &mut y).unwrap(),
            );
            dot(&y, &upstream)
        };
        let params = store.values().to_vec();
        let x_view = ArrayView2::from_shape((batch, 4), &x[..]).unwrap();
        let dy = ArrayView2::from_shape((batch, 3), &upstream[..]).unwrap();
        layer.accumulate_param_grads(store.grads_mut(), x_view, dy);
        let mut dx = vec![0.0; batch * 4];
        layer.input_grad(
            &params,
            dy,
            ArrayViewMut2::from_shape((batch, 4), &mut dx).unwrap(),
        );
        assert_gradients_match(&params, store.grads(), |p| loss(p, &x));
        assert_gradients_match(&x, &dx, |x| loss(&params, x));
    }

    /// Widths below, at and above a block of lanes, and batches of 0, 1 and many rows: the
    /// bias fill and the bias gradient have the bits of their row-by-row definitions.
    #[test]
    fn bias_fill_and_column_sums_have_the_bits_of_row_by_row_loops() {
        use rand::RngExt;
        let mut rng = Pcg64Mcg::seed_from_u64(11);
        for (rows, columns) in [(0, 5), (1, 16), (7, 3), (1000, 16), (333, 21), (50, 1)] {
            let pattern: Vec<f32> = (0..columns).map(|_| rng.random::<f32>() - 0.5).collect();
            let mut filled = vec![f32::NAN; rows * columns];
            fill_repeating(&mut filled, &pattern);
            assert!(
                filled.chunks(columns).all(|row| row == pattern),
                "{rows}x{columns}"
            );

            let values: Vec<f32> = (0..rows * columns)
                .map(|_| rng.random::<f32>() - 0.5)
                .collect();
            let mut by_rows = pattern.clone();
            for row in values.chunks(columns) {
                by_rows.iter_mut().zip(row).for_each(|(s, &v)| *s += v);
            }
            let mut sums = pattern.clone();
            add_column_sums(&mut sums, &values);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&sums), bits(&by_rows), "{rows}x{columns}");
        }
    }

    #[test]
    fn zero_sizes_are_rejected() {
        let mut rng = Pcg64Mcg::seed_from_u64(0);
        let mut store = ParamStore::<f32>::new();
        assert!(Linear::new(&mut store, "fc", 0, 3, Init::PyTorchDefault, &mut rng).is_err());
    }
}
