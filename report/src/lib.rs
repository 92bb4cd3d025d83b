//! Reports: `reports/<scenario>/README.md` answers a sweep's research question with tables
//! (Markdown beside the Parquet they came from) and figures (PNG and SVG).
//!
//! Every section builds its table first and draws its figure from that table alone, so a
//! figure never shows a number the report's tables do not hold. Penalties are in units of
//! 10^6, as in the paper.

pub mod behaviour;
mod behaviour_claims;
pub mod behaviour_replay;
pub mod chart;
mod columns;
mod comparison;
mod convergence;
mod disturbance;
mod earlier;
pub mod header;
mod illustration;
pub mod judgement;
pub mod markdown;
pub mod motion;
mod penalty;
mod publish;
mod test_curve;
mod time_to_quality;
mod training;
mod transfer;
pub mod verdicts;

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use polars::prelude::*;

use chart::{ChartError, Figure, render};
use store::atomic_file::write_atomic;
use store::provenance::BuiltFrom;
use store::schema;
use store::status::CellState;
use store::{MissingCell, Store, StoreError, tables};
use world::Map;

pub use behaviour_replay::{Replay, ReplayError};

/// Penalties are reported in millions, as in the paper.
pub const PENALTY_UNIT: f64 = 1e6;

#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error("{0}")]
    Polars(#[from] PolarsError),
    #[error(transparent)]
    Chart(#[from] ChartError),
    #[error(transparent)]
    Stats(#[from] stats::StatsError),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{0} holds no sweep (no sweep.json)")]
    NoSweep(PathBuf),
    #[error(transparent)]
    Claims(#[from] plan::scenario::ScenarioError),
    #[error(transparent)]
    Status(#[from] store::status::StatusError),
    #[error(transparent)]
    Behaviour(#[from] behaviour_replay::BehaviourError),
}

/// What a report wrote.
#[derive(Debug)]
pub struct ReportSummary {
    pub folder: PathBuf,
    pub tables: usize,
    pub figures: usize,
    /// The bytes of the table store it carries in `store/`.
    pub store_bytes: u64,
}

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
    let header = header::HeaderTables {
        cells: cells.as_ref(),
        episodes: &loaded.episodes,
        training: loaded.training.as_ref(),
        convergence: loaded.convergence.as_ref(),
        checkpoints: loaded.checkpoints.as_ref(),
    };
    header::section(&mut report, &header, &writer.git_commit)?;
    let missing = missing_cells(store)?;
    if !missing.is_empty() {
        report.paragraph(&missing_paragraph(&missing, manifest.cells.len()));
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

/// The cells of the sweep that its tables lack, failed or not run, each with why: every
/// figure and verdict rests on the others, and the reader must know which. A table store
/// keeps the list its report printed: its cells are complete by construction.
fn missing_cells(store: &Store) -> Result<Vec<MissingCell>, ReportError> {
    if let Some(marker) = store.table_store()? {
        return Ok(marker.missing);
    }
    let status = store::status::sweep_status(store.root())?;
    Ok(status
        .cells
        .into_iter()
        .filter_map(|cell| {
            let why = match cell.state {
                CellState::Done { .. } => return None,
                CellState::Failed { failure, .. } => format!("failed: {}", failure.error),
                CellState::Running { .. } => "still running".to_owned(),
                CellState::Missing { .. } => "not run".to_owned(),
                CellState::Damaged { why, .. } => format!("damaged: {why}"),
            };
            Some(MissingCell {
                label: cell.label,
                key: cell.key,
                why,
            })
        })
        .collect())
}

fn missing_paragraph(missing: &[MissingCell], cells: usize) -> String {
    let lines: Vec<String> = missing
        .iter()
        .map(|cell| format!("- {} (`{}`): {}", cell.label, cell.key, cell.why))
        .collect();
    format!(
        "**{} of {cells} cells are missing** from these tables, and every number, figure and \
         verdict below rests on the others:\n\n{}",
        missing.len(),
        lines.join("\n")
    )
}

/// The claims of the scenario as the sweep ran it (its copy in the store).
pub fn store_claims(store: &Store) -> Result<Vec<plan::scenario::claims::Claim>, ReportError> {
    let text = store.scenario_text()?;
    Ok(plan::scenario::claims::claims_of_text(
        &text,
        &store.scenario_path(),
    )?)
}

/// A learned setting as the training table names it: map, policy, N_train.
pub type LearnedSetting = (String, String, u32);

/// Each learned setting's training runs' own wall times in seconds, by their logs: a run's is
/// its log's last `wall_seconds` (the log counts from the run's start, across resumes; one
/// cell holds one run). What one more run of the setting costs, whether or not the sweep took
/// the run from the cache (then the cell's own wall time counts only its tests).
pub fn training_run_seconds(
    training: &DataFrame,
) -> PolarsResult<BTreeMap<LearnedSetting, Vec<f64>>> {
    let keys = columns::strings(training, schema::cell::KEY)?;
    let walls = columns::f64s(training, schema::training::WALL_SECONDS)?;
    let settings = columns::trained_keys(training)?;
    let mut runs: BTreeMap<LearnedSetting, Vec<f64>> = BTreeMap::new();
    for (_, rows) in columns::group_rows(&keys) {
        let (map, policy) = &settings[rows[0]];
        if let Some(n_train) = policy.n_train {
            let seconds = rows.iter().map(|&r| walls[r]).fold(0.0, f64::max);
            let setting = (map.clone(), policy.policy.clone(), n_train);
            runs.entry(setting).or_default().push(seconds);
        }
    }
    Ok(runs)
}

/// The store's tables that claims are tested against and the report's sections draw.
pub struct StoreTables {
    pub episodes: DataFrame,
    pub training: Option<DataFrame>,
    /// The recorded episodes' motions and their maps, when the sweep kept trajectories.
    pub motions: Option<(HashMap<String, Map>, Vec<motion::Motion>)>,
    /// The episodes played under disturbances, when the scenario declared any.
    pub disturbed: Option<DataFrame>,
    /// The learned runs' test penalty along training, when their policies asked for it.
    pub test_curve: Option<DataFrame>,
    /// Where runs trained until converged stopped, and both their policies' tests.
    pub convergence: Option<DataFrame>,
    pub checkpoints: Option<DataFrame>,
    /// Where behaviour claims' test episodes are replayed from, and their measures kept.
    store: Store,
}

impl StoreTables {
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
        Ok(results)
    }

    /// Every test episode that the behaviour claims of `claims` read, measured (see
    /// `behaviour_replay`).
    pub fn behaviour_measures(
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

/// The report folder being written: the README's text, and its tables and figures.
pub struct ReportWriter {
    publication: publish::Publication,
    readme: String,
    tables: usize,
    figures: usize,
}

impl ReportWriter {
    fn new(reports_root: &Path, name: &str) -> Result<Self, ReportError> {
        let publication = publish::Publication::start(reports_root, name)?;
        for sub in ["tables", "figures"] {
            let path = publication.fresh.join(sub);
            std::fs::create_dir_all(&path).map_err(|source| ReportError::Io { path, source })?;
        }
        Ok(Self {
            publication,
            readme: String::new(),
            tables: 0,
            figures: 0,
        })
    }

    /// Where the report is written until it is whole.
    fn folder(&self) -> &Path {
        &self.publication.fresh
    }

    fn heading(&mut self, level: usize, text: &str) {
        self.readme += &format!("{} {text}\n\n", "#".repeat(level));
    }

    fn paragraph(&mut self, text: &str) {
        self.readme += text;
        self.readme += "\n\n";
    }

    /// Writes `tables/NAME.parquet` and `tables/NAME.md`, and shows the table in the README.
    fn table(&mut self, name: &str, frame: &DataFrame) -> Result<(), ReportError> {
        let markdown = markdown::table(frame)?;
        self.write(
            &format!("tables/{name}.parquet"),
            &tables::parquet_bytes(frame)?,
        )?;
        self.write(&format!("tables/{name}.md"), markdown.as_bytes())?;
        self.tables += 1;
        self.readme += &markdown;
        self.readme += &format!("\n([Parquet](tables/{name}.parquet))\n\n");
        Ok(())
    }

    /// Writes a table too long to read (per step or per cell) as Parquet only, and links it.
    fn linked_table(
        &mut self,
        name: &str,
        frame: &DataFrame,
        what: &str,
    ) -> Result<(), ReportError> {
        self.write(
            &format!("tables/{name}.parquet"),
            &tables::parquet_bytes(frame)?,
        )?;
        self.tables += 1;
        self.readme += &format!(
            "{what}: [Parquet](tables/{name}.parquet) ({} rows).\n\n",
            frame.height()
        );
        Ok(())
    }

    /// Writes `figures/NAME.png`, and `figures/NAME.svg` unless it is large, and shows the PNG
    /// in the README.
    fn figure(
        &mut self,
        name: &str,
        figure: &impl Figure,
        caption: &str,
    ) -> Result<(), ReportError> {
        let rendered = render(figure)?;
        self.write(&format!("figures/{name}.png"), &rendered.png)?;
        let svg = if rendered.svg.len() <= MAX_SVG_BYTES {
            self.write(&format!("figures/{name}.svg"), rendered.svg.as_bytes())?;
            format!("[SVG](figures/{name}.svg)")
        } else {
            format!("SVG of {} KB left out", rendered.svg.len() / 1000)
        };
        self.figures += 1;
        self.readme += &format!("![{caption}](figures/{name}.png)\n\n*{caption}* ({svg})\n\n");
        Ok(())
    }

    fn write(&mut self, relative: &str, bytes: &[u8]) -> Result<(), ReportError> {
        let path = self.folder().join(relative);
        write_atomic(&path, bytes).map_err(|source| ReportError::Io { path, source })
    }

    /// Writes the README and puts the whole folder in the last report's place: the folder
    /// then holds exactly what the README shows, and nothing of an earlier report.
    fn finish(mut self, store_bytes: u64) -> Result<ReportSummary, ReportError> {
        let readme = std::mem::take(&mut self.readme);
        self.write("README.md", readme.as_bytes())?;
        Ok(ReportSummary {
            folder: self.publication.swap_in()?,
            tables: self.tables,
            figures: self.figures,
            store_bytes,
        })
    }
}

/// The largest SVG a report keeps. Maps and trajectories draw a shape per cell or step, and
/// their SVGs run to hundreds of KB; their PNGs stand, so that a report stays small enough to
/// commit.
const MAX_SVG_BYTES: usize = 100_000;

/// A name safe in file names: letters, digits and `-`, everything else `_`.
fn file_stem(parts: &[&str]) -> String {
    parts
        .join("_")
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
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
