//! Activation and scratch storage that grows to the largest batch seen and is then reused, so
//! that warmed-up forward and backward passes allocate nothing.

use ndarray::{ArrayView2, ArrayViewMut2};

/// A vector that only grows; views of any smaller size are taken from its front.
#[derive(Debug, Clone, Default)]
pub(crate) struct ReusableBuffer<T> {
    data: Vec<T>,
}

impl<T: Copy + num_traits::Zero> ReusableBuffer<T> {
    /// The first `len` elements, growing the buffer (with zeros) when it is shorter.
    pub(crate) fn slice_mut(&mut self, len: usize) -> &mut [T] {
        if self.data.len() < len {
            self.data.resize(len, T::zero());
        }
        &mut self.data[..len]
    }

    /// The first `len` elements, as last written.
    pub(crate) fn slice(&self, len: usize) -> &[T] {
        &self.data[..len]
    }

    /// The front as a row-major `rows x cols` matrix.
    pub(crate) fn matrix(&self, rows: usize, cols: usize) -> ArrayView2<'_, T> {
        ArrayView2::from_shape((rows, cols), self.slice(rows * cols))
            .expect("length equals rows * cols")
    }

    /// The front as a writable row-major `rows x cols` matrix, growing the buffer if needed.
    pub(crate) fn matrix_mut(&mut self, rows: usize, cols: usize) -> ArrayViewMut2<'_, T> {
        ArrayViewMut2::from_shape((rows, cols), self.slice_mut(rows * cols))
            .expect("length equals rows * cols")
    }
}

/// The two gradient buffers of a backward pass through a stack of layers: the gradient of
/// layer k's output lives in buffer k % 2, and layer k writes its input gradient (the output
/// gradient of layer k - 1) into the other one.
#[derive(Debug, Clone, Default)]
pub(crate) struct AlternatingBuffers<T> {
    buffers: [ReusableBuffer<T>; 2],
}

impl<T> AlternatingBuffers<T> {
    /// Where the gradient of layer `layer`'s output goes.
    pub(crate) fn output_grad_mut(&mut self, layer: usize) -> &mut ReusableBuffer<T> {
        &mut self.buffers[layer % 2]
    }

    /// Layer `layer`'s output gradient, and the buffer for its input gradient.
    pub(crate) fn output_and_input_grads(
        &mut self,
        layer: usize,
    ) -> (&ReusableBuffer<T>, &mut ReusableBuffer<T>) {
        let [even, odd] = &mut self.buffers;
        if layer.is_multiple_of(2) {
            (even, odd)
        } else {
            (odd, even)
        }
    }
}
