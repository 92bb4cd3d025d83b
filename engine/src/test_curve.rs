//! The learning curve in test units. A learned cell whose policy sets `evaluate_every: K`
//! plays its test episodes at N_train (the seeds of its final tests) with the policy before
//! training, after every K training episodes and at the end. The paper's claims are about test
//! penalty, not the training episodes' own, and a training profile is judged by the CPU it
//! takes to reach a test penalty (time to quality), so every point records the training's
//! CPU-seconds so far beside its training episodes.
//!
//! **CPU.** A cell that runs on one thread (a sweep's cells do when it runs as many at once
//! as there are cores) counts its thread's own CPU clock: other work on the machine (a build,
//! another sweep) does not inflate it, where wall time would. A cell on several threads
//! counts its threads' clocks summed (a sweep gives each cell a pool of its own), not wall
//! time times its threads, which counted whatever ran beside it. After a resume, the
//! training between the last point and the checkpoint the run resumed from counts by its
//! wall time (the run keeps that, not its CPU).
//!
//! Training stops only where a round of `environments` episodes ends, so a point lands on the
//! first round's end at or after each multiple of K (choose K a multiple of `environments`
//! for even points). The points are saved beside the run in progress after every play: an
//! interrupted run resumes with them and plays no point twice. Playing reads the weights only
//! and draws from the test episodes' own seeds, so the training run is the same bit for bit
//! with or without a curve.

use std::path::Path;
use std::time::Duration;

use polars::prelude::*;

use crate::cpu_clock::thread_cpu_time;
use plan::cell::CellConfig;
use store::atomic_file::write_atomic;
use store::schema::cell;
use store::schema::test_curve::{CPU_SECONDS, TRAINING_EPISODE, WALL_SECONDS};
use store::tables::{self, EpisodeRow};
use store::{MAX_FILE_BYTES, StoreError, TEST_CURVE_FILE};

/// The test episodes played with the policy of one moment of training.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct CurvePoint {
    /// Training episodes done when the policy was played.
    pub(crate) training_episode: u64,
    /// CPU-seconds of training so far (see the module's notes); playing the curve is not
    /// counted.
    pub(crate) cpu_seconds: f64,
    /// The run's training wall seconds so far, as its checkpoint keeps them.
    pub(crate) wall_seconds: f64,
    pub(crate) rows: Vec<EpisodeRow>,
}

/// The points of one training run so far.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct TestCurve {
    every: u64,
    points: Vec<CurvePoint>,
}

impl TestCurve {
    fn new(every: u64) -> Self {
        Self {
            every: every.max(1),
            points: Vec::new(),
        }
    }

    /// The points saved in `folder` by a run now resumed after `done` training episodes
    /// (points after them belong to training the run repeats, and are dropped); none when
    /// nothing was saved.
    pub(crate) fn resume(folder: &Path, every: u64, done: u64) -> Result<Self, StoreError> {
        let mut curve = Self::new(every);
        if let Some(frame) = read_in_progress(folder, TEST_CURVE_FILE, "a run's test curve")? {
            curve.points = points(&frame)?;
            curve.points.retain(|p| p.training_episode <= done);
        }
        Ok(curve)
    }

    /// Whether the policy after `done` of `total` training episodes is due a play: before
    /// training, at the end, and at the first stop at or after each multiple of K.
    pub(crate) fn due(&self, done: u64, total: u64) -> bool {
        due(
            self.points.last().map(|p| p.training_episode),
            self.every,
            done,
            total,
        )
    }

    /// Where training should stop next after `done` episodes: the next multiple of K, or
    /// `total`.
    pub(crate) fn next_stop(&self, done: u64, total: u64) -> u64 {
        next_stop(self.every, done, total)
    }

    /// The training CPU-seconds and wall seconds of the last point, if any.
    pub(crate) fn last_clock(&self) -> Option<(f64, f64)> {
        self.points.last().map(|p| (p.cpu_seconds, p.wall_seconds))
    }

    pub(crate) fn push(&mut self, point: CurvePoint) {
        self.points.push(point);
    }

    pub(crate) fn points(&self) -> &[CurvePoint] {
        &self.points
    }

    /// The curve as a cell's table: the episodes table's columns, with the training
    /// episode and CPU-seconds after the cell's.
    pub(crate) fn frame(&self, key: &str, config: &CellConfig) -> Result<DataFrame, StoreError> {
        let rows: Vec<EpisodeRow> = self.points.iter().flat_map(|p| p.rows.clone()).collect();
        let mut frame = tables::episodes_frame(key, config, &rows)?;
        let per_row = |value: fn(&CurvePoint) -> f64| -> Vec<f64> {
            let each = |p: &CurvePoint| vec![value(p); p.rows.len()];
            self.points.iter().flat_map(each).collect()
        };
        let episodes: Vec<u64> = (self.points.iter())
            .flat_map(|p| vec![p.training_episode; p.rows.len()])
            .collect();
        frame.insert_column(
            cell::COLUMNS.len(),
            Column::new(TRAINING_EPISODE.into(), episodes),
        )?;
        let seconds = Column::new(CPU_SECONDS.into(), per_row(|p| p.cpu_seconds));
        frame.insert_column(cell::COLUMNS.len() + 1, seconds)?;
        let wall = Column::new(WALL_SECONDS.into(), per_row(|p| p.wall_seconds));
        frame.insert_column(cell::COLUMNS.len() + 2, wall)?;
        Ok(frame)
    }

    /// Writes the curve beside the run in progress in `folder`.
    pub(crate) fn save(
        &self,
        folder: &Path,
        key: &str,
        config: &CellConfig,
    ) -> Result<(), StoreError> {
        let bytes = tables::parquet_bytes(&self.frame(key, config)?)?;
        write_in_progress(folder, TEST_CURVE_FILE, &bytes)
    }
}

/// The table `name` saved beside a run in progress in `folder` (`what` it is, for messages);
/// `None` when nothing was saved.
pub(crate) fn read_in_progress(
    folder: &Path,
    name: &str,
    what: &'static str,
) -> Result<Option<DataFrame>, StoreError> {
    let path = folder.join(name);
    if !path.exists() {
        return Ok(None);
    }
    let bytes = store::read(&path, MAX_FILE_BYTES, what)?;
    Ok(Some(tables::read_parquet(bytes)?))
}

/// Writes `bytes` as `name` beside a run in progress in `folder`, whole. The first play
/// comes before the run's first save, which makes the folder, so this makes it too.
pub(crate) fn write_in_progress(folder: &Path, name: &str, bytes: &[u8]) -> Result<(), StoreError> {
    std::fs::create_dir_all(folder).map_err(|e| StoreError::io(folder, e))?;
    let path = folder.join(name);
    write_atomic(&path, bytes).map_err(|e| StoreError::io(&path, e))
}

/// Whether the policy after `done` of `total` training episodes is due a play every `every`
/// episodes, the last play being after `last`: before training, at the end, and at the first
/// stop at or after each multiple of `every`.
pub(crate) fn due(last: Option<u64>, every: u64, done: u64, total: u64) -> bool {
    let since = done / every * every;
    match last {
        Some(last) if last == done => false,
        Some(last) => done == total || last < since,
        None => true,
    }
}

/// Where training should stop next after `done` episodes for plays every `every`: the next
/// multiple, or `total`.
pub(crate) fn next_stop(every: u64, done: u64, total: u64) -> u64 {
    ((done / every + 1) * every).min(total)
}

/// The training CPU-seconds of a run resumed with `wall_seconds` of training, whose latest
/// saved point (of a test or validation curve) had `last` (CPU-seconds, wall seconds): the
/// point's CPU, plus the wall time trained after it.
pub(crate) fn cpu_at_resume(last: Option<(f64, f64)>, wall_seconds: f64) -> f64 {
    match last {
        Some((cpu, wall)) => cpu + (wall_seconds - wall).max(0.0),
        None => wall_seconds,
    }
}

/// The CPU of the code that runs between [`CpuMeter::start`] and [`CpuMeter::seconds`] on
/// the current rayon pool: the summed clocks of the pool's threads, which a sweep gives each
/// cell to itself. On a pool of one thread that is its own clock; on more, their own work,
/// where wall time times the threads would also count whatever ran beside them.
pub(crate) struct CpuMeter {
    start: Duration,
}

impl CpuMeter {
    pub(crate) fn start() -> Self {
        Self {
            start: pool_cpu_time(),
        }
    }

    pub(crate) fn seconds(&self) -> f64 {
        (pool_cpu_time() - self.start).as_secs_f64()
    }
}

/// The CPU time every thread of the current rayon pool has used so far, summed.
fn pool_cpu_time() -> Duration {
    rayon::broadcast(|_| thread_cpu_time()).into_iter().sum()
}

/// The points of a curve table as [`TestCurve::frame`] wrote them, in its order.
fn points(frame: &DataFrame) -> Result<Vec<CurvePoint>, StoreError> {
    let episodes = frame.column(TRAINING_EPISODE)?.u64()?;
    let seconds = frame.column(CPU_SECONDS)?.f64()?;
    let wall = frame.column(WALL_SECONDS)?.f64()?;
    let rows = tables::episode_rows(frame)?;
    let mut points: Vec<CurvePoint> = Vec::new();
    for (i, row) in rows.into_iter().enumerate() {
        let episode = episodes.get(i).ok_or_else(tables::missing_value)?;
        let cpu_seconds = seconds.get(i).ok_or_else(tables::missing_value)?;
        let wall_seconds = wall.get(i).ok_or_else(tables::missing_value)?;
        match points.last_mut() {
            Some(point) if point.training_episode == episode => point.rows.push(row),
            _ => points.push(CurvePoint {
                training_episode: episode,
                cpu_seconds,
                wall_seconds,
                rows: vec![row],
            }),
        }
    }
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Spins the calling thread until its own clock has run `busy`.
    fn spin(busy: Duration) {
        let start = thread_cpu_time();
        while thread_cpu_time() - start < busy {
            std::hint::black_box(0u64);
        }
    }

    /// On a pool of two threads the meter counts the work its threads did, not its wall time
    /// twice: one busy thread beside an idle one is one thread's CPU, two busy ones two.
    #[test]
    fn a_meter_on_a_pool_counts_its_threads_work() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let busy = Duration::from_millis(30);
        let (one, both) = pool.install(|| {
            let meter = CpuMeter::start();
            spin(busy);
            let one = meter.seconds();
            let meter = CpuMeter::start();
            rayon::broadcast(|_| spin(busy));
            (one, meter.seconds())
        });
        let busy = busy.as_secs_f64();
        assert!(one >= busy && one < 1.5 * busy, "{one}");
        assert!(both >= 2.0 * busy && both < 3.0 * busy, "{both}");
    }

    fn point(training_episode: u64) -> CurvePoint {
        let row = |episode| EpisodeRow {
            n_test: 2,
            episode,
            test_seed: 7,
            cumulative_penalty: -(training_episode as f64) - f64::from(episode),
            average_idleness: 1.5,
            worst_idleness: 3,
            steps: 10,
        };
        CurvePoint {
            training_episode,
            cpu_seconds: training_episode as f64 * 0.25,
            wall_seconds: training_episode as f64 * 0.5,
            rows: vec![row(0), row(1)],
        }
    }

    #[test]
    fn plays_come_before_training_at_every_multiple_and_at_the_end() {
        let mut curve = TestCurve::new(40);
        assert!(curve.due(0, 100));
        curve.push(point(0));
        assert!(!curve.due(0, 100));
        assert_eq!(curve.next_stop(0, 100), 40);
        // A round of 8 environments overshoots 40: the play lands at 48, once.
        assert!(curve.due(48, 100));
        curve.push(point(48));
        assert!(!curve.due(48, 100));
        assert!(!curve.due(56, 100), "56 is not past the next multiple");
        assert_eq!(curve.next_stop(48, 100), 80);
        assert!(curve.due(80, 100));
        curve.push(point(80));
        assert_eq!(curve.next_stop(80, 100), 100);
        assert!(curve.due(100, 100), "the end is always played");
        // The schedule's count is what the cost estimate counts.
        use plan::scenario::stopping::plays;
        assert_eq!(plays(100, 40), 4);
        assert_eq!(plays(80, 40), 3);
    }

    fn learned_cell() -> CellConfig {
        let text = "name: unit\nseed: 3\nmaps:\n  - inline: {name: a, grid: \"....\\n....\\n\"}\n\
                    world: {fov: 3, test_steps: 10, train_steps: 4}\npolicies:\n  \
                    - ma-ppo: {profile: fast-v1, episodes: 100, evaluate_every: 40, \
                    set: {network: compact}}\nagents: {train: [2], test: [2]}\ntest_episodes: 2\n";
        let scenario = plan::scenario::Scenario::parse(text, Path::new("unit.yaml")).unwrap();
        scenario.cells().remove(0).config
    }

    #[test]
    fn a_saved_curve_resumes_without_the_points_after_the_checkpoint() {
        let folder = std::env::temp_dir().join(format!("test-curve-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&folder);
        let config = learned_cell();
        let mut curve = TestCurve::new(40);
        for episode in [0, 40, 80] {
            curve.push(point(episode));
        }
        curve.save(&folder, "key", &config).unwrap();
        let frame = curve.frame("key", &config).unwrap();
        let names: Vec<&str> = frame
            .get_column_names()
            .into_iter()
            .map(|n| n.as_str())
            .collect();
        assert_eq!(
            &names[..7],
            &[
                "cell_key",
                "map",
                "policy",
                "n_train",
                "training_seed",
                TRAINING_EPISODE,
                CPU_SECONDS
            ]
        );
        assert_eq!(frame.height(), 6);
        let resumed = TestCurve::resume(&folder, 40, 60).unwrap();
        assert_eq!(resumed.points(), &curve.points()[..2]);
        // The point at 40 took 10 CPU-seconds and 20 wall; 5 more wall seconds to the
        // checkpoint count as 5 CPU-seconds.
        assert_eq!(cpu_at_resume(resumed.last_clock(), 25.0), 15.0);
        let fresh = TestCurve::resume(&folder.join("none"), 40, 60).unwrap();
        assert!(fresh.points().is_empty());
        std::fs::remove_dir_all(folder).unwrap();
    }
}
