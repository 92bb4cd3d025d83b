//! TensorBoard event files beside a training run, so that a researcher watches a run learn
//! while it trains (runs take hours), in the tools they already watch runs in: `tensorboard
//! --logdir`, and Weights & Biases through `wandb sync --sync-tensorboard`. They are a view,
//! never a result: only this module reads them (to continue a resumed run's curves), no key,
//! record or hash covers them, and writing them draws no random number and moves no bit.
//!
//! **Format.** An event file is TFRecord: each record is its length (u64, little-endian), the
//! masked CRC-32C of those 8 bytes, the data, and the masked CRC-32C of the data. The data is
//! a `tensorflow.Event` protocol buffer; the few fields that scalars need are written here by
//! hand and encoded by `prost`'s derive (no maintained TensorBoard writer exists in Rust:
//! `tensorboard-rs` stopped in 2022 on protobuf 2), with the `crc32c` crate for the checksum.
//! A file's first event carries only `file_version: "brain.Event:2"`. Every value is a
//! `simple_value` (an f32, as TensorBoard keeps scalars) with explicit presence, so that a
//! zero (MA-PPO's attention entropy) is written, and read back as a scalar.
//!
//! **Tags and steps.** One event per training episode holds every column of the training log
//! (`training.parquet`) but the episode, under `train/`, `loss/` and `time/` (TensorBoard
//! groups tags by what comes before the slash); its step is the log's `episode` (from 0). A
//! sweep's learned cell adds its evaluations under `eval/`, at the training episodes done when
//! they were played (the `training_episode` of its test curve and validations). An event's
//! wall time is the time it was written.
//!
//! **Resume.** A run resumed after a stop writes a new file into the same folder: TensorBoard
//! reads a folder's files as one run, in the order of their names, and a new file's name sorts
//! after the folder's others. It first reads what those hold, and writes a tag only at steps
//! after the last one written: the episodes a resumed run trains again (those after the save
//! it resumed from, written before the stop) are not written twice, and those the files lack
//! (a run trained for a while without events) are written from the log. A new run (no episode
//! done) removes the folder's event files first.

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use learning::ppo::EpisodeRecord;
use polars::prelude::{DataFrame, DataType, PolarsError};
use prost::Message;

use crate::test_curve::TestCurve;
use crate::training_log;
use crate::validation::{Stop, Validation};
use plan::cell::CellConfig;
use store::Store;
use store::schema::training;

/// The folder of a store that holds its learned cells' events, one folder per training run.
pub(crate) const EVENTS_FOLDER: &str = "events";

/// How every event file's name starts (TensorBoard reads the files whose name holds
/// `tfevents`).
const FILE_PREFIX: &str = "events.out.tfevents.";

const FILE_VERSION: &str = "brain.Event:2";

/// The tag of each column of the training log but the episode.
pub const TRAINING_TAGS: [(&str, &str); 15] = [
    (training::PENALTY, "train/penalty"),
    (training::AGENTS, "train/agents"),
    (training::LEARNING_RATE, "train/learning_rate"),
    (training::GRAD_NORM, "train/grad_norm"),
    (training::LOSS, "loss/total"),
    (training::POLICY_LOSS, "loss/policy"),
    (training::VALUE_LOSS, "loss/value"),
    (training::ENTROPY, "loss/entropy"),
    (training::ATTENTION_ENTROPY, "loss/attention_entropy"),
    (training::APPROX_KL, "loss/approx_kl"),
    (training::CLIP_FRACTION, "loss/clip_fraction"),
    (training::STEPS_PER_SECOND, "time/steps_per_second"),
    (training::ROLLOUT_SECONDS, "time/rollout_seconds"),
    (training::UPDATE_SECONDS, "time/update_seconds"),
    (training::WALL_SECONDS, "time/wall_seconds"),
];

/// The mean cumulative penalty of a test curve's point.
pub(crate) const TEST_PENALTY: &str = "eval/test_penalty";
/// The mean penalty of a validation of a run until converged.
pub(crate) const VALIDATION_PENALTY: &str = "eval/validation_penalty";
/// The lowest validation penalty so far: the best policy's.
pub(crate) const BEST_VALIDATION_PENALTY: &str = "eval/best_validation_penalty";
/// Where a run until converged stopped: 1 when the rule stopped it, 0 at its cap.
pub(crate) const STOP: &str = "eval/stop";

#[derive(Debug, thiserror::Error)]
pub enum EventsError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// An earlier event file over its size limit, or not a regular file.
    #[error(transparent)]
    Input(#[from] world::InputError),
    #[error("TensorBoard events of the training log: {0}")]
    Log(#[from] PolarsError),
}

/// `tensorflow.Event`, with the fields this module writes.
#[derive(Clone, PartialEq, Message)]
struct Event {
    #[prost(double, tag = "1")]
    wall_time: f64,
    #[prost(int64, tag = "2")]
    step: i64,
    #[prost(string, optional, tag = "3")]
    file_version: Option<String>,
    #[prost(message, optional, tag = "5")]
    summary: Option<Summary>,
}

/// `tensorflow.Summary`.
#[derive(Clone, PartialEq, Message)]
struct Summary {
    #[prost(message, repeated, tag = "1")]
    value: Vec<Value>,
}

/// `tensorflow.Summary.Value`, a scalar.
#[derive(Clone, PartialEq, Message)]
struct Value {
    #[prost(string, tag = "1")]
    tag: String,
    #[prost(float, optional, tag = "2")]
    simple_value: Option<f32>,
}

/// The folder of the events of a sweep's learned cell with `config` in `store`:
/// `events/MAP-POLICY-nN_TRAIN-seedREPETITION`, named for people so that `tensorboard
/// --logdir STORE` shows a sweep's runs side by side; outside `cells/`, so that no cell's
/// files or hashes hold them and they stay when the cell's run in progress is removed.
pub fn sweep_folder(store: &Store, config: &CellConfig) -> PathBuf {
    let n_train = config.n_train.map_or(String::new(), |n| format!("-n{n}"));
    let policy = config.policy.label();
    let name = format!(
        "{}-{policy}{n_train}-seed{}",
        config.map.name, config.repetition
    );
    store.root().join(EVENTS_FOLDER).join(file_safe(&name))
}

/// `name` with every character but ASCII letters, digits and `-_.@+` as `_`.
fn file_safe(name: &str) -> String {
    let safe = |c: char| c.is_ascii_alphanumeric() || "-_.@+".contains(c);
    name.chars()
        .map(|c| if safe(c) { c } else { '_' })
        .collect()
}

/// A training run's event file, open for writing.
pub(crate) struct EventLog {
    path: PathBuf,
    file: File,
    /// The last step written of each tag, in this file or the folder's earlier ones.
    last: HashMap<String, i64>,
}

impl EventLog {
    /// A new event file in `folder` (made if need be). A `fresh` run first removes the
    /// folder's event files; any other leaves them, and what they hold is not written again.
    pub(crate) fn open(folder: &Path, fresh: bool) -> Result<Self, EventsError> {
        std::fs::create_dir_all(folder).map_err(|e| io_error(folder, e))?;
        let earlier = event_files(folder)?;
        let mut last = HashMap::new();
        for path in &earlier {
            if fresh {
                std::fs::remove_file(path).map_err(|e| io_error(path, e))?;
            } else {
                note_steps(&mut last, &read_events(path)?);
            }
        }
        let newest = if fresh { None } else { earlier.last() };
        let path = folder.join(file_name(newest));
        let file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
            .map_err(|e| io_error(&path, e))?;
        let mut log = Self { path, file, last };
        log.append(&Event {
            wall_time: now(),
            file_version: Some(FILE_VERSION.to_owned()),
            ..Event::default()
        })?;
        Ok(log)
    }

    /// The training log's episodes (its rows) that the files lack, one event each.
    pub(crate) fn write_log(&mut self, log: &DataFrame) -> Result<(), EventsError> {
        let episodes = log.column(training::EPISODE)?.u64()?;
        let columns = TRAINING_TAGS
            .iter()
            .map(|&(name, tag)| Ok((tag, log.column(name)?.cast(&DataType::Float64)?)))
            .collect::<Result<Vec<_>, PolarsError>>()?;
        for (row, episode) in episodes.iter().enumerate() {
            let mut scalars = Vec::with_capacity(columns.len());
            for (tag, column) in &columns {
                if let Some(value) = column.f64()?.get(row) {
                    scalars.push((*tag, value));
                }
            }
            if let Some(episode) = episode {
                self.write(episode, &scalars)?;
            }
        }
        Ok(())
    }

    /// The episode of `record`, as its row of the training log.
    pub(crate) fn write_record(&mut self, record: &EpisodeRecord) -> Result<(), EventsError> {
        self.write_log(&training_log::to_frame(std::slice::from_ref(record))?)
    }

    /// The evaluations of a sweep's learned cell that the files lack: its test curve, its
    /// validations with the best so far, and the stop of a run that stops at its last one.
    pub(crate) fn write_evaluations(
        &mut self,
        curve: Option<&TestCurve>,
        validation: Option<&Validation>,
        stop: Option<Stop>,
    ) -> Result<(), EventsError> {
        for point in curve.map_or(&[][..], TestCurve::points) {
            let total: f64 = point.rows.iter().map(|row| row.cumulative_penalty).sum();
            let mean = total / point.rows.len().max(1) as f64;
            self.write(point.training_episode, &[(TEST_PENALTY, mean)])?;
        }
        let points = validation.map_or(&[][..], Validation::points);
        let mut best = f64::INFINITY;
        for point in points {
            best = best.min(point.penalty);
            let scalars = [
                (VALIDATION_PENALTY, point.penalty),
                (BEST_VALIDATION_PENALTY, best),
            ];
            self.write(point.training_episode, &scalars)?;
        }
        if let (Some(stop), Some(last)) = (stop, points.last()) {
            let converged = f64::from(u8::from(stop == Stop::Converged));
            self.write(last.training_episode, &[(STOP, converged)])?;
        }
        Ok(())
    }

    /// One event at `step` with `scalars`, leaving out a tag already written at `step` or
    /// later; none when that leaves nothing.
    fn write(&mut self, step: u64, scalars: &[(&str, f64)]) -> Result<(), EventsError> {
        let step = i64::try_from(step).unwrap_or(i64::MAX);
        let mut value = Vec::with_capacity(scalars.len());
        for &(tag, scalar) in scalars {
            if self.last.get(tag).is_some_and(|&last| last >= step) {
                continue;
            }
            self.last.insert(tag.to_owned(), step);
            value.push(Value {
                tag: tag.to_owned(),
                simple_value: Some(scalar as f32),
            });
        }
        if value.is_empty() {
            return Ok(());
        }
        self.append(&Event {
            wall_time: now(),
            step,
            file_version: None,
            summary: Some(Summary { value }),
        })
    }

    /// Writes `event` as one record: unbuffered, so that a run killed after an episode has
    /// that episode in its file.
    fn append(&mut self, event: &Event) -> Result<(), EventsError> {
        let bytes = record(&event.encode_to_vec());
        self.file
            .write_all(&bytes)
            .map_err(|e| io_error(&self.path, e))
    }
}

fn io_error(path: &Path, source: std::io::Error) -> EventsError {
    EventsError::Io {
        path: path.to_owned(),
        source,
    }
}

/// Seconds since the Unix epoch, as TensorBoard's wall times are.
fn now() -> f64 {
    let since = SystemTime::now().duration_since(UNIX_EPOCH);
    since.map_or(0.0, |d| d.as_secs_f64())
}

/// The event files of `folder`, in name order: TensorBoard's reading order.
fn event_files(folder: &Path) -> Result<Vec<PathBuf>, EventsError> {
    let entries = std::fs::read_dir(folder).map_err(|e| io_error(folder, e))?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| io_error(folder, e))?.path();
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        if name.starts_with(FILE_PREFIX) && path.is_file() {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// A new event file's name, TensorFlow's `events.out.tfevents.SECONDS.HOST.PID`. Its seconds
/// are now's, or one after those of `newest` (the folder's last file) where that is not
/// earlier, so that the new file sorts after it whichever process writes it, however soon.
fn file_name(newest: Option<&PathBuf>) -> String {
    let seconds_of = |path: &PathBuf| {
        let name = path.file_name()?.to_str()?.strip_prefix(FILE_PREFIX)?;
        name.split('.').next()?.parse::<u64>().ok()
    };
    let now = now() as u64;
    let seconds = newest.and_then(seconds_of).map_or(now, |s| now.max(s + 1));
    let host = file_safe(&store::provenance::host_name());
    format!("{FILE_PREFIX}{seconds:010}.{host}.{}", std::process::id())
}

/// Sets the last step of each tag of `events` in `last`.
fn note_steps(last: &mut HashMap<String, i64>, events: &[Event]) {
    for event in events {
        for value in event.summary.iter().flat_map(|s| &s.value) {
            let step = last.entry(value.tag.clone()).or_insert(event.step);
            *step = (*step).max(event.step);
        }
    }
}

/// The events of the file at `path`.
fn read_events(path: &Path) -> Result<Vec<Event>, EventsError> {
    let bytes = world::read_bounded(path, store::MAX_FILE_BYTES, "a TensorBoard event file")?;
    let events = records(&bytes).map_while(|data| Event::decode(data).ok());
    Ok(events.collect())
}

/// Every scalar of the event files in `folder`, in reading order: step, tag and value.
#[cfg(test)]
pub(crate) fn folder_scalars(folder: &Path) -> Vec<(i64, String, f32)> {
    let files = event_files(folder).unwrap();
    let events: Vec<Event> = files.iter().flat_map(|f| read_events(f).unwrap()).collect();
    let values = events
        .iter()
        .flat_map(|e| e.summary.iter().flat_map(|s| &s.value).map(|v| (e.step, v)));
    let scalar = |(step, v): (i64, &Value)| Some((step, v.tag.clone(), v.simple_value?));
    values.filter_map(scalar).collect()
}

/// TensorFlow's masked CRC-32C: a checksum of data that holds checksums is not itself a
/// checksum that a reader would take for one.
fn masked_crc(bytes: &[u8]) -> u32 {
    crc32c::crc32c(bytes)
        .rotate_right(15)
        .wrapping_add(0xa282_ead8)
}

/// `data` framed as a TFRecord.
fn record(data: &[u8]) -> Vec<u8> {
    let length = (data.len() as u64).to_le_bytes();
    let mut record = Vec::with_capacity(data.len() + 16);
    record.extend_from_slice(&length);
    record.extend_from_slice(&masked_crc(&length).to_le_bytes());
    record.extend_from_slice(data);
    record.extend_from_slice(&masked_crc(data).to_le_bytes());
    record
}

/// The data of the TFRecords of `bytes`, up to the first that is cut short (a writer stopped
/// in the middle of it) or fails its checksum: TensorBoard stops reading there too.
fn records(bytes: &[u8]) -> impl Iterator<Item = &[u8]> {
    let mut rest = bytes;
    std::iter::from_fn(move || {
        let (length, after) = rest.split_first_chunk::<8>()?;
        let (length_crc, after) = after.split_first_chunk::<4>()?;
        if masked_crc(length) != u32::from_le_bytes(*length_crc) {
            return None;
        }
        let length = usize::try_from(u64::from_le_bytes(*length)).ok()?;
        let data = after.get(..length)?;
        let (data_crc, after) = after.get(length..)?.split_first_chunk::<4>()?;
        if masked_crc(data) != u32::from_le_bytes(*data_crc) {
            return None;
        }
        rest = after;
        Some(data)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder(name: &str) -> PathBuf {
        let folder = std::env::temp_dir().join(format!("events-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&folder);
        folder
    }

    #[test]
    fn the_checksum_is_crc32c_masked_as_tensorflow_masks_it() {
        assert_eq!(crc32c::crc32c(b"123456789"), 0xE306_9283);
        // TensorBoard's own `masked_crc32c(b"123456789")`.
        assert_eq!(masked_crc(b"123456789"), 0xC78A_B0E5);
    }

    #[test]
    fn records_read_back_up_to_a_torn_or_damaged_one() {
        let data: [&[u8]; 3] = [b"first", b"", b"third record"];
        let bytes: Vec<u8> = data.iter().flat_map(|d| record(d)).collect();
        assert_eq!(records(&bytes).collect::<Vec<_>>(), data);
        // Cut in the middle of the last record, as a killed writer leaves it.
        let torn = &bytes[..bytes.len() - 3];
        assert_eq!(records(torn).collect::<Vec<_>>(), data[..2]);
        let mut damaged = bytes.clone();
        damaged[12] ^= 1; // the first record's data
        assert_eq!(records(&damaged).count(), 0);
    }

    #[test]
    fn scalars_are_written_once_per_tag_and_step_and_zero_is_a_scalar() {
        let dir = folder("once");
        let mut log = EventLog::open(&dir, true).unwrap();
        log.write(0, &[("a", 0.0), ("b", 1.5)]).unwrap();
        log.write(0, &[("a", 9.0)]).unwrap(); // written at 0 already: left out
        log.write(1, &[("a", 2.0)]).unwrap();
        let first = read_events(&log.path).unwrap().remove(0);
        assert_eq!(first.file_version.as_deref(), Some(FILE_VERSION));
        let expected = [(0, "a", 0.0), (0, "b", 1.5), (1, "a", 2.0)]
            .map(|(step, tag, value)| (step, tag.to_owned(), value));
        assert_eq!(folder_scalars(&dir), expected);
        // The zero's presence is on the wire, as TensorBoard's reader needs it.
        let zero = Value {
            tag: String::new(),
            simple_value: Some(0.0),
        };
        assert!(!zero.encode_to_vec().is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_resumed_log_writes_only_later_steps_into_a_file_that_sorts_last() {
        let dir = folder("resumed");
        let mut first = EventLog::open(&dir, true).unwrap();
        first.write(3, &[("a", 1.0)]).unwrap();
        drop(first);
        let mut resumed = EventLog::open(&dir, false).unwrap();
        resumed.write(2, &[("a", 5.0), ("b", 5.0)]).unwrap();
        resumed.write(4, &[("a", 6.0)]).unwrap();
        let files = event_files(&dir).unwrap();
        assert_eq!(files.len(), 2);
        assert_eq!(files[1], resumed.path);
        drop(resumed);
        let expected = [(3, "a", 1.0), (2, "b", 5.0), (4, "a", 6.0)]
            .map(|(step, tag, value)| (step, tag.to_owned(), value));
        assert_eq!(folder_scalars(&dir), expected);
        // A fresh run starts over.
        drop(EventLog::open(&dir, true).unwrap());
        assert_eq!(event_files(&dir).unwrap().len(), 1);
        assert!(folder_scalars(&dir).is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn every_column_of_the_training_log_but_the_episode_has_a_tag() {
        let mut columns: Vec<&str> = TRAINING_TAGS.iter().map(|(c, _)| *c).collect();
        columns.insert(0, training::EPISODE);
        columns.sort();
        let mut log = training::LOG_COLUMNS.to_vec();
        log.sort();
        assert_eq!(columns, log);
    }

    #[test]
    fn sweep_folders_are_named_for_people_and_safe_for_file_systems() {
        let name = "open-ma-g-ppo[local]@fast-v2-n2-seed0";
        assert_eq!(file_safe(name), "open-ma-g-ppo_local_@fast-v2-n2-seed0");
        assert_eq!(file_safe("a/b c"), "a_b_c");
    }
}
