//! What the learned policies see: per agent a local map and a mini-map, coded as the paper
//! (obstacle 150, agent 200, free cell = its penalty) and divided by Rmax.
//!
//! Images are square, side S = max(L, mini-map sides), row 0 at the bottom (the map's y
//! direction). A channel smaller than S fills the rest of its image with the obstacle code, so
//! any map and L give images of one shape; the paper's maps and L = 25 give S = 25 and no fill.

use crate::episode::{Episode, World};
use crate::map::{Cell, Map};
use crate::penalty::OBSTACLE_CODE;

/// The code of an agent: every agent in a local window, the observing agent on its mini-map.
pub const AGENT_CODE: f32 = 200.0;
/// The code of the other agents on the mini-map, when they are marked (the released code).
pub const OTHER_AGENT_CODE: f32 = 100.0;

/// Which images a policy gets (the paper's RQ2 compares the three). Named in training
/// configurations, hence serde.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Channels {
    Local,
    Mini,
    Both,
}

impl Channels {
    pub fn count(self) -> usize {
        match self {
            Channels::Local | Channels::Mini => 1,
            Channels::Both => 2,
        }
    }

    fn local(self) -> bool {
        self != Channels::Mini
    }

    fn mini(self) -> bool {
        self != Channels::Local
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ObservationConfig {
    pub channels: Channels,
    /// Mark the other agents on the mini-map with `OTHER_AGENT_CODE` (the released code's
    /// variant); the paper marks the observing agent only.
    pub mark_others_on_mini: bool,
}

impl Default for ObservationConfig {
    fn default() -> Self {
        Self {
            channels: Channels::Both,
            mark_others_on_mini: false,
        }
    }
}

/// Side S of the images of `map` with field of view `fov`: the local image and the mini-map
/// (the map at half resolution) are padded to one square side, so that both stack as channels.
pub fn image_side(map: &Map, fov: usize) -> usize {
    fov.max(map.width().div_ceil(2))
        .max(map.height().div_ceil(2))
}

/// Writes every agent's observation into one caller-owned buffer; allocates nothing per step.
#[derive(Clone, Debug)]
pub struct Observer {
    config: ObservationConfig,
    side: usize,
    fov: usize,
    mini_width: usize,
    mini_height: usize,
    scale: f32,
    /// This step's mini-map image (side x side, padding filled once) before agent marks,
    /// scaled; shared by all agents, each of which copies it whole.
    mini: Vec<f32>,
    /// Per block row: the lower and upper of each column pair, before pairing columns.
    column_low: Vec<f32>,
    column_high: Vec<f32>,
}

impl Observer {
    pub fn new(world: &World, config: ObservationConfig) -> Self {
        let map = world.map();
        let fov = world.params().fov();
        let (mini_width, mini_height) = (map.width().div_ceil(2), map.height().div_ceil(2));
        let side = image_side(map, fov);
        let scale = 1.0 / world.params().rmax();
        let mini = vec![OBSTACLE_CODE * scale; side * side];
        let (column_low, column_high) = (vec![0.0; 2 * mini_width], vec![0.0; 2 * mini_width]);
        Self {
            config,
            side,
            fov,
            mini_width,
            mini_height,
            scale,
            mini,
            column_low,
            column_high,
        }
    }

    pub fn config(&self) -> ObservationConfig {
        self.config
    }

    /// Side S of every image.
    pub fn side(&self) -> usize {
        self.side
    }

    pub fn channels(&self) -> usize {
        self.config.channels.count()
    }

    /// Floats per agent: channels x S x S.
    pub fn per_agent(&self) -> usize {
        self.channels() * self.side * self.side
    }

    /// Writes agent i's observation to `out[i * per_agent()..]`, channels local then mini.
    pub fn write(&mut self, episode: &Episode, out: &mut [f32]) {
        debug_assert_eq!(out.len(), episode.agents() * self.per_agent());
        let channels = self.config.channels;
        if channels.mini() {
            self.compute_mini(episode);
        }
        let image = self.side * self.side;
        let positions = episode.positions();
        for (agent, obs) in out.chunks_exact_mut(self.per_agent()).enumerate() {
            let (local, mini) = obs.split_at_mut(if channels.local() { image } else { 0 });
            if channels.local() {
                self.write_local(episode, agent, local);
            }
            if channels.mini() {
                self.write_mini(positions, agent, mini);
            }
        }
    }

    fn write_local(&self, episode: &Episode, agent: usize, out: &mut [f32]) {
        let (fov, half, side) = (self.fov, self.fov / 2, self.side);
        if side > fov {
            out.fill(OBSTACLE_CODE * self.scale);
        }
        let grid = episode.penalty();
        let at = episode.positions()[agent];
        let (stride, pad) = (grid.stride(), grid.pad());
        let left = at.x as usize + pad - half;
        for r in 0..fov {
            let start = (at.y as usize + pad - half + r) * stride + left;
            let source = &grid.codes()[start..start + fov];
            for (o, &code) in out[r * side..r * side + fov].iter_mut().zip(source) {
                *o = code * self.scale;
            }
        }
        for &other in episode.positions() {
            let dx = other.x as i64 - at.x as i64 + half as i64;
            let dy = other.y as i64 - at.y as i64 + half as i64;
            if (0..fov as i64).contains(&dx) && (0..fov as i64).contains(&dy) {
                out[dy as usize * side + dx as usize] = AGENT_CODE * self.scale;
            }
        }
    }

    fn write_mini(&self, positions: &[Cell], agent: usize, out: &mut [f32]) {
        out.copy_from_slice(&self.mini);
        let block = |cell: Cell| (cell.y as usize / 2) * self.side + cell.x as usize / 2;
        if self.config.mark_others_on_mini {
            for &other in positions {
                out[block(other)] = OTHER_AGENT_CODE * self.scale;
            }
        }
        out[block(positions[agent])] = AGENT_CODE * self.scale;
    }

    /// Each 2 x 2 block shows its lowest penalty when it has a negative one, else the obstacle
    /// code when it holds an obstacle (or a cell beyond the map), else 0. With obstacles coded
    /// 150 and penalties <= 0 that is: the block's minimum if negative, else its maximum.
    fn compute_mini(&mut self, episode: &Episode) {
        let grid = episode.penalty();
        let (codes, stride, pad) = (grid.codes(), grid.stride(), grid.pad());
        let pairs = 2 * self.mini_width;
        for by in 0..self.mini_height {
            let bottom = (2 * by + pad) * stride + pad;
            let (lower, upper) = (
                &codes[bottom..bottom + pairs],
                &codes[bottom + stride..][..pairs],
            );
            for (((low, high), &a), &b) in self
                .column_low
                .iter_mut()
                .zip(&mut self.column_high)
                .zip(lower)
                .zip(upper)
            {
                (*low, *high) = (fast_min(a, b), fast_max(a, b));
            }
            let row = &mut self.mini[by * self.side..by * self.side + self.mini_width];
            let column_pairs = self
                .column_low
                .chunks_exact(2)
                .zip(self.column_high.chunks_exact(2));
            for (out, (low, high)) in row.iter_mut().zip(column_pairs) {
                let (low, high) = (fast_min(low[0], low[1]), fast_max(high[0], high[1]));
                *out = if low < 0.0 { low } else { high } * self.scale;
            }
        }
    }
}

/// `min` without NaN handling (codes are never NaN), which compiles to one instruction.
fn fast_min(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

fn fast_max(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}
