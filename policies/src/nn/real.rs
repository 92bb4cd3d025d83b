//! The float type the network is generic over: `f32` for training, `f64` for gradient checks
//! tight enough to fail on a wrong derivative.

use std::fmt::Debug;
use std::iter::Sum;
use std::ops::{AddAssign, DivAssign, MulAssign, SubAssign};

use ndarray::LinalgScalar;

use super::matmul::{PackingBuffers, TileKernel};

/// A float the layers compute in.
pub trait Real:
    num_traits::Float
    + LinalgScalar
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + Sum
    + Default
    + Debug
    + Send
    + Sync
    + TileKernel
    + PackingBuffers
    + 'static
{
    /// Rounds a constant or an `f64` draw to this type, so that the same seed gives the same
    /// initial weights (up to rounding) in every precision.
    fn from_f64(value: f64) -> Self;

    /// Widens to `f64`, for reports and norms.
    fn as_f64(self) -> f64;

    /// Converts a count (a batch size, a number of heads) for averaging.
    fn from_count(count: usize) -> Self {
        Self::from_f64(count as f64)
    }

    /// Partial sums of a dot product, one per lane.
    type Lanes: LaneSums<Self>;

    /// `e^self` from the `libm` crate: the C library's `exp` differs between its versions
    /// and between its variants for different CPUs.
    fn exp_portable(self) -> Self;

    /// The natural logarithm from the `libm` crate, for the same reason.
    fn ln_portable(self) -> Self;
}

/// Lanes of [`LaneSums`]: one AVX2 register of `f32`.
pub const LANES: usize = 8;

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

impl Real for f32 {
    fn from_f64(value: f64) -> Self {
        value as f32
    }

    fn as_f64(self) -> f64 {
        f64::from(self)
    }

    type Lanes = wide::f32x8;

    fn exp_portable(self) -> Self {
        libm::expf(self)
    }

    fn ln_portable(self) -> Self {
        libm::logf(self)
    }
}

impl Real for f64 {
    fn from_f64(value: f64) -> Self {
        value
    }

    fn as_f64(self) -> f64 {
        self
    }

    type Lanes = [f64; LANES];

    fn exp_portable(self) -> Self {
        libm::exp(self)
    }

    fn ln_portable(self) -> Self {
        libm::log(self)
    }
}
