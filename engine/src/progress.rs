//! The sweep's progress on the terminal: a bar per running cell and one for the whole sweep
//! with its ETA, all counted in environment steps (the unit of cost). Hidden when stderr is
//! not a terminal, so logs and tests see only the final report.

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

/// `total_steps` counts only the cells to run, so the ETA is not fooled by finished ones.
pub(crate) struct Progress {
    bars: MultiProgress,
    overall: ProgressBar,
}

impl Progress {
    pub(crate) fn new(total_steps: u64) -> Self {
        let bars = MultiProgress::new();
        let overall = bars.add(ProgressBar::new(total_steps));
        overall.set_style(style(
            "sweep [{bar:30}] {percent:>3}% {elapsed_precise} elapsed, ETA {eta_precise} {msg}",
        ));
        Self { bars, overall }
    }

    /// A bar for a cell that starts now.
    pub(crate) fn start_cell(&self, label: String, steps: u64) -> CellProgress<'_> {
        let bar = self.bars.add(ProgressBar::new(steps));
        bar.set_style(style("  [{bar:20}] {percent:>3}% {msg}"));
        bar.set_message(label);
        CellProgress {
            progress: self,
            bar,
        }
    }

    pub(crate) fn finish(&self) {
        self.overall.finish_and_clear();
    }
}

/// A running cell's bar; it leaves the screen when dropped.
pub(crate) struct CellProgress<'a> {
    progress: &'a Progress,
    bar: ProgressBar,
}

impl CellProgress<'_> {
    pub(crate) fn advance(&self, steps: u64) {
        self.bar.inc(steps);
        self.progress.overall.inc(steps);
    }
}

impl Drop for CellProgress<'_> {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
        self.progress.bars.remove(&self.bar);
    }
}

fn style(template: &str) -> ProgressStyle {
    ProgressStyle::with_template(template)
        .expect("the progress templates are valid")
        .progress_chars("=> ")
}
