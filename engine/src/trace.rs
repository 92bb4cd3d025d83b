//! The per-step trace of an episode as CSV: t, reward, then x, y and action of every agent.

use std::fmt::Write;

use world::{Action, Episode};

/// Collects trace rows in memory; write the text out with `atomic_file::write_atomic`.
pub struct Trace {
    text: String,
}

impl Trace {
    pub fn new(agents: usize) -> Self {
        let mut text = String::from("t,reward");
        for i in 0..agents {
            write!(text, ",x{i},y{i},a{i}").expect("writing to a String");
        }
        text.push('\n');
        Self { text }
    }

    /// Appends the row of the step just taken; step 0 has no actions and leaves them empty.
    pub fn record(&mut self, episode: &Episode, actions: Option<&[Action]>) {
        write!(self.text, "{},{}", episode.time(), episode.reward()).expect("writing to a String");
        for (i, p) in episode.positions().iter().enumerate() {
            let action = actions
                .map(|a| a[i].index().to_string())
                .unwrap_or_default();
            write!(self.text, ",{},{},{action}", p.x, p.y).expect("writing to a String");
        }
        self.text.push('\n');
    }

    pub fn into_text(self) -> String {
        self.text
    }
}
