//! Value normalisation, as MAPPO's `ValueNorm`: the critic learns returns brought to about
//! zero mean and unit variance by running statistics, so that the value loss, and with it the
//! gradient the critic sends through a joint clip, keeps one scale while the returns drift
//! (from about -26 per cell under a random policy to about -3.6 trained).
//!
//! The statistics are exponential moving averages of the batch mean and the batch mean of
//! squares of the return targets, with MAPPO's debiasing weight (the same average of the
//! constant 1), so that early estimates are not pulled towards the zero they start from:
//!
//! - `m <- beta m + (1 - beta) mean(R)`, `s <- beta s + (1 - beta) mean(R^2)`,
//!   `d <- beta d + (1 - beta)`, once per update, on all the round's raw return targets,
//!   before the epochs (so every minibatch of an update sees one normalisation);
//! - `mu = m / max(d, 1e-5)`, `sigma^2 = max(s / max(d, 1e-5) - mu^2, 1e-2)` (MAPPO's epsilon
//!   and variance floor; before the first update that is mean 0, deviation 0.1).
//!
//! With `beta` near 1 (MAPPO's 0.99999) this is about the mean over every update so far; with
//! `beta = 0` it is the current batch alone. The critic's outputs are de-normalised with the
//! statistics from before the update to compute GAE; the targets are normalised with the
//! statistics after it. Sums are in `f64`, in order, so the statistics are the same bits on
//! every machine, and a checkpoint stores them exactly (as decimal strings, which parse back to
//! the same `f64`).

use serde::{Deserialize, Serialize};

/// MAPPO's guard on the debiasing weight.
const DEBIASING_EPSILON: f64 = 1e-5;
/// MAPPO's floor on the variance: targets are never stretched more than ten times.
const MIN_VARIANCE: f64 = 1e-2;

/// The option: how fast the statistics forget.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValueNormalisation {
    /// The weight of the past in each update of the statistics, in [0, 1).
    pub(crate) beta: f64,
}

/// The running statistics; part of the training state and of its checkpoint.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValueNorm {
    #[serde(with = "exact")]
    mean: f64,
    #[serde(with = "exact")]
    mean_square: f64,
    #[serde(with = "exact")]
    debiasing: f64,
}

impl ValueNorm {
    /// Folds one batch of raw return targets into the statistics.
    pub(crate) fn update(&mut self, beta: f64, returns: &[f32]) {
        if returns.is_empty() {
            return;
        }
        let n = returns.len() as f64;
        let mean = returns.iter().map(|&r| r as f64).sum::<f64>() / n;
        let square = returns.iter().map(|&r| (r as f64).powi(2)).sum::<f64>() / n;
        let blend = |old: f64, new: f64| beta * old + (1.0 - beta) * new;
        self.mean = blend(self.mean, mean);
        self.mean_square = blend(self.mean_square, square);
        self.debiasing = blend(self.debiasing, 1.0);
    }

    /// The debiased mean and standard deviation.
    pub(crate) fn moments(&self) -> (f64, f64) {
        let weight = self.debiasing.max(DEBIASING_EPSILON);
        let mean = self.mean / weight;
        let variance = (self.mean_square / weight - mean * mean).max(MIN_VARIANCE);
        (mean, variance.sqrt())
    }

    /// Raw returns to the critic's scale.
    pub(crate) fn normalise(&self, values: &mut [f32]) {
        let (mean, deviation) = self.moments();
        values
            .iter_mut()
            .for_each(|v| *v = ((*v as f64 - mean) / deviation) as f32);
    }

    /// The critic's outputs back to returns.
    pub(crate) fn denormalise(&self, values: &mut [f32]) {
        let (mean, deviation) = self.moments();
        values
            .iter_mut()
            .for_each(|v| *v = (*v as f64 * deviation + mean) as f32);
    }
}

/// An `f64` as its shortest decimal string: `serde_json` parses numbers only to within an ulp,
/// Rust's `str::parse` exactly, and a resumed run needs the same bits.
mod exact {
    use serde::{Deserialize, Deserializer, Serializer};

    pub(crate) fn serialize<S: Serializer>(value: &f64, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(value)
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
        let text = String::deserialize(deserializer)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9 * b.abs().max(1.0)
    }

    #[test]
    fn statistics_after_known_batches() {
        let mut norm = ValueNorm::default();
        assert_eq!(
            norm.moments(),
            (0.0, 0.1),
            "before any batch: MAPPO's floor"
        );
        // Batch 1: mean 2, mean square 14/3 (1, 2, 3).
        norm.update(0.5, &[1.0, 2.0, 3.0]);
        let (mean, deviation) = norm.moments();
        assert!(close(mean, 2.0), "{mean}");
        assert!(
            close(deviation, (14.0 / 3.0 - 4.0f64).sqrt()),
            "{deviation}"
        );
        // Batch 2: mean 6, mean square 40 (4, 8); weights 0.25 and 0.5, debiased by 0.75.
        norm.update(0.5, &[4.0, 8.0]);
        let (mean, deviation) = norm.moments();
        let expected_mean = (0.25 * 2.0 + 0.5 * 6.0) / 0.75;
        let expected_square = (0.25 * 14.0 / 3.0 + 0.5 * 40.0) / 0.75;
        assert!(close(mean, expected_mean), "{mean}");
        let expected = (expected_square - expected_mean * expected_mean).sqrt();
        assert!(close(deviation, expected), "{deviation}");
        // beta = 0: the last batch alone; a constant batch hits the variance floor.
        norm.update(0.0, &[-3.0, -3.0]);
        assert_eq!(norm.moments(), (-3.0, 0.1));
    }

    #[test]
    fn normalising_and_denormalising_round_trip() {
        let mut norm = ValueNorm::default();
        norm.update(0.99999, &[-26.0, -20.5, -31.25, -24.0]);
        let returns = [-26.0f32, -3.6, 0.0, -40.0];
        let mut values = returns;
        norm.normalise(&mut values);
        let mean = values.iter().map(|&v| v as f64).sum::<f64>() / 4.0;
        assert!(mean.abs() < 5.0, "targets near the critic's scale ({mean})");
        norm.denormalise(&mut values);
        for (v, r) in values.iter().zip(returns) {
            assert!((v - r).abs() < 1e-5 * r.abs().max(1.0), "{v} vs {r}");
        }
    }

    #[test]
    fn statistics_survive_json_bit_for_bit() {
        let mut norm = ValueNorm::default();
        norm.update(0.99999, &[-0.123_456_79, -3.6, 1.0e-7]);
        norm.update(0.99999, &[-26.1, -2.0]);
        let text = serde_json::to_string(&norm).unwrap();
        assert_eq!(serde_json::from_str::<ValueNorm>(&text).unwrap(), norm);
    }
}
