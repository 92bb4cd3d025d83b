//! The mean and the sample standard deviation, which the crate's root and `power` both use:
//! a module below them, so neither imports the other.

use crate::error::{StatsError, check};

pub fn mean(values: &[f64]) -> Result<f64, StatsError> {
    check(values)?;
    Ok(values.iter().sum::<f64>() / values.len() as f64)
}

/// The sample standard deviation (divisor n - 1); 0 for a single value.
pub fn standard_deviation(values: &[f64]) -> Result<f64, StatsError> {
    let centre = mean(values)?;
    if values.len() == 1 {
        return Ok(0.0);
    }
    let squares: f64 = values.iter().map(|v| (v - centre).powi(2)).sum();
    Ok((squares / (values.len() - 1) as f64).sqrt())
}
