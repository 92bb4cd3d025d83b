//! A claim over several points is contradicted only when the family of its points is:
//! Holm's step-down procedure (Holm 1979) keeps the chance of calling any true point
//! contradicted at most `alpha`, whatever the points' dependence, and rejects at least as
//! much as Bonferroni. (Support needs no correction: a claim is supported only when every
//! point is, an intersection-union test at the points' own level.)

/// Which of the hypotheses with these p-values Holm's procedure rejects at family-wise level
/// `alpha`: sorted ascending, the j-th smallest (from 0) is rejected while every p-value up
/// to it is at most `alpha / (k - j)`.
pub fn holm(p_values: &[f64], alpha: f64) -> Vec<bool> {
    let k = p_values.len();
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|&a, &b| p_values[a].total_cmp(&p_values[b]));
    let mut rejected = vec![false; k];
    for (step, &index) in order.iter().enumerate() {
        if p_values[index] > alpha / (k - step) as f64 {
            break;
        }
        rejected[index] = true;
    }
    rejected
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holm_steps_down_and_stops_at_the_first_failure() {
        // k = 4 at 0.05: thresholds 0.0125, 0.0167, 0.025, 0.05 for the sorted p-values.
        assert_eq!(
            holm(&[0.01, 0.04, 0.03, 0.005], 0.05),
            [true, false, false, true]
        );
        assert_eq!(holm(&[0.01, 0.016, 0.024, 0.04], 0.05), [true; 4]);
        // 0.02 alone passes an uncorrected test, but not among 12 points.
        let mut twelve = vec![0.5; 12];
        twelve[3] = 0.02;
        assert_eq!(holm(&twelve, 0.05), [false; 12]);
        assert_eq!(holm(&[0.02], 0.05), [true]);
        assert!(holm(&[], 0.05).is_empty());
    }
}
