//! Rectifiers, applied in place. ReLU is the leaky rectifier with slope 0. For any slope >= 0
//! the output has the sign of the input, so backward needs only the output and activations
//! need not be stored twice.

use super::real::Real;

/// `max(x, 0) + slope * min(x, 0)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LeakyRelu {
    pub(crate) negative_slope: f64,
}

/// The plain rectifier.
pub(crate) const RELU: LeakyRelu = LeakyRelu {
    negative_slope: 0.0,
};

impl LeakyRelu {
    pub(crate) fn apply<T: Real>(self, x: T) -> T {
        if x > T::zero() {
            x
        } else {
            x * T::from_f64(self.negative_slope)
        }
    }

    /// The derivative at the input that produced `output`.
    pub(crate) fn derivative_at_output<T: Real>(self, output: T) -> T {
        if output > T::zero() {
            T::one()
        } else {
            T::from_f64(self.negative_slope)
        }
    }

    pub(crate) fn forward_in_place<T: Real>(self, values: &mut [T]) {
        values.iter_mut().for_each(|v| *v = self.apply(*v));
    }

    /// Turns the gradient with respect to the outputs into the gradient with respect to the
    /// inputs.
    pub(crate) fn backward_in_place<T: Real>(self, outputs: &[T], grads: &mut [T]) {
        grads
            .iter_mut()
            .zip(outputs)
            .for_each(|(g, &y)| *g *= self.derivative_at_output(y));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gradient_check::assert_gradients_match;

    #[test]
    fn leaky_relu_gradient_matches_finite_differences() {
        let activation = LeakyRelu {
            negative_slope: 0.2,
        };
        let input = [-1.5, -0.3, 0.4, 2.0, -0.7];
        let weights = [0.3, -1.1, 0.8, 0.5, 1.7];
        let loss = |x: &[f64]| {
            let mut y = x.to_vec();
            activation.forward_in_place(&mut y);
            y.iter().zip(&weights).map(|(a, b)| a * b).sum::<f64>()
        };
        let mut output = input.to_vec();
        activation.forward_in_place(&mut output);
        let mut grads = weights.to_vec();
        activation.backward_in_place(&output, &mut grads);
        assert_gradients_match(&input, &grads, loss);
    }

    #[test]
    fn relu_zeroes_negatives() {
        let mut v = [-1.0f32, 2.0];
        RELU.forward_in_place(&mut v);
        assert_eq!(v, [0.0, 2.0]);
    }
}
