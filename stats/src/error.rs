//! Why a statistic cannot be computed, and the check every statistic's input passes first: a
//! leaf below the root and the resampling, which both use them.

use thiserror::Error;

#[derive(Debug, Clone, PartialEq, Error)]
pub enum StatsError {
    #[error("no values to summarise")]
    Empty,
    #[error("confidence must be strictly between 0 and 1, got {0}")]
    Confidence(f64),
    #[error("a bootstrap needs at least one resample")]
    NoResamples,
    #[error("paired samples must hold the same runs (and episodes) in the same order")]
    Unpaired,
    #[error("{successes} of {trials} is not a count of some of a number of trials")]
    Count { successes: f64, trials: f64 },
    #[error("value {index} is {value}, not a finite number")]
    NotFinite { index: usize, value: f64 },
}

/// Refuses no values, or a value that is not a finite number (naming it).
pub(crate) fn check(values: &[f64]) -> Result<(), StatsError> {
    if values.is_empty() {
        return Err(StatsError::Empty);
    }
    match values.iter().position(|value| !value.is_finite()) {
        Some(index) => Err(StatsError::NotFinite {
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}
