//! Returns and advantages of one episode. The reward is shared by the team, so Monte-Carlo
//! returns are one per step; values (and so GAE advantages) are one per agent and step, laid
//! out `[step][agent]`.

/// `returns[t] = rewards[t] + gamma * returns[t + 1]`, zero after the last step (the released
/// code treats the episode's end as terminal).
pub(crate) fn discounted_returns(rewards: &[f32], gamma: f64, returns: &mut [f32]) {
    let mut running = 0.0f64;
    for (r, out) in rewards.iter().zip(returns.iter_mut()).rev() {
        running = *r as f64 + gamma * running;
        *out = running as f32;
    }
}

/// Generalised advantage estimation for `agents` agents sharing `rewards` (one per step);
/// `values` holds `rewards.len() + 1` steps of values, the last one bootstrapping the state
/// after the final step. Writes `[step][agent]` advantages.
pub(crate) fn gae(
    rewards: &[f32],
    values: &[f32],
    agents: usize,
    gamma: f64,
    lambda: f64,
    advantages: &mut [f32],
) {
    debug_assert_eq!(values.len(), (rewards.len() + 1) * agents);
    for agent in 0..agents {
        let mut running = 0.0f64;
        for (t, &r) in rewards.iter().enumerate().rev() {
            let value = values[t * agents + agent] as f64;
            let next = values[(t + 1) * agents + agent] as f64;
            let delta = r as f64 + gamma * next - value;
            running = delta + gamma * lambda * running;
            advantages[t * agents + agent] = running as f32;
        }
    }
}

/// To zero mean and unit standard deviation, as PyTorch's `(x - x.mean()) / (x.std() + 1e-5)`
/// (unbiased standard deviation), summed in `f64`.
pub(crate) fn normalise(values: &mut [f32]) {
    let n = values.len();
    if n < 2 {
        return;
    }
    let mean = values.iter().map(|&v| v as f64).sum::<f64>() / n as f64;
    let variance = values
        .iter()
        .map(|&v| (v as f64 - mean).powi(2))
        .sum::<f64>()
        / (n - 1) as f64;
    let scale = 1.0 / (variance.sqrt() + 1e-5);
    for v in values {
        *v = ((*v as f64 - mean) * scale) as f32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn monte_carlo_returns_by_hand() {
        let mut returns = [0.0; 3];
        discounted_returns(&[-1.0, -2.0, -4.0], 0.5, &mut returns);
        // -4; -2 + 0.5 * -4 = -4; -1 + 0.5 * -4 = -3
        assert_eq!(returns, [-3.0, -4.0, -4.0]);
    }

    #[test]
    fn gae_by_hand() {
        // Two steps, two agents; values [step][agent] with a bootstrap row.
        let rewards = [-1.0, -2.0];
        let values = [0.5, -1.0, 1.0, 0.0, -2.0, 4.0];
        let mut advantages = [0.0; 4];
        gae(&rewards, &values, 2, 0.5, 0.5, &mut advantages);
        // Agent 0: delta1 = -2 + 0.5 * -2 - 1 = -4; delta0 = -1 + 0.5 * 1 - 0.5 = -1;
        // A1 = -4, A0 = -1 + 0.25 * -4 = -2.
        // Agent 1: delta1 = -2 + 0.5 * 4 - 0 = 0; delta0 = -1 + 0.5 * 0 + 1 = 0; A = 0, 0.
        assert_eq!(advantages, [-2.0, 0.0, -4.0, 0.0]);
        // lambda = 1 and a zero bootstrap give Monte-Carlo returns minus values.
        let values = [0.5, -1.0, 1.0, 0.0, 0.0, 0.0];
        gae(&rewards, &values, 2, 0.5, 1.0, &mut advantages);
        let mut returns = [0.0; 2];
        discounted_returns(&rewards, 0.5, &mut returns);
        for t in 0..2 {
            for agent in 0..2 {
                let expected = returns[t] - values[t * 2 + agent];
                assert_eq!(advantages[t * 2 + agent], expected);
            }
        }
    }

    #[test]
    fn normalisation_follows_pytorch() {
        let mut values = [1.0, 2.0, 3.0];
        normalise(&mut values);
        // mean 2, unbiased std 1.
        let expected = [-1.0 / (1.0 + 1e-5), 0.0, 1.0 / (1.0 + 1e-5)];
        for (v, e) in values.iter().zip(expected) {
            assert!((*v as f64 - e).abs() < 1e-7, "{v} vs {e}");
        }
    }
}
