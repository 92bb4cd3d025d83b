//! The lanes of a dot product: `LANES` running sums kept apart and added at the end, the same
//! bits with a vector unit as without.

/// Lanes of [`LaneSums`]: one AVX2 register of `f32`.
pub(crate) const LANES: usize = 8;

/// `LANES` running sums of products, the product rounded before the sum as in scalar code, so
/// a vector unit gives the same bits as none.
pub trait LaneSums<T>: Copy {
    fn zero() -> Self;
    fn add_products(self, x: &[T; LANES], y: &[T; LANES]) -> Self;
    fn to_array(self) -> [T; LANES];
}

/// The compiler does not turn the scalar loop into vector instructions by itself.
impl LaneSums<f32> for wide::f32x8 {
    #[inline(always)]
    fn zero() -> Self {
        wide::f32x8::ZERO
    }

    #[inline(always)]
    fn add_products(self, x: &[f32; LANES], y: &[f32; LANES]) -> Self {
        self + wide::f32x8::from(*x) * wide::f32x8::from(*y)
    }

    #[inline(always)]
    fn to_array(self) -> [f32; LANES] {
        wide::f32x8::to_array(self)
    }
}

/// `f64` runs in gradient checks only, where speed does not matter.
impl LaneSums<f64> for [f64; LANES] {
    fn zero() -> Self {
        [0.0; LANES]
    }

    fn add_products(mut self, x: &[f64; LANES], y: &[f64; LANES]) -> Self {
        for l in 0..LANES {
            self[l] += x[l] * y[l];
        }
        self
    }

    fn to_array(self) -> [f64; LANES] {
        self
    }
}
