//! One flat buffer for every parameter of a model and one for every gradient, so that the
//! optimiser, gradient clipping and checkpointing each work on a single slice. Layers keep only
//! [`ParamSlot`]s (offsets) into these buffers.

use super::real::Real;

/// Where one parameter tensor lives in the flat buffers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParamSlot {
    offset: usize,
    len: usize,
}

impl ParamSlot {
    /// This tensor's part of a flat buffer (values or gradients).
    pub fn of<'a, T>(&self, flat: &'a [T]) -> &'a [T] {
        &flat[self.offset..self.offset + self.len]
    }

    /// This tensor's part of a flat buffer, writable.
    pub fn of_mut<'a, T>(&self, flat: &'a mut [T]) -> &'a mut [T] {
        &mut flat[self.offset..self.offset + self.len]
    }

    /// The positions of this tensor in the flat buffers.
    #[cfg(test)]
    pub(crate) fn range(&self) -> std::ops::Range<usize> {
        self.offset..self.offset + self.len
    }

    #[cfg(test)]
    fn len(&self) -> usize {
        self.len
    }
}

/// The name and shape of one parameter tensor, for checkpoints (shapes follow PyTorch:
/// linear weights `[out, in]`, convolution weights `[out, in, kh, kw]`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParamSpec {
    pub name: String,
    pub shape: Vec<usize>,
    pub slot: ParamSlot,
}

/// All parameters of a model, their gradients, and the names and shapes of their tensors.
#[derive(Debug, Clone, Default)]
pub struct ParamStore<T> {
    values: Vec<T>,
    grads: Vec<T>,
    specs: Vec<ParamSpec>,
}

impl<T: Real> ParamStore<T> {
    pub(crate) fn new() -> Self {
        ParamStore {
            values: Vec::new(),
            grads: Vec::new(),
            specs: Vec::new(),
        }
    }

    /// Appends a zero tensor and its zero gradient; layers call this while they are built.
    pub(crate) fn allocate(&mut self, name: String, shape: &[usize]) -> ParamSlot {
        let slot = ParamSlot {
            offset: self.values.len(),
            len: shape.iter().product(),
        };
        self.values.resize(slot.offset + slot.len, T::zero());
        self.grads.resize(slot.offset + slot.len, T::zero());
        self.specs.push(ParamSpec {
            name,
            shape: shape.to_vec(),
            slot,
        });
        slot
    }

    /// The number of scalar parameters.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    pub fn specs(&self) -> &[ParamSpec] {
        &self.specs
    }

    pub fn values(&self) -> &[T] {
        &self.values
    }

    pub fn values_mut(&mut self) -> &mut [T] {
        &mut self.values
    }

    pub fn grads(&self) -> &[T] {
        &self.grads
    }

    #[cfg(test)]
    pub(crate) fn grads_mut(&mut self) -> &mut [T] {
        &mut self.grads
    }

    /// Values to read and gradients to accumulate into, as a backward pass needs them.
    pub(crate) fn values_and_grads_mut(&mut self) -> (&[T], &mut [T]) {
        (&self.values, &mut self.grads)
    }

    /// Values to update and gradients to read, as an optimiser step needs them.
    pub fn values_mut_and_grads(&mut self) -> (&mut [T], &[T]) {
        (&mut self.values, &self.grads)
    }

    /// Backward passes accumulate, so every update starts here.
    pub fn zero_grads(&mut self) {
        self.grads.fill(T::zero());
    }

    /// The global L2 norm of all gradients (summed in `f64`, in a fixed order).
    pub fn grad_norm(&self) -> f64 {
        norm_of(&self.grads)
    }

    /// Scales all gradients so that their global norm is at most `max_norm` (as PyTorch's
    /// `clip_grad_norm_`), and returns the norm before clipping.
    pub fn clip_grad_norm(&mut self, max_norm: f64) -> f64 {
        clip_to_norm(&mut self.grads, max_norm)
    }

    /// [`ParamStore::clip_grad_norm`] on the gradients at `range` alone (one network of
    /// several in the store), so that one network's large gradients cannot shrink another's
    /// step; returns that part's norm before clipping.
    pub fn clip_grad_norm_of(&mut self, range: std::ops::Range<usize>, max_norm: f64) -> f64 {
        clip_to_norm(&mut self.grads[range], max_norm)
    }
}

/// The L2 norm of `grads`, summed in `f64` in order.
fn norm_of<T: Real>(grads: &[T]) -> f64 {
    grads
        .iter()
        .map(|g| g.as_f64() * g.as_f64())
        .sum::<f64>()
        .sqrt()
}

/// Scales `grads` to norm at most `max_norm` (PyTorch's `1e-6` guard); returns the norm before.
fn clip_to_norm<T: Real>(grads: &mut [T], max_norm: f64) -> f64 {
    let norm = norm_of(grads);
    let scale = max_norm / (norm + 1e-6);
    if scale < 1.0 {
        let scale = T::from_f64(scale);
        grads.iter_mut().for_each(|g| *g *= scale);
    }
    norm
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tensors_are_laid_out_back_to_back() {
        let mut store = ParamStore::<f32>::new();
        let a = store.allocate("a".into(), &[2, 3]);
        let b = store.allocate("b".into(), &[4]);
        assert_eq!(store.len(), 10);
        store.values_mut()[6] = 1.0;
        assert_eq!(b.of(store.values()), &[1.0, 0.0, 0.0, 0.0]);
        assert_eq!(a.len(), 6);
        assert_eq!(store.specs()[1].shape, vec![4]);
    }

    #[test]
    fn clipping_bounds_the_global_norm() {
        let mut store = ParamStore::<f64>::new();
        store.allocate("w".into(), &[2]);
        store.grads_mut().copy_from_slice(&[3.0, 4.0]);
        assert_eq!(store.clip_grad_norm(10.0), 5.0);
        assert_eq!(store.grads(), &[3.0, 4.0]);
        store.clip_grad_norm(1.0);
        assert!((store.grad_norm() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn clipping_a_range_bounds_its_norm_and_leaves_the_rest() {
        let mut store = ParamStore::<f64>::new();
        store.allocate("actor".into(), &[2]);
        store.allocate("critic".into(), &[2]);
        store.grads_mut().copy_from_slice(&[0.3, 0.4, 30.0, 40.0]);
        assert_eq!(store.clip_grad_norm_of(0..2, 10.0), 0.5);
        assert_eq!(
            &store.grads()[..2],
            &[0.3, 0.4],
            "a norm under the bound is kept"
        );
        assert_eq!(store.clip_grad_norm_of(2..4, 10.0), 50.0);
        assert!((norm_of(&store.grads()[2..]) - 10.0).abs() < 1e-6);
        assert_eq!(&store.grads()[..2], &[0.3, 0.4]);
    }
}
