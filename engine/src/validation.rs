//! Training until converged (`plan::scenario::stopping`): the validation curve of a run, the
//! stopping rule applied to it, and the best policy kept beside the final one.
//!
//! A run plays its validation episodes (their own seeds, `CellConfig::validation_seed`) before
//! training and at the first stop at or after every multiple of `validate_every`, as the test
//! curve does. The rule is a function of the curve alone: the *reference* is the first
//! validation penalty, replaced by a later one only when that is lower by `min_improvement`
//! (relative); the run stops once `patience` validations have passed since the reference was
//! last replaced (Keras's `EarlyStopping` with `min_delta` relative), or at its cap; a rule
//! with `wait_for_improvement` does not count while the reference is still the first. The best
//! policy is the one with the lowest validation penalty of all (the earliest of equals),
//! whether or not its improvement counted for the rule.
//!
//! The curve and the best policy are saved beside the run in progress after every
//! validation (the best first), so an interrupted run resumes with both and plays no
//! validation twice; the test `a_run_until_converged_resumes_bit_for_bit` holds it.

use std::path::Path;

use polars::prelude::*;

use learning::checkpoint;
use learning::ppo::TrainingState;
use plan::cell::CellConfig;
use plan::scenario::stopping::StoppingRule;
use store::save_set::SaveSet;
use store::schema::convergence as run;
use store::schema::validation::{CPU_SECONDS, TRAINING_EPISODE, VALIDATION_PENALTY, WALL_SECONDS};
use store::tables::{self, cell_columns};
use store::{BEST_METADATA_FILE, BEST_WEIGHTS_FILE, MAX_FILE_BYTES, StoreError, VALIDATION_FILE};

use crate::test_curve;

/// One validation: the mean penalty of the validation episodes after `training_episode`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ValidationPoint {
    pub(crate) training_episode: u64,
    /// Training CPU-seconds so far (`test_curve`'s clock).
    pub(crate) cpu_seconds: f64,
    pub(crate) wall_seconds: f64,
    pub(crate) penalty: f64,
}

/// Why a run until converged stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Stop {
    /// The rule: no large enough improvement over `patience` validations.
    Converged,
    /// The cap (the policy's `episodes`) came first.
    Capped,
}

impl Stop {
    fn name(self) -> &'static str {
        match self {
            Stop::Converged => run::CONVERGED,
            Stop::Capped => run::CAPPED,
        }
    }
}

/// The validations of one run so far, under its rule.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Validation {
    rule: StoppingRule,
    points: Vec<ValidationPoint>,
}

impl Validation {
    fn new(rule: StoppingRule) -> Self {
        Self {
            rule,
            points: Vec::new(),
        }
    }

    /// The validations saved in `folder` by a run now resumed after `done` training
    /// episodes (later ones belong to training the run repeats); none when nothing was saved.
    pub(crate) fn resume(folder: &Path, rule: StoppingRule, done: u64) -> Result<Self, StoreError> {
        let mut validation = Self::new(rule);
        let what = "a run's validation curve";
        if let Some(frame) = test_curve::read_in_progress(folder, VALIDATION_FILE, what)? {
            validation.points = points(&frame)?;
            validation.points.retain(|p| p.training_episode <= done);
        }
        Ok(validation)
    }

    fn every(&self) -> u64 {
        u64::from(self.rule.validate_every)
    }

    /// Whether the policy after `done` training episodes of at most `cap` is due a
    /// validation.
    pub(crate) fn due(&self, done: u64, cap: u64) -> bool {
        let last = self.points.last().map(|p| p.training_episode);
        test_curve::due(last, self.every(), done, cap)
    }

    /// Where training should stop next after `done` episodes.
    pub(crate) fn next_stop(&self, done: u64, cap: u64) -> u64 {
        test_curve::next_stop(self.every(), done, cap)
    }

    pub(crate) fn push(&mut self, point: ValidationPoint) {
        self.points.push(point);
    }

    pub(crate) fn points(&self) -> &[ValidationPoint] {
        &self.points
    }

    pub(crate) fn rule(&self) -> &StoppingRule {
        &self.rule
    }

    /// The training CPU-seconds and wall seconds of the last validation, if any.
    pub(crate) fn last_clock(&self) -> Option<(f64, f64)> {
        self.points.last().map(|p| (p.cpu_seconds, p.wall_seconds))
    }

    /// The validation with the lowest penalty, the earliest of equals.
    pub(crate) fn best(&self) -> Option<&ValidationPoint> {
        let lower = |a: &&ValidationPoint, b: &&ValidationPoint| a.penalty.total_cmp(&b.penalty);
        self.points.iter().min_by(lower)
    }

    /// Whether the run stops after `done` of at most `cap` episodes, validated there.
    pub(crate) fn stop(&self, done: u64, cap: u64) -> Option<Stop> {
        if self.points.last()?.training_episode != done {
            return None;
        }
        if self.patience_spent() {
            Some(Stop::Converged)
        } else {
            (done >= cap).then_some(Stop::Capped)
        }
    }

    /// Whether `patience` validations have passed since the reference penalty was last
    /// lowered by at least `min_improvement` of itself (and, where the rule waits for
    /// improvement, whether it ever was).
    fn patience_spent(&self) -> bool {
        let Some(first) = self.points.first() else {
            return false;
        };
        let mut reference = (0, first.penalty);
        for (i, point) in self.points.iter().enumerate().skip(1) {
            if point.penalty < reference.1 * (1.0 - self.rule.min_improvement) {
                reference = (i, point.penalty);
            }
        }
        if self.rule.wait_for_improvement && reference.0 == 0 {
            return false;
        }
        self.points.len() - 1 - reference.0 >= self.rule.patience as usize
    }

    /// The curve as a cell's table.
    pub(crate) fn frame(&self, key: &str, config: &CellConfig) -> Result<DataFrame, StoreError> {
        let rows = self.points.len();
        let column = |f: fn(&ValidationPoint) -> f64| self.points.iter().map(f).collect::<Vec<_>>();
        let episodes: Vec<u64> = self.points.iter().map(|p| p.training_episode).collect();
        let mut columns = cell_columns(key, config, rows);
        columns.extend([
            Column::new(TRAINING_EPISODE.into(), episodes),
            Column::new(CPU_SECONDS.into(), column(|p| p.cpu_seconds)),
            Column::new(WALL_SECONDS.into(), column(|p| p.wall_seconds)),
            Column::new(VALIDATION_PENALTY.into(), column(|p| p.penalty)),
        ]);
        Ok(DataFrame::new(rows, columns)?)
    }

    /// Writes the curve beside the run in progress in `folder`.
    pub(crate) fn save(
        &self,
        folder: &Path,
        key: &str,
        config: &CellConfig,
    ) -> Result<(), StoreError> {
        let bytes = tables::parquet_bytes(&self.frame(key, config)?)?;
        test_curve::write_in_progress(folder, VALIDATION_FILE, &bytes)
    }

    /// The cell's one-row table of where the run stopped and why, after `cpu_seconds` of
    /// training.
    pub(crate) fn convergence_frame(
        &self,
        (key, config): (&str, &CellConfig),
        stop: Stop,
        cpu_seconds: f64,
    ) -> Result<DataFrame, StoreError> {
        let (best, last) = match (self.best(), self.points.last()) {
            (Some(best), Some(last)) => (best, last),
            _ => {
                return Err(StoreError::corrupt(
                    Path::new(VALIDATION_FILE),
                    "no validation",
                ));
            }
        };
        let mut columns = cell_columns(key, config, 1);
        columns.extend([
            Column::new(run::STOP_EPISODE.into(), [last.training_episode]),
            Column::new(run::STOP.into(), [stop.name()]),
            Column::new(run::BEST_EPISODE.into(), [best.training_episode]),
            Column::new(run::BEST_PENALTY.into(), [best.penalty]),
            Column::new(run::FINAL_PENALTY.into(), [last.penalty]),
            Column::new(run::VALIDATIONS.into(), [self.points.len() as u32]),
            Column::new(run::CPU_SECONDS.into(), [cpu_seconds]),
            Column::new(run::TESTED.into(), [self.rule.tested.name()]),
        ]);
        Ok(DataFrame::new(1, columns)?)
    }
}

/// The best policy's save: its weights and metadata, one unit (`best-save.json`).
const BEST_SAVE: SaveSet = SaveSet {
    name: "best-save",
    files: &[BEST_WEIGHTS_FILE, BEST_METADATA_FILE],
};

/// The best policy of a run so far: its checkpoint's weights and metadata (no optimiser:
/// it is tested, never trained on).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct BestPolicy {
    pub(crate) episode: u64,
    pub(crate) weights: Vec<u8>,
    pub(crate) metadata: String,
}

impl BestPolicy {
    /// The policy of `state`, the run as it is now.
    pub(crate) fn of(state: &TrainingState) -> Self {
        let files = checkpoint::save(state);
        BestPolicy {
            episode: state.episodes_done,
            weights: files.weights,
            metadata: files.metadata,
        }
    }

    /// The best policy saved in `folder` when it is the one `validation` names best, or
    /// was saved at `done` (the validation there is about to be played again and will find
    /// it best again); `None` otherwise.
    pub(crate) fn resume(folder: &Path, validation: &Validation, done: u64) -> Option<Self> {
        BEST_SAVE.recover(folder).ok()?;
        let read = |name| store::read(&folder.join(name), MAX_FILE_BYTES, "a run's best policy");
        let weights = read(BEST_WEIGHTS_FILE).ok()?;
        let metadata = String::from_utf8(read(BEST_METADATA_FILE).ok()?).ok()?;
        let episode = checkpoint::read_metadata(&metadata).ok()?.episodes_done;
        let best = validation.best().map(|p| p.training_episode);
        (best == Some(episode) || episode == done).then_some(BestPolicy {
            episode,
            weights,
            metadata,
        })
    }

    /// Writes the policy beside the run in progress, its two files together.
    pub(crate) fn save(&self, folder: &Path) -> Result<(), StoreError> {
        let files: [(&str, &[u8]); 2] = [
            (BEST_WEIGHTS_FILE, &self.weights),
            (BEST_METADATA_FILE, self.metadata.as_bytes()),
        ];
        BEST_SAVE.save(folder, &files)
    }
}

/// The points of a validation table as [`Validation::frame`] wrote them.
fn points(frame: &DataFrame) -> Result<Vec<ValidationPoint>, StoreError> {
    let episodes = frame.column(TRAINING_EPISODE)?.u64()?;
    let cpu = frame.column(CPU_SECONDS)?.f64()?;
    let wall = frame.column(WALL_SECONDS)?.f64()?;
    let penalty = frame.column(VALIDATION_PENALTY)?.f64()?;
    (0..frame.height())
        .map(|i| {
            Ok(ValidationPoint {
                training_episode: episodes.get(i).ok_or_else(tables::missing_value)?,
                cpu_seconds: cpu.get(i).ok_or_else(tables::missing_value)?,
                wall_seconds: wall.get(i).ok_or_else(tables::missing_value)?,
                penalty: penalty.get(i).ok_or_else(tables::missing_value)?,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rule(patience: u32) -> StoppingRule {
        StoppingRule {
            validate_every: 10,
            patience,
            min_improvement: 0.1,
            ..StoppingRule::default()
        }
    }

    fn with(penalties: &[f64], patience: u32) -> Validation {
        let mut validation = Validation::new(rule(patience));
        for (i, &penalty) in penalties.iter().enumerate() {
            validation.push(ValidationPoint {
                training_episode: 10 * i as u64,
                cpu_seconds: i as f64,
                wall_seconds: i as f64,
                penalty,
            });
        }
        validation
    }

    #[test]
    fn a_run_stops_once_patience_validations_improve_less_than_the_minimum() {
        // 100 -> 85 counts (15 %); 80 and 79 do not (under 10 % of 85); two more end it.
        let validation = with(&[100.0, 85.0, 80.0, 79.0], 2);
        assert_eq!(validation.stop(30, 1000), Some(Stop::Converged));
        assert_eq!(with(&[100.0, 85.0, 80.0], 2).stop(20, 1000), None);
        // A large improvement resets the count.
        assert_eq!(with(&[100.0, 85.0, 80.0, 70.0], 2).stop(30, 1000), None);
        // The cap ends it otherwise, and only where the last validation was played.
        assert_eq!(with(&[100.0, 85.0], 2).stop(10, 10), Some(Stop::Capped));
        assert_eq!(with(&[100.0, 85.0], 2).stop(15, 10), None);
        // The best is the lowest of all, small improvements included; the earliest of equals.
        assert_eq!(validation.best().unwrap().training_episode, 30);
        assert_eq!(
            with(&[5.0, 3.0, 3.0], 9).best().unwrap().training_episode,
            10
        );
    }

    #[test]
    fn a_rule_that_waits_for_improvement_never_stops_a_run_that_did_not_learn() {
        // No validation improves on the untrained policy's: the first form stops, the
        // waiting one trains on to the cap.
        let flat = [100.0, 120.0, 99.0, 110.0];
        assert_eq!(with(&flat, 2).stop(30, 1000), Some(Stop::Converged));
        let mut waiting = with(&flat, 2);
        waiting.rule.wait_for_improvement = true;
        assert_eq!(waiting.stop(30, 1000), None);
        assert_eq!(waiting.stop(30, 30), Some(Stop::Capped));
        // Once it learned, it stops where the first form does.
        let learned = [100.0, 85.0, 80.0, 79.0];
        let mut waiting = with(&learned, 2);
        waiting.rule.wait_for_improvement = true;
        assert_eq!(waiting.stop(30, 1000), with(&learned, 2).stop(30, 1000));
    }

    #[test]
    fn validations_come_before_training_at_every_multiple_and_at_the_cap() {
        let mut validation = with(&[], 2);
        assert!(validation.due(0, 25));
        validation = with(&[1.0], 2);
        assert_eq!(validation.next_stop(0, 25), 10);
        assert!(validation.due(10, 25));
        validation = with(&[1.0, 1.0, 1.0], 2);
        assert_eq!(validation.next_stop(20, 25), 25);
        assert!(validation.due(25, 25));
    }
}
