//! Reports: `reports/<scenario>/README.md` answers a sweep's research question with tables
//! (Markdown beside the Parquet they came from) and figures (PNG and SVG).
//!
//! Every section builds its table first and draws its figure from that table alone, so a
//! figure never shows a number the report's tables do not hold. Penalties are in units of
//! 10^6, as in the paper.

mod attention;
mod behaviour;
mod behaviour_claims;
mod behaviour_replay;
mod budget;
mod chart;
mod columns;
mod comparison;
mod convergence;
mod disturbance;
mod earlier;
mod error;
mod failures;
mod header;
mod illustration;
pub mod judgement;
pub mod markdown;
mod missing;
mod motion;
mod penalty;
mod publish;
mod refusal_replay;
mod replayed;
mod run_seconds;
mod test_curve;
mod time_to_quality;
mod training;
mod transfer;
mod units;
pub mod verdicts;
mod writer;

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use polars::prelude::*;

use store::Store;
use store::provenance::BuiltFrom;
use store::schema;
use world::Map;

pub use error::ReportError;
pub use replayed::{Replay, ReplayError};
pub use run_seconds::{LearnedSetting, training_run_seconds};
use units::PENALTY_UNIT;
pub use writer::ReportSummary;
use writer::{ReportWriter, file_stem};

/// The folder of a report that holds the table store it was written from.
pub const STORE_FOLDER: &str = "store";

/// Writes the report of the sweep in `store` (a sweep's store or a table store) to
/// `reports_root/<scenario>/`, with the store's tables as a table store in its `store/`, so
/// that the report can be rebuilt, byte for byte, from the repository alone. The folder is
/// written whole, by one writer at a time (`publish`). `writer` is the code writing it, which
/// the header names beside the code that computed the cells.
pub fn write_report(
    store: &Store,
    reports_root: &Path,
    replay: &dyn Replay,
    writer: &BuiltFrom,
) -> Result<ReportSummary, ReportError> {
    let manifest = store
        .manifest()?
        .ok_or_else(|| ReportError::NoSweep(store.root().to_owned()))?;
    let mut report = ReportWriter::new(reports_root, &manifest.scenario)?;
    report.heading(1, &format!("Report: {}", manifest.scenario));
    // The scenario as the sweep ran it, read once for what the experiment is, its claims and
    // its earlier verdicts.
    let (scenario, scenario_path) = (store.scenario_text()?, store.scenario_path());
    let description = plan::scenario::description_of_text(&scenario, &scenario_path)?;
    if !description.is_empty() {
        report.paragraph(&description);
    }
    report.paragraph(&format!(
        "The sweep `{}` ({} cells, code version `{}`, scenario blake3 `{}`). Cumulative \
         penalties are per test episode, in units of 10^6.",
        manifest.scenario,
        manifest.cells.len(),
        manifest.code_version,
        &manifest.scenario_hash[..16.min(manifest.scenario_hash.len())],
    ));
    let loaded = StoreTables::load(store)?;
    let cells = store.optional_table(schema::cells::TABLE)?;
    let refusals = refusal_replay::measures(store, &loaded.episodes, replay)?;
    let samples = comparison::samples(&loaded.episodes)?;
    let run_failures = failures::of_runs(&samples, &refusals)?;
    let header = header::HeaderTables {
        cells: cells.as_ref(),
        episodes: &loaded.episodes,
        training: loaded.training.as_ref(),
        convergence: loaded.convergence.as_ref(),
        checkpoints: loaded.checkpoints.as_ref(),
        failures: &run_failures,
    };
    header::section(&mut report, &header, &writer.git_commit)?;
    let missing = missing::cells(store)?;
    if !missing.is_empty() {
        report.paragraph(&missing::paragraph(&missing, manifest.cells.len()));
    }
    let claims = plan::scenario::claims::claims_of_text(&scenario, &scenario_path)?;
    let mut results = Vec::new();
    if !claims.is_empty() {
        let measures = loaded.behaviour_measures(&claims, replay)?;
        results = loaded.judge(&claims, &measures)?;
        verdicts::section(&mut report, &results)?;
        // Under the behaviour claims' verdicts: every run's share and every episode.
        behaviour_claims::section(&mut report, &claims, &measures)?;
    }
    let StoreTables {
        episodes,
        training,
        motions,
        disturbed,
        test_curve,
        ..
    } = loaded;
    let summary = store.table(schema::summary::TABLE)?;
    let comparisons = comparison::comparisons(&episodes)?;
    penalty::section(&mut report, &summary, &episodes, &comparisons)?;
    failures::section(&mut report, &samples, &run_failures)?;
    comparison::section(&mut report, &comparisons)?;
    transfer::section(&mut report, &summary)?;
    if let (Some(disturbed), Some(steps)) = (
        &disturbed,
        store.optional_table(schema::disturbed_steps::TABLE)?,
    ) {
        disturbance::section(&mut report, disturbed, &steps, &motion::maps(store)?)?;
    }
    if let Some(training) = &training {
        training::section(&mut report, training)?;
        attention::section(&mut report, training)?;
    }
    if let Some(curve) = &test_curve {
        let levels = time_to_quality::levels(&comparison::samples(&episodes)?);
        let trained = test_curve::section(&mut report, curve, &levels)?;
        time_to_quality::section(&mut report, &trained, &levels)?;
    }
    if let Some((maps, motions)) = &motions {
        motion::section(&mut report, motions, maps, &claims)?;
        behaviour::section(&mut report, motions)?;
    }
    if let (Some(snapshots), Some(trajectories)) = (
        store.optional_table(schema::snapshots::TABLE)?,
        store.optional_table(schema::trajectories::TABLE)?,
    ) {
        illustration::section(&mut report, &snapshots, &trajectories, store)?;
    }
    let earlier = plan::scenario::earlier::earlier_of_text(&scenario, &scenario_path)?;
    if let Some(earlier) = &earlier {
        earlier::section(&mut report, earlier, &results)?;
    }
    let store_bytes = store.write_table_store(&report.folder().join(STORE_FOLDER), &missing)?;
    report.finish(store_bytes)
}

/// The claims of the scenario as the sweep ran it (its copy in the store).
pub fn store_claims(store: &Store) -> Result<Vec<plan::scenario::claims::Claim>, ReportError> {
    let text = store.scenario_text()?;
    Ok(plan::scenario::claims::claims_of_text(
        &text,
        &store.scenario_path(),
    )?)
}

/// The store's tables that claims are tested against and the report's sections draw.
pub struct StoreTables {
    episodes: DataFrame,
    pub training: Option<DataFrame>,
    /// The recorded episodes' motions and their maps, when the sweep kept trajectories.
    motions: Option<(HashMap<String, Map>, Vec<motion::Motion>)>,
    /// The episodes played under disturbances, when the scenario declared any.
    disturbed: Option<DataFrame>,
    /// The learned runs' test penalty along training, when their policies asked for it.
    test_curve: Option<DataFrame>,
    /// Where runs trained until converged stopped, and both their policies' tests.
    convergence: Option<DataFrame>,
    checkpoints: Option<DataFrame>,
    /// Where behaviour claims' test episodes are replayed from, and their measures kept.
    store: Store,
}

impl StoreTables {
    /// Each learned setting's training runs' CPU seconds (`run_seconds`): what more runs of
    /// it cost. Empty without a training table.
    pub fn run_cpu_seconds(&self) -> PolarsResult<BTreeMap<LearnedSetting, Vec<f64>>> {
        match &self.training {
            Some(training) => {
                run_seconds::training_run_cpu_seconds(training, self.convergence.as_ref())
            }
            None => Ok(BTreeMap::new()),
        }
    }

    /// The tables of a sweep's store or of a table store (its files checked against its
    /// marker first).
    pub fn load(store: &Store) -> Result<Self, ReportError> {
        store.table_store()?;
        let motions = match store.optional_table(schema::trajectories::TABLE)? {
            Some(trajectories) => Some(motion::load(&trajectories, store)?),
            None => None,
        };
        Ok(Self {
            episodes: store.table(schema::episodes::TABLE)?,
            training: store.optional_table(schema::training::TABLE)?,
            motions,
            disturbed: store.optional_table(schema::disturbed::TABLE)?,
            test_curve: store.optional_table(schema::test_curve::TABLE)?,
            convergence: store.optional_table(schema::convergence::TABLE)?,
            checkpoints: store.optional_table(schema::checkpoints::TABLE)?,
            store: store.clone(),
        })
    }

    /// The verdict of every claim; behaviour claims' test episodes played again by `replay`
    /// where the store holds no measures of them.
    pub fn verdicts(
        &self,
        claims: &[plan::scenario::claims::Claim],
        replay: &dyn Replay,
    ) -> Result<Vec<verdicts::ClaimResult>, ReportError> {
        self.judge(claims, &self.behaviour_measures(claims, replay)?)
    }

    /// The verdict of every claim, the behaviour claims' from `behaviours`, their measures.
    pub fn judge(
        &self,
        claims: &[plan::scenario::claims::Claim],
        behaviours: &[behaviour_replay::EpisodeMeasure],
    ) -> Result<Vec<verdicts::ClaimResult>, ReportError> {
        let recorded = verdicts::Recorded {
            episodes: &self.episodes,
            training: self.training.as_ref(),
            behaviours: Some(behaviours),
            disturbed: self.disturbed.as_ref(),
            test_curve: self.test_curve.as_ref(),
            convergence: self.convergence.as_ref(),
        };
        let mut results = verdicts::evaluate(claims, &recorded)?;
        if let Some(convergence) = &self.convergence {
            convergence::name_tested(&mut results, claims, convergence)?;
        }
        if let (Some(convergence), Some(checkpoints)) = (&self.convergence, &self.checkpoints) {
            let judged = convergence::claims_on_converged_runs(claims, convergence)?;
            let again: Vec<_> = judged.iter().map(|&i| claims[i].clone()).collect();
            let episodes =
                convergence::other_policy_episodes(&self.episodes, convergence, checkpoints)?;
            let others = verdicts::evaluate(
                &again,
                &verdicts::Recorded {
                    episodes: &episodes,
                    ..recorded
                },
            )?;
            convergence::name_other_verdicts(&mut results, &judged, &others, convergence)?;
        }
        Ok(results)
    }

    /// Every test episode that the behaviour claims of `claims` read, measured (see
    /// `behaviour_replay`).
    fn behaviour_measures(
        &self,
        claims: &[plan::scenario::claims::Claim],
        replay: &dyn Replay,
    ) -> Result<Vec<behaviour_replay::EpisodeMeasure>, ReportError> {
        let motions = self.motions.as_ref().map(|(_, m)| m.as_slice());
        let recorded = (&self.episodes, motions.unwrap_or_default());
        let measures = behaviour_replay::measures(&self.store, claims, recorded, replay)?;
        Ok(measures)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_stems_are_plain() {
        assert_eq!(
            file_stem(&["open", "ma-g-ppo[mini]@smoke", "n4"]),
            "open_ma-g-ppo_mini__smoke_n4"
        );
    }
}
