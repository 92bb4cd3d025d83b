//! Value axes: linear, or logarithmic where the values shown span more than two decades. On a
//! linear axis such values leave the small ones flat on the floor: four_room's penalties at
//! N = 2 are hundreds of times those at N = 6, whose bars did not show.

use std::ops::Range;

use super::padded_range;

/// Decades the shown values must span before the axis turns logarithmic.
const LOG_DECADES: f64 = 2.0;

/// Whether `values` are all positive and span more than [`LOG_DECADES`] decades.
fn spans_decades(values: impl IntoIterator<Item = f64>) -> bool {
    let finite = values.into_iter().filter(|v| v.is_finite());
    let (low, high) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
        (l.min(v), h.max(v))
    });
    low > 0.0 && (high / low).log10() > LOG_DECADES
}

/// Ticks for a log axis from `low` to `high`: powers of ten and their 2 and 5 multiples,
/// or every multiple 1 to 9 where those give fewer than three (an axis from 53 to 153
/// would have had the one tick 100); the ends where even those give fewer than two.
pub(crate) fn log_ticks(low: f64, high: f64) -> Vec<f64> {
    let within = |multiples: &[f64]| -> Vec<f64> {
        let (first, last) = (low.log10().floor() as i32, high.log10().ceil() as i32);
        let candidates =
            (first..=last).flat_map(|e| multiples.iter().map(move |m| m * 10f64.powi(e)));
        candidates.filter(|t| (low..=high).contains(t)).collect()
    };
    let coarse = within(&[1.0, 2.0, 5.0]);
    if coarse.len() >= 3 {
        return coarse;
    }
    let fine = within(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    match fine.len() >= 2 {
        true => fine,
        false => vec![low, high],
    }
}

/// A value axis: its range and whether it is logarithmic.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ValueAxis {
    pub(crate) range: Range<f64>,
    pub(crate) log: bool,
}

impl ValueAxis {
    /// The axis for `shown` (the values that decide the scale: means, curves) that also holds
    /// `reach` (interval and band edges) where it can: a log axis cannot reach 0 or below, so
    /// those edges are cut at its floor. A linear axis starts at 0 when `from_zero` (bars).
    pub(crate) fn fit(shown: &[f64], reach: &[f64], from_zero: bool) -> Self {
        let all = || shown.iter().chain(reach).copied();
        if !spans_decades(shown.iter().copied()) {
            return Self {
                range: padded_range(all(), from_zero),
                log: false,
            };
        }
        let positive = all().filter(|v| *v > 0.0 && v.is_finite());
        let (low, high) = positive.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(v), h.max(v))
        });
        // A twentieth of the span on either side, as the linear axes have.
        let margin = (high / low).powf(0.05);
        Self {
            range: low / margin..high * margin,
            log: true,
        }
    }

    /// The ticks of a log axis (see [`log_ticks`]).
    pub(crate) fn log_ticks(&self) -> Vec<f64> {
        log_ticks(self.range.start, self.range.end)
    }

    /// Where a bar starts: 0, or the floor of a log axis.
    pub(crate) fn base(&self) -> f64 {
        if self.log { self.range.start } else { 0.0 }
    }

    /// `value` as drawn: on a log axis, cut at the floor; an unbounded value at the axis'
    /// edge.
    pub(crate) fn clamp(&self, value: f64) -> f64 {
        match (self.log, value.is_finite()) {
            (false, true) => value,
            _ => value.clamp(self.range.start, self.range.end),
        }
    }

    /// An axis description that says when the scale is logarithmic.
    pub(crate) fn describe(&self, label: &str) -> String {
        if self.log {
            format!("{label}, log scale")
        } else {
            label.to_owned()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_positive_values_over_two_decades_go_on_a_log_axis() {
        assert!(spans_decades([0.5, 3.0, 120.0]), "2.4 decades");
        assert!(
            !spans_decades([1.0, 100.0]),
            "exactly two decades stay linear"
        );
        assert!(
            !spans_decades([0.0, 1.0, 1000.0]),
            "a zero has no logarithm"
        );
        assert!(!spans_decades([-5.0, 1000.0]));
        assert!(!spans_decades([]), "nothing to span");
        assert!(spans_decades([f64::NAN, 0.01, 5.0]), "NaN is not shown");
    }

    #[test]
    fn a_log_axis_has_at_least_two_ticks() {
        assert_eq!(
            log_ticks(8.0, 600.0),
            [10.0, 20.0, 50.0, 100.0, 200.0, 500.0]
        );
        assert_eq!(log_ticks(53.0, 153.0), [60.0, 70.0, 80.0, 90.0, 100.0]);
        assert_eq!(log_ticks(53.0, 58.0), [53.0, 58.0]);
    }

    #[test]
    fn a_log_axis_holds_every_positive_value_and_cuts_the_rest() {
        let axis = ValueAxis::fit(&[0.2, 40.0], &[0.1, -3.0, 80.0], true);
        assert!(axis.log);
        assert!(axis.range.start < 0.1 && axis.range.start > 0.0);
        assert!(axis.range.end > 80.0);
        assert_eq!(axis.base(), axis.range.start, "bars rise from the floor");
        assert_eq!(axis.clamp(-3.0), axis.range.start);
        assert_eq!(axis.describe("penalty"), "penalty, log scale");
    }

    #[test]
    fn a_narrow_span_keeps_a_linear_axis_from_zero() {
        let axis = ValueAxis::fit(&[2.0, 40.0], &[1.0, 45.0], true);
        assert!(!axis.log);
        assert_eq!(axis.range.start, 0.0);
        assert_eq!((axis.base(), axis.clamp(-1.0)), (0.0, -1.0));
        assert_eq!(axis.clamp(f64::INFINITY), axis.range.end);
        assert_eq!(axis.describe("penalty"), "penalty");
    }
}
