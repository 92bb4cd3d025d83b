//! The per-episode training log as a Polars table, stored as Parquet. A resumed run appends to
//! the log of the run it continues.

use std::io::Cursor;

use learning::ppo::EpisodeRecord;
use polars::prelude::*;
use store::schema::training;

/// One row per record.
pub(crate) fn to_frame(records: &[EpisodeRecord]) -> PolarsResult<DataFrame> {
    let f64s = |name: &str, read: fn(&EpisodeRecord) -> f64| {
        Column::new(name.into(), records.iter().map(read).collect::<Vec<f64>>())
    };
    let columns = vec![
        Column::new(
            training::EPISODE.into(),
            records.iter().map(|r| r.episode).collect::<Vec<u64>>(),
        ),
        Column::new(
            training::AGENTS.into(),
            records
                .iter()
                .map(|r| r.agents as u32)
                .collect::<Vec<u32>>(),
        ),
        f64s(training::PENALTY, |r| r.penalty),
        f64s(training::LOSS, |r| r.update.loss.total),
        f64s(training::POLICY_LOSS, |r| r.update.loss.policy),
        f64s(training::VALUE_LOSS, |r| r.update.loss.value),
        f64s(training::ENTROPY, |r| r.update.loss.entropy),
        f64s(training::ATTENTION_ENTROPY, |r| {
            r.update.loss.attention_entropy
        }),
        f64s(training::APPROX_KL, |r| r.update.loss.approx_kl),
        f64s(training::CLIP_FRACTION, |r| r.update.loss.clip_fraction),
        f64s(training::GRAD_NORM, |r| r.update.grad_norm),
        f64s(training::LEARNING_RATE, |r| r.update.learning_rate),
        f64s(training::STEPS_PER_SECOND, |r| r.steps_per_second),
        f64s(training::ROLLOUT_SECONDS, |r| r.rollout_seconds),
        f64s(training::UPDATE_SECONDS, |r| r.update_seconds),
        f64s(training::WALL_SECONDS, |r| r.wall_seconds),
    ];
    DataFrame::new(records.len(), columns)
}

/// The log's columns that a repeated run reproduces bit for bit.
pub fn reproducible_columns() -> Vec<PlSmallStr> {
    training::LOG_COLUMNS
        .into_iter()
        .filter(|name| !training::TIMING_COLUMNS.contains(name))
        .map(PlSmallStr::from_static)
        .collect()
}

pub(crate) fn to_parquet(frame: &mut DataFrame) -> PolarsResult<Vec<u8>> {
    let mut bytes = Vec::new();
    ParquetWriter::new(&mut bytes).finish(frame)?;
    Ok(bytes)
}

pub fn from_parquet(bytes: &[u8]) -> PolarsResult<DataFrame> {
    ParquetReader::new(Cursor::new(bytes)).finish()
}

/// `earlier` (from the run resumed), keeping only its episodes before `first`, then `records`.
pub(crate) fn append(
    earlier: &DataFrame,
    first: u64,
    records: &[EpisodeRecord],
) -> PolarsResult<DataFrame> {
    let kept = earlier.filter(&earlier.column(training::EPISODE)?.u64()?.lt(first))?;
    kept.vstack(&to_frame(records)?)
}

#[cfg(test)]
mod tests {
    use learning::ppo::UpdateStats;

    use super::*;

    fn record(episode: u64) -> EpisodeRecord {
        EpisodeRecord {
            episode,
            agents: 2,
            penalty: 1.5e6 + episode as f64,
            update: UpdateStats::default(),
            steps_per_second: 1.0,
            rollout_seconds: 2.0,
            update_seconds: 3.0,
            wall_seconds: 4.0,
        }
    }

    #[test]
    fn records_round_trip_through_parquet_and_resumes_append() {
        let mut frame = to_frame(&[record(0), record(1), record(2)]).unwrap();
        let bytes = to_parquet(&mut frame).unwrap();
        let read = from_parquet(&bytes).unwrap();
        assert!(read.equals(&frame));
        // A resume from episode 2 drops the earlier log's episode 2 and appends its own.
        let joined = append(&read, 2, &[record(2), record(3)]).unwrap();
        let episodes: Vec<u64> = joined
            .column("episode")
            .unwrap()
            .u64()
            .unwrap()
            .into_no_null_iter()
            .collect();
        assert_eq!(episodes, vec![0, 1, 2, 3]);
    }

    #[test]
    fn the_log_has_the_schema_columns_and_all_but_the_timings_reproduce() {
        let frame = to_frame(&[record(0)]).unwrap();
        let names: Vec<&str> = frame
            .get_column_names()
            .iter()
            .map(|n| n.as_str())
            .collect();
        assert_eq!(names, training::LOG_COLUMNS);
        let reproducible = reproducible_columns();
        assert_eq!(reproducible.len(), 12);
        assert!(
            reproducible
                .iter()
                .all(|c| !training::TIMING_COLUMNS.contains(&c.as_str()))
        );
    }
}
