//! The float type the network is generic over: `f32` for training, `f64` for gradient checks
//! tight enough to fail on a wrong derivative.

use std::fmt::Debug;
use std::iter::Sum;
use std::ops::{AddAssign, DivAssign, MulAssign, SubAssign};

use ndarray::LinalgScalar;

use super::matmul::Scalar;

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
    + Scalar
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

    /// `e^self` from the `libm` crate: the C library's `exp` differs between its versions
    /// and between its variants for different CPUs.
    fn exp_portable(self) -> Self;

    /// The natural logarithm from the `libm` crate, for the same reason.
    fn ln_portable(self) -> Self;
}

impl Real for f32 {
    fn from_f64(value: f64) -> Self {
        value as f32
    }

    fn as_f64(self) -> f64 {
        f64::from(self)
    }

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

    fn exp_portable(self) -> Self {
        libm::exp(self)
    }

    fn ln_portable(self) -> Self {
        libm::log(self)
    }
}
