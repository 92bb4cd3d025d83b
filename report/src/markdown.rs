//! Tables as Markdown: every column of a frame, numbers to four significant digits, so a
//! reader sees the Parquet table's values (the Parquet file holds them exactly).

use polars::prelude::*;

/// A Markdown table of `frame`; nulls are empty cells.
pub fn table(frame: &DataFrame) -> PolarsResult<String> {
    let names: Vec<String> = frame
        .get_column_names()
        .iter()
        .map(|n| n.to_string())
        .collect();
    let mut text = format!("| {} |\n", names.join(" | "));
    text += &format!("|{}\n", "---|".repeat(names.len()));
    let columns = frame.columns();
    for row in 0..frame.height() {
        let cells: Vec<String> = columns
            .iter()
            .map(|c| c.get(row).map(|v| cell(&v)))
            .collect::<PolarsResult<_>>()?;
        text += &format!("| {} |\n", cells.join(" | "));
    }
    Ok(text)
}

/// A cell's text; a `|` in it (a claim's "|N_train - N_test|") is escaped, or it would end
/// the cell and shift the rest of the row.
fn cell(value: &AnyValue) -> String {
    let text = match value {
        AnyValue::Null => String::new(),
        AnyValue::Float64(v) => number(*v),
        AnyValue::Float32(v) => number(*v as f64),
        AnyValue::String(s) => s.to_string(),
        AnyValue::StringOwned(s) => s.to_string(),
        other => other.to_string(),
    };
    text.replace('|', "\\|")
}

/// Four significant digits; scientific notation for very large or small magnitudes.
pub fn number(value: f64) -> String {
    if value == 0.0 || !value.is_finite() {
        return format!("{value}");
    }
    let magnitude = value.abs().log10().floor() as i32;
    if !(-3..6).contains(&magnitude) {
        return format!("{value:.3e}");
    }
    let decimals = (3 - magnitude).max(0) as usize;
    format!("{value:.decimals$}")
}

/// A 95 % interval as "[low, high]", each bound written by `show`; "[no interval]" where a
/// bound is not finite (one training run has no spread to draw from), never "[-inf, inf]".
pub fn interval(low: f64, high: f64, show: impl Fn(f64) -> String) -> String {
    if low.is_finite() && high.is_finite() {
        format!("[{}, {}]", show(low), show(high))
    } else {
        "[no interval]".to_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_interval_without_finite_bounds_says_so() {
        assert_eq!(interval(-1.5, 2.25, number), "[-1.500, 2.250]");
        assert_eq!(interval(0.1, 0.9, |v| format!("{v:.2}")), "[0.10, 0.90]");
        assert_eq!(
            interval(f64::NEG_INFINITY, f64::INFINITY, number),
            "[no interval]"
        );
        assert_eq!(interval(f64::NAN, 1.0, number), "[no interval]");
    }

    #[test]
    fn numbers_keep_four_significant_digits() {
        assert_eq!(number(0.0), "0");
        assert_eq!(number(44.04), "44.04");
        assert_eq!(number(0.12346), "0.1235");
        assert_eq!(number(-313.66), "-313.7");
        assert_eq!(number(12345.0), "12345");
        assert_eq!(number(2.5e7), "2.500e7");
        assert_eq!(number(1.0e-5), "1.000e-5");
    }

    #[test]
    fn frames_become_pipe_tables() {
        let frame = df!(
            "policy" => ["gcs", "a|b"],
            "n_train" => [None, Some(4u32)],
            "mean" => [1.5, 20.25],
        )
        .unwrap();
        assert_eq!(
            table(&frame).unwrap(),
            "| policy | n_train | mean |\n|---|---|---|\n| gcs |  | 1.500 |\n| a\\|b | 4 | 20.25 |\n"
        );
    }
}
