//! Rerun recordings (`.rrd`) of stored test episodes, scrubbable in time in the rerun viewer:
//! per step the penalty map as an image, the agents as points with their field-of-view squares
//! and recent trails, the team's penalty as a time series, and for MA-G-PPO the attention
//! weights between agents. An episode can also be played under one of its cell's
//! disturbances, as the disturbed table holds it, with lost robots drawn apart in grey.
//!
//! Recordings are views: the episode is played again from the cell's config (test episodes are
//! pure functions of it), and the Parquet tables stay the source of truth. An `.rrd` file is
//! not byte-reproducible (rerun stamps a random recording id and wall-clock times).

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use rerun::external::re_entity_db::EntityDb;
use rerun::external::re_log_encoding::DecoderApp;
use world::{Episode, World};

use world::{AttentionEdges, Policy};

use engine::execution::{CellError, observed_test_episode, stored_policy};
use store::{Store, StoreError};
use world::palette;

/// The timeline every entity is logged on: the episode's step (0 is the start).
const TIMELINE: &str = "step";
/// Steps of trail drawn behind each agent.
const TRAIL: usize = 100;

mod entity {
    pub(crate) const PENALTY_MAP: &str = "map/penalty";
    pub(crate) const AGENTS: &str = "map/agents";
    /// Robots lost under a disturbance, from the step they stop; they leave `AGENTS`.
    pub(crate) const LOST: &str = "map/lost";
    pub(crate) const FIELDS_OF_VIEW: &str = "map/fov";
    pub(crate) const TRAILS: &str = "map/trails";
    pub(crate) const PENALTY: &str = "penalty/total";
    /// MA-G-PPO only: lines between agents, and each weight as a series `attention/I/J` (how
    /// much agent I attends to agent J).
    pub(crate) const ATTENTION: &str = "map/attention";
    pub(crate) const ATTENTION_WEIGHTS: &str = "attention";
}

#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Cell(#[from] CellError),
    #[error("the stored world parameters of cell {key} are not valid: {problem}")]
    World { key: String, problem: String },
    #[error("cell {key} was not tested with {n_test} agents or has no test episode {episode}")]
    NoSuchEpisode {
        key: String,
        n_test: u32,
        episode: u32,
    },
    #[error("cell {key} has no disturbance named {name:?} (it has {known})")]
    NoSuchDisturbance {
        key: String,
        name: String,
        known: String,
    },
    #[error("{path}: {problem}")]
    Rerun { path: PathBuf, problem: String },
}

/// Which stored test episode to record.
#[derive(Clone, Debug)]
pub struct EpisodeChoice {
    pub cell: String,
    pub n_test: u32,
    pub episode: u32,
    /// A disturbance of the cell's config by name; `None` plays the episode undisturbed.
    pub disturbance: Option<String>,
}

/// Plays the chosen episode of `store` again and saves its recording at `path`.
pub fn record_episode(
    store: &Store,
    choice: &EpisodeChoice,
    path: &Path,
) -> Result<(), RecordingError> {
    let record = store.verified_record(&choice.cell)?;
    let config = &record.config;
    if !config.n_test.contains(&choice.n_test) || choice.episode >= config.test_episodes {
        return Err(RecordingError::NoSuchEpisode {
            key: choice.cell.clone(),
            n_test: choice.n_test,
            episode: choice.episode,
        });
    }
    let disturbance = match &choice.disturbance {
        None => None,
        Some(name) => {
            config
                .disturbance(name)
                .map_err(|known| RecordingError::NoSuchDisturbance {
                    key: choice.cell.clone(),
                    name: name.clone(),
                    known,
                })?
        }
    };
    let map = store.map(&config.map.name, &config.map.hash)?;
    let params = config.world.params().map_err(|e| RecordingError::World {
        key: choice.cell.clone(),
        problem: e.to_string(),
    })?;
    let world = World::new(map, params);
    let mut policy = stored_policy(store, &record, &world)?;
    let attention = Arc::new(Mutex::new(None));
    let mut tap = AttentionTap {
        policy: policy.as_mut(),
        last: attention.clone(),
    };
    let rerun_error = |e: &dyn std::fmt::Display| RecordingError::Rerun {
        path: path.to_owned(),
        problem: e.to_string(),
    };
    let stream = rerun::RecordingStreamBuilder::new("vpm-harness")
        .save(path)
        .map_err(|e| rerun_error(&e))?;
    let mut logger = StepLogger::new(&world, stream);
    let mut failure = None;
    observed_test_episode(
        &world,
        &mut tap,
        config,
        (choice.n_test, choice.episode),
        disturbance,
        &mut |episode, _, _| {
            if failure.is_none() {
                let edges = attention.lock().expect("no panics hold the lock").take();
                failure = logger.log(episode, edges).err();
            }
        },
    )
    .map_err(CellError::from)?;
    if let Some(e) = failure {
        return Err(rerun_error(&e));
    }
    logger.stream.flush_blocking().map_err(|e| rerun_error(&e))
}

/// Records, for every cell of `keys` from repetition 0, its first test episode with its
/// largest N_test into `folder/KEY.rrd` (the sweep's `--record`), skipping unfinished cells
/// (another shard's) and recordings that exist; returns how many it wrote. Each is written under a temporary name and renamed.
pub fn record_cells(
    store: &Store,
    keys: &[String],
    folder: &Path,
) -> Result<usize, RecordingError> {
    let io = |path: &Path, e: std::io::Error| RecordingError::Rerun {
        path: path.to_owned(),
        problem: e.to_string(),
    };
    std::fs::create_dir_all(folder).map_err(|e| io(folder, e))?;
    let mut written = 0;
    for key in keys {
        let Some(record) = store.finished(key) else {
            continue;
        };
        let path = folder.join(format!("{key}.rrd"));
        let largest = record.config.n_test.iter().max();
        let (Some(&n_test), 0) = (largest, record.config.repetition) else {
            continue;
        };
        if path.exists() {
            continue;
        }
        let partial = folder.join(format!(".{key}.rrd.partial"));
        let choice = EpisodeChoice {
            cell: key.clone(),
            n_test,
            episode: 0,
            disturbance: None,
        };
        record_episode(store, &choice, &partial)?;
        std::fs::rename(&partial, &path).map_err(|e| io(&path, e))?;
        written += 1;
    }
    Ok(written)
}

/// Passes every call on to the recorded policy and keeps, after each step, the attention
/// between agents that chose its actions, for the logger to draw.
struct AttentionTap<'a> {
    policy: &'a mut dyn Policy,
    last: Arc<Mutex<Option<AttentionEdges>>>,
}

impl Policy for AttentionTap<'_> {
    fn name(&self) -> &str {
        self.policy.name()
    }

    fn starts(&mut self, world: &World, agents: usize) -> Option<Vec<world::Cell>> {
        self.policy.starts(world, agents)
    }

    fn reset(&mut self, episode: &Episode, seed: world::Seed) {
        self.policy.reset(episode, seed);
    }

    fn act(&mut self, episode: &Episode, actions: &mut [world::Action]) {
        self.policy.act(episode, actions);
        *self.last.lock().expect("no panics hold the lock") = self.policy.attention();
    }
}

/// Logs one step after another to a recording stream.
struct StepLogger {
    world: Arc<World>,
    stream: rerun::RecordingStream,
    trails: Vec<Vec<[f32; 2]>>,
    pixels: Vec<u8>,
}

impl StepLogger {
    fn new(world: &Arc<World>, stream: rerun::RecordingStream) -> Self {
        Self {
            world: world.clone(),
            stream,
            trails: Vec::new(),
            pixels: Vec::new(),
        }
    }

    fn log(
        &mut self,
        episode: &Episode,
        attention: Option<AttentionEdges>,
    ) -> Result<(), rerun::RecordingStreamError> {
        let map = self.world.map();
        let (width, height) = (map.width(), map.height());
        self.stream
            .set_time_sequence(TIMELINE, episode.time() as i64);
        self.penalty_image(episode);
        let image = rerun::Image::from_rgb24(self.pixels.clone(), [width as u32, height as u32]);
        self.stream.log(entity::PENALTY_MAP, &image)?;
        // Image space: x to the right, y down from the top row.
        let centres: Vec<[f32; 2]> = episode
            .positions()
            .iter()
            .map(|c| [c.x as f32 + 0.5, (height - 1 - c.y as usize) as f32 + 0.5])
            .collect();
        self.trails.resize(centres.len(), Vec::new());
        for (trail, &centre) in self.trails.iter_mut().zip(&centres) {
            trail.push(centre);
            if trail.len() > TRAIL {
                trail.remove(0);
            }
        }
        let colours: Vec<rerun::Color> = (0..centres.len()).map(agent_colour).collect();
        let (lost, active): (Vec<usize>, Vec<usize>) =
            (0..centres.len()).partition(|&a| episode.stopped()[a]);
        let at = |agents: &[usize]| agents.iter().map(|&a| centres[a]).collect::<Vec<_>>();
        self.stream.log(
            entity::AGENTS,
            &rerun::Points2D::new(at(&active))
                .with_radii([0.6])
                .with_colors(active.iter().map(|&a| colours[a]))
                .with_labels(active.iter().map(|a| format!("agent {a}"))),
        )?;
        if !lost.is_empty() {
            let [red, green, blue] = palette::LOST;
            self.stream.log(
                entity::LOST,
                &rerun::Points2D::new(at(&lost))
                    .with_radii([0.6])
                    .with_colors([rerun::Color::from_rgb(red, green, blue)])
                    .with_labels(lost.iter().map(|a| format!("agent {a}, lost"))),
            )?;
        }
        let half = self.world.params().fov() as f32 / 2.0;
        self.stream.log(
            entity::FIELDS_OF_VIEW,
            &rerun::Boxes2D::from_centers_and_half_sizes(
                at(&active),
                vec![[half, half]; active.len()],
            )
            .with_colors(active.iter().map(|&a| colours[a])),
        )?;
        self.stream.log(
            entity::TRAILS,
            &rerun::LineStrips2D::new(self.trails.clone()).with_colors(colours),
        )?;
        if let Some(edges) = attention {
            self.log_attention(&centres, &edges)?;
        }
        self.stream
            .log(entity::PENALTY, &rerun::Scalars::new([-episode.reward()]))
    }

    /// MA-G-PPO's attention: a line from each agent towards each neighbour, as opaque as its
    /// weight, and every weight as a time series `attention/I/J`.
    fn log_attention(
        &self,
        centres: &[[f32; 2]],
        edges: &AttentionEdges,
    ) -> Result<(), rerun::RecordingStreamError> {
        let lines: Vec<Vec<[f32; 2]>> = edges
            .iter()
            .map(|&(agent, neighbour, _)| {
                let (from, to) = (centres[agent], centres[neighbour]);
                // Half way, so that the two directions of a pair stay apart.
                vec![from, [(from[0] + to[0]) / 2.0, (from[1] + to[1]) / 2.0]]
            })
            .collect();
        let colours: Vec<rerun::Color> = edges
            .iter()
            .map(|&(agent, _, weight)| {
                let [red, green, blue] = palette::series(agent);
                rerun::Color::from_unmultiplied_rgba(red, green, blue, (weight * 255.0) as u8)
            })
            .collect();
        let radii = edges.iter().map(|&(_, _, weight)| 0.1 + 0.5 * weight);
        self.stream.log(
            entity::ATTENTION,
            &rerun::LineStrips2D::new(lines)
                .with_colors(colours)
                .with_radii(radii),
        )?;
        for &(agent, neighbour, weight) in edges {
            let path = format!("{}/{agent}/{neighbour}", entity::ATTENTION_WEIGHTS);
            self.stream
                .log(path, &rerun::Scalars::new([weight as f64]))?;
        }
        Ok(())
    }

    /// The penalty map as RGB rows from the top: blue at 0 to red at -Rmax, obstacles dark.
    fn penalty_image(&mut self, episode: &Episode) {
        let map = self.world.map();
        let rmax = self.world.params().rmax() as f64;
        let grid = episode.penalty();
        self.pixels.clear();
        for row in 0..map.height() {
            let y = map.height() - 1 - row;
            for x in 0..map.width() {
                let code = grid.codes()[(y + grid.pad()) * grid.stride() + x + grid.pad()] as f64;
                let rgb = if code > 0.0 {
                    palette::OBSTACLE
                } else {
                    palette::penalty(-code / rmax)
                };
                self.pixels.extend(rgb);
            }
        }
    }
}

fn agent_colour(agent: usize) -> rerun::Color {
    let [red, green, blue] = palette::series(agent);
    rerun::Color::from_rgb(red, green, blue)
}

/// What a recording holds, as rerun's own loader (the viewer's entity database) reads it.
#[derive(Debug, PartialEq)]
pub struct RecordingContents {
    pub entities: Vec<String>,
    /// Rows logged on the step timeline, all entities together.
    pub rows: u64,
    /// The first and last step.
    pub steps: Option<(i64, i64)>,
}

/// Reads a recording back through rerun's decoder into its entity database.
pub fn read_recording(path: &Path) -> Result<RecordingContents, RecordingError> {
    let problem = |e: &dyn std::fmt::Display| RecordingError::Rerun {
        path: path.to_owned(),
        problem: e.to_string(),
    };
    let file = std::fs::File::open(path).map_err(|e| problem(&e))?;
    let messages =
        DecoderApp::decode_eager(std::io::BufReader::new(file)).map_err(|e| problem(&e))?;
    let mut database: Option<EntityDb> = None;
    for message in messages {
        let message = message.map_err(|e| problem(&e))?;
        let database = database.get_or_insert_with(|| EntityDb::new(message.store_id().clone()));
        database.add_log_msg(&message).map_err(|e| problem(&e))?;
    }
    let Some(database) = database else {
        return Err(problem(&"the file holds no messages"));
    };
    let timeline = TIMELINE.into();
    Ok(RecordingContents {
        entities: database
            .sorted_entity_paths()
            .map(|p| p.to_string())
            .collect(),
        rows: database.num_temporal_rows_on_timeline(&timeline),
        steps: database
            .time_range_for(&timeline)
            .map(|range| (range.min().as_i64(), range.max().as_i64())),
    })
}
