//! What the learned policies see: per agent a local map and a mini-map, coded as the paper
//! (obstacle 150, agent 200, free cell = its penalty) and divided by Rmax, or as the released
//! code (agents 100 in the local map, raw codes: [`ObservationCodes`], [`ObservationScale`]).
//!
//! Images are square, side S = max(L, mini-map sides), row 0 at the bottom (the map's y
//! direction). A channel smaller than S fills the rest of its image with the obstacle code, so
//! any map and L give images of one shape; the paper's maps and L = 25 give S = 25 and no fill.
//!
//! The mini-map pools the map in square blocks of b cells. By default b is the smallest block
//! that fits the map into the L x L of the local view, b = ceil(max(W, H) / L): the paper's
//! 2 x 2 blocks are the 50 x 50, L = 25 case, and a 200 x 200 map gets 8 x 8 blocks, so the
//! network's input stays L x L whatever the map. A configuration may set b instead; S then
//! grows when the pooled map is larger than L.

use crate::episode::{Episode, World};
use crate::map::{Cell, Map};
use crate::penalty::OBSTACLE_CODE;

/// The code of an agent: every agent in a local window (the paper's text), the observing
/// agent on its mini-map (the paper and the released code).
pub const AGENT_CODE: f32 = 200.0;
/// The code of the other agents on the mini-map, when they are marked (a released variant),
/// and of every agent in a local window in the released code.
pub(crate) const OTHER_AGENT_CODE: f32 = 100.0;

/// How the agents in a local window are coded.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum ObservationCodes {
    /// 200, as the paper's text says.
    #[default]
    PaperText,
    /// 100, the agent itself included, as the released `env.py` marks `current_map_state`.
    Released,
}

impl ObservationCodes {
    fn local_agent(self) -> f32 {
        match self {
            ObservationCodes::PaperText => AGENT_CODE,
            ObservationCodes::Released => OTHER_AGENT_CODE,
        }
    }
}

/// What the codes are divided by before the network sees them.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum ObservationScale {
    /// By Rmax: penalties in [-1, 0], obstacles 0.375.
    #[default]
    Rmax,
    /// Not at all: the released code feeds the raw codes (its learning rate of 2e-6 was set
    /// for them).
    Raw,
}

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
    /// The side b of the mini-map's blocks; `None` fits the map to the local view's side.
    pub mini_map_block: Option<usize>,
    pub codes: ObservationCodes,
    pub scale: ObservationScale,
}

impl Default for ObservationConfig {
    fn default() -> Self {
        Self {
            channels: Channels::Both,
            mark_others_on_mini: false,
            mini_map_block: None,
            codes: ObservationCodes::PaperText,
            scale: ObservationScale::Rmax,
        }
    }
}

/// The shapes of the images of one map, field of view and configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageGeometry {
    /// The side b of a mini-map block, in cells.
    pub block: usize,
    mini_width: usize,
    mini_height: usize,
    /// The side S of every image: the local image and the mini-map are padded to one square
    /// side, so that both stack as channels.
    pub side: usize,
}

impl ImageGeometry {
    /// `block` is the configuration's choice, `None` for the default (module doc); a block of
    /// 0 is read as 1.
    pub fn new(map: &Map, fov: usize, block: Option<usize>) -> Self {
        let fit = map.width().max(map.height()).div_ceil(fov.max(1));
        let block = block.unwrap_or(fit).max(1);
        let (mini_width, mini_height) = (map.width().div_ceil(block), map.height().div_ceil(block));
        Self {
            block,
            mini_width,
            mini_height,
            side: fov.max(mini_width).max(mini_height),
        }
    }

    /// The mini-map pixel (row-major in an S x S image) of the block that holds `cell`.
    fn mini_pixel(&self, cell: Cell) -> usize {
        (cell.y as usize / self.block) * self.side + cell.x as usize / self.block
    }
}

/// Writes every agent's observation into one caller-owned buffer; allocates nothing per step.
#[derive(Clone, Debug)]
pub struct Observer {
    config: ObservationConfig,
    geometry: ImageGeometry,
    fov: usize,
    scale: f32,
    /// This step's mini-map image (side x side, padding filled once) before agent marks,
    /// scaled; shared by all agents, each of which copies it whole.
    mini: Vec<f32>,
    /// Per block row: each map column's lowest and highest code over the block's rows.
    column_low: Vec<f32>,
    column_high: Vec<f32>,
}

impl Observer {
    pub fn new(world: &World, config: ObservationConfig) -> Self {
        let map = world.map();
        let fov = world.params().fov();
        let geometry = ImageGeometry::new(map, fov, config.mini_map_block);
        let side = geometry.side;
        let scale = match config.scale {
            ObservationScale::Rmax => 1.0 / world.params().rmax(),
            ObservationScale::Raw => 1.0,
        };
        let mini = vec![OBSTACLE_CODE * scale; side * side];
        let (column_low, column_high) = (vec![0.0; map.width()], vec![0.0; map.width()]);
        Self {
            config,
            geometry,
            fov,
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
        self.geometry.side
    }

    pub fn channels(&self) -> usize {
        self.config.channels.count()
    }

    /// The memory of the observer's buffers (the mini-map image and its column bounds).
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.mini.as_slice())
            + size_of_val(self.column_low.as_slice())
            + size_of_val(self.column_high.as_slice())
    }

    /// Floats per agent: channels x S x S.
    pub fn per_agent(&self) -> usize {
        self.channels() * self.side() * self.side()
    }

    /// Writes agent i's observation to `out[i * per_agent()..]`, channels local then mini.
    pub fn write(&mut self, episode: &Episode, out: &mut [f32]) {
        debug_assert_eq!(out.len(), episode.agents() * self.per_agent());
        let channels = self.config.channels;
        if channels.mini() {
            self.compute_mini(episode);
        }
        let image = self.side() * self.side();
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
        let (fov, half, side) = (self.fov, self.fov / 2, self.side());
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
                out[dy as usize * side + dx as usize] =
                    self.config.codes.local_agent() * self.scale;
            }
        }
    }

    fn write_mini(&self, positions: &[Cell], agent: usize, out: &mut [f32]) {
        out.copy_from_slice(&self.mini);
        if self.config.mark_others_on_mini {
            for &other in positions {
                out[self.geometry.mini_pixel(other)] = OTHER_AGENT_CODE * self.scale;
            }
        }
        out[self.geometry.mini_pixel(positions[agent])] = AGENT_CODE * self.scale;
    }

    /// Each block shows its lowest penalty when it has a negative one, else the obstacle code
    /// when it holds an obstacle (or a cell beyond the map), else 0. With obstacles coded 150
    /// and penalties <= 0 that is: the block's minimum if negative, else its maximum. Rows are
    /// folded first (over the block's map rows, each column at once), then columns.
    fn compute_mini(&mut self, episode: &Episode) {
        let grid = episode.penalty();
        let (codes, stride, pad) = (grid.codes(), grid.stride(), grid.pad());
        let ImageGeometry {
            block,
            mini_width,
            mini_height,
            side,
        } = self.geometry;
        let width = self.column_low.len();
        let map_height = episode.world().map().height();
        let row = |y: usize| &codes[(y + pad) * stride + pad..][..width];
        for by in 0..mini_height {
            let rows = by * block..((by + 1) * block).min(map_height);
            self.column_low.copy_from_slice(row(rows.start));
            self.column_high.copy_from_slice(row(rows.start));
            for y in rows.start + 1..rows.end {
                for ((low, high), &code) in self
                    .column_low
                    .iter_mut()
                    .zip(&mut self.column_high)
                    .zip(row(y))
                {
                    (*low, *high) = (fast_min(*low, code), fast_max(*high, code));
                }
            }
            let beyond_top = rows.end < (by + 1) * block;
            let image_row = &mut self.mini[by * side..][..mini_width];
            let blocks = self
                .column_low
                .chunks(block)
                .zip(self.column_high.chunks(block));
            for (out, (low, high)) in image_row.iter_mut().zip(blocks) {
                let low = low.iter().copied().fold(f32::INFINITY, fast_min);
                let beyond = beyond_top || high.len() < block;
                let high = if beyond {
                    OBSTACLE_CODE
                } else {
                    high.iter().copied().fold(f32::NEG_INFINITY, fast_max)
                };
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

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn open(width: usize, height: usize) -> Map {
        let row = ".".repeat(width);
        let text = vec![row; height].join("\n");
        Map::parse_text("open", &text, Path::new("open.txt")).unwrap()
    }

    #[test]
    fn the_mini_map_fits_the_local_view_unless_a_block_is_set() {
        let geometry = |w, h, fov, block| {
            let g = ImageGeometry::new(&open(w, h), fov, block);
            (g.block, g.mini_width, g.mini_height, g.side)
        };
        assert_eq!(
            geometry(50, 50, 25, None),
            (2, 25, 25, 25),
            "the paper's case"
        );
        assert_eq!(geometry(200, 200, 25, None), (8, 25, 25, 25));
        assert_eq!(geometry(201, 90, 25, None), (9, 23, 10, 25));
        assert_eq!(geometry(12, 6, 25, None), (1, 12, 6, 25));
        assert_eq!(geometry(200, 200, 25, Some(2)), (2, 100, 100, 100));
        assert_eq!(geometry(16, 16, 7, Some(2)), (2, 8, 8, 8));
    }

    #[test]
    fn a_partial_block_at_the_edge_shows_an_obstacle_unless_it_holds_a_negative_penalty() {
        let world = World::new(open(5, 5), crate::WorldParams::new(1, 1.0, 10.0).unwrap());
        let mut episode = Episode::new(world.clone(), 1).unwrap();
        episode.reset_at(&[Cell::new(0, 0)]).unwrap();
        let config = ObservationConfig {
            channels: Channels::Mini,
            mark_others_on_mini: false,
            mini_map_block: Some(3),
            ..ObservationConfig::default()
        };
        let mut observer = Observer::new(&world, config);
        assert_eq!(observer.side(), 2);
        let mut out = vec![0.0; observer.per_agent()];
        observer.write(&episode, &mut out);
        // Every cell but the agent's has decayed once: -1 / Rmax in every block.
        assert_eq!(out, vec![AGENT_CODE / 10.0, -0.1, -0.1, -0.1]);
        let world = World::new(open(4, 1), crate::WorldParams::new(3, 1.0, 10.0).unwrap());
        let mut episode = Episode::new(world.clone(), 2).unwrap();
        episode
            .reset_at(&[Cell::new(0, 0), Cell::new(3, 0)])
            .unwrap();
        let mut observer = Observer::new(&world, config);
        let mut out = vec![0.0; 2 * observer.per_agent()];
        observer.write(&episode, &mut out);
        // Every cell is seen (penalty 0). The second block holds cell 3 and two cells beyond
        // the map: an obstacle.
        assert_eq!(observer.side(), 3);
        assert_eq!(out[..2], [AGENT_CODE / 10.0, OBSTACLE_CODE / 10.0]);
    }

    /// The released code's local map: every agent in the window 100, the observing one
    /// included; raw codes, so a penalty reads as itself.
    #[test]
    fn released_codes_mark_every_agent_100_in_the_local_map_and_raw_codes_are_unscaled() {
        let world = World::new(open(5, 1), crate::WorldParams::new(3, 1.0, 10.0).unwrap());
        let mut episode = Episode::new(world.clone(), 2).unwrap();
        episode
            .reset_at(&[Cell::new(0, 0), Cell::new(1, 0)])
            .unwrap();
        let released = ObservationConfig {
            channels: Channels::Local,
            codes: ObservationCodes::Released,
            scale: ObservationScale::Raw,
            ..ObservationConfig::default()
        };
        let local = |config| {
            let mut observer = Observer::new(&world, config);
            let mut out = vec![0.0; 2 * observer.per_agent()];
            observer.write(&episode, &mut out);
            out[..observer.per_agent()].to_vec()
        };
        // Agent 0's window, the middle row: beyond the map, itself, agent 1, a seen cell.
        assert_eq!(local(released)[3..6], [OBSTACLE_CODE, 100.0, 100.0]);
        let paper = ObservationConfig {
            channels: Channels::Local,
            ..ObservationConfig::default()
        };
        assert_eq!(local(paper)[3..6], [15.0, 20.0, 20.0]);
    }
}
