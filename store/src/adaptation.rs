//! How a team's per-step penalty answers a disturbance, measured on one test episode: the mean
//! before and after the event, over the last quarter of the episode, and how long it takes to
//! settle. The report divides the last-quarter mean by that of an undisturbed team of the
//! survivors' size (the adaptation ratio).

/// Per-step penalties are averaged over this fraction of the episode (200 steps of 2000)
/// before the settling test. A team on tours sees its per-step penalty swing with the tour:
/// TSPC's 40-step means on `open` vary by 18 % (coefficient of variation), GCS's by 26 %, so a
/// shorter window never settles within 10 %; 200 steps span a tour.
const SETTLE_WINDOW_FRACTION: usize = 10;

/// Within this fraction of the final level counts as settled.
const SETTLE_TOLERANCE: f64 = 0.1;

/// Bins of the per-step penalty curve kept per episode for figures.
pub(crate) const CURVE_BINS: usize = 50;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adaptation {
    /// Mean per-step penalty over steps 1..=event; `None` without an event.
    pub(crate) before: Option<f64>,
    /// Mean per-step penalty over steps event+1..=T; `None` without an event.
    pub(crate) after: Option<f64>,
    /// Mean per-step penalty over the last quarter of the episode: its final level.
    pub(crate) last_quarter: f64,
    /// Steps after the event until the per-step penalty (averaged over T/10 steps) stays
    /// within 10 % of the final level; `None` without an event.
    pub(crate) settle_steps: Option<u32>,
}

impl Adaptation {
    /// `penalties[i]` is the penalty of step i + 1; `event` the step after which robots were
    /// lost.
    pub fn measure(penalties: &[f64], event: Option<u32>) -> Self {
        let steps = penalties.len();
        let quarter = (steps / 4).max(1).min(steps);
        let last_quarter = mean(&penalties[steps - quarter..]);
        let event = event.map(|e| (e as usize).min(steps));
        Self {
            before: event.map(|e| mean(&penalties[..e])),
            after: event.map(|e| mean(&penalties[e..])),
            last_quarter,
            settle_steps: event.map(|e| settle_steps(penalties, e, last_quarter)),
        }
    }
}

/// The first window end from which every window mean after `event` stays within tolerance of
/// `level`, counted in steps after the event.
fn settle_steps(penalties: &[f64], event: usize, level: f64) -> u32 {
    let steps = penalties.len();
    let window = (steps / SETTLE_WINDOW_FRACTION).max(1);
    let tolerance = SETTLE_TOLERANCE * level.abs();
    let first_window = (event + window).min(steps);
    let mut first_settled = first_window;
    let mut sum: f64 = penalties[event..first_window].iter().sum();
    for end in first_window..=steps {
        if end > event + window {
            sum += penalties[end - 1] - penalties[end - 1 - window];
        }
        let width = (end - event).min(window).max(1);
        if (sum / width as f64 - level).abs() > tolerance {
            first_settled = end + 1;
        }
    }
    (first_settled.min(steps) - event) as u32
}

/// The curve of an episode's per-step penalty in `CURVE_BINS` bins: (last step of the bin,
/// mean penalty per step in it).
pub fn curve(penalties: &[f64]) -> impl Iterator<Item = (u32, f64)> + '_ {
    let width = penalties.len().div_ceil(CURVE_BINS).max(1);
    penalties
        .chunks(width)
        .enumerate()
        .map(move |(i, bin)| ((i * width + bin.len()) as u32, mean(bin)))
}

fn mean(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.iter().sum::<f64>() / values.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_change_is_measured_before_after_and_settled_at_once() {
        // 100 steps at 10, then 100 at 20: lost robots at step 100 double the penalty.
        let penalties: Vec<f64> = (0..200)
            .map(|t| if t < 100 { 10.0 } else { 20.0 })
            .collect();
        let a = Adaptation::measure(&penalties, Some(100));
        assert_eq!(
            (a.before, a.after, a.last_quarter),
            (Some(10.0), Some(20.0), 20.0)
        );
        // The window is 20 steps; the first whole window after the event is already at 20.
        assert_eq!(a.settle_steps, Some(20));
        let none = Adaptation::measure(&penalties, None);
        assert_eq!((none.before, none.settle_steps), (None, None));
    }

    #[test]
    fn a_slow_recovery_settles_when_it_stays_within_ten_percent() {
        // After the event the penalty falls linearly from 40 to 10 over 100 steps, then stays.
        let penalties: Vec<f64> = (0..400)
            .map(|t| match t {
                0..100 => 10.0,
                100..200 => 40.0 - 0.3 * (t - 100) as f64,
                _ => 10.0,
            })
            .collect();
        let a = Adaptation::measure(&penalties, Some(100));
        let settled = a.settle_steps.unwrap();
        // Window means within 10 % of 10 need the window (40 steps) to end at step 225.
        assert_eq!(settled, 125);
    }

    #[test]
    fn the_curve_has_fifty_bins_of_means() {
        let penalties: Vec<f64> = (0..2000).map(|t| t as f64).collect();
        let points: Vec<(u32, f64)> = curve(&penalties).collect();
        assert_eq!(points.len(), CURVE_BINS);
        assert_eq!(points[0], (40, 19.5));
        assert_eq!(points[49].0, 2000);
    }
}
