//! A slow simulator written as plainly as the problem statement: every step it casts a segment
//! from every agent to every free cell of its square, with no precomputation and no padding.
//!
//! It is the oracle for the fast `Episode` and `Observer` (differential tests) and the baseline
//! the world benchmark is measured against, standing in for the authors' Python environment,
//! which also recomputes visibility at every step.

use crate::episode::Action;
use crate::map::{Cell, Map};
use crate::observation::{
    AGENT_CODE, OTHER_AGENT_CODE, ObservationCodes, ObservationConfig, ObservationScale,
};
use crate::params::WorldParams;
use crate::penalty::OBSTACLE_CODE;
use crate::visibility::segment_clear;

pub struct ReferenceEpisode {
    map: Map,
    params: WorldParams,
    positions: Vec<Cell>,
    /// Indexed like the map; meaningful for free cells only.
    penalty: Vec<f32>,
}

impl ReferenceEpisode {
    /// Starts at `starts` (assumed distinct free cells) and applies step 0.
    pub fn new(map: Map, params: WorldParams, starts: &[Cell]) -> (Self, f64) {
        let penalty = vec![0.0; map.width() * map.height()];
        let mut episode = Self {
            map,
            params,
            positions: starts.to_vec(),
            penalty,
        };
        let reward = episode.update_penalty();
        (episode, reward)
    }

    pub fn step(&mut self, actions: &[Action]) -> f64 {
        for (i, action) in actions.iter().enumerate() {
            let (dx, dy) = action.delta();
            let p = self.positions[i];
            let (x, y) = (p.x as i64 + dx, p.y as i64 + dy);
            let taken = self
                .positions
                .iter()
                .any(|q| q.x as i64 == x && q.y as i64 == y);
            if !self.map.is_obstacle(x, y) && !taken {
                self.positions[i] = Cell::new(x as u16, y as u16);
            }
        }
        self.update_penalty()
    }

    pub fn positions(&self) -> &[Cell] {
        &self.positions
    }

    pub fn penalty(&self, cell: Cell) -> f32 {
        self.penalty[self.map.index(cell)]
    }

    fn seen(&self, cell: Cell) -> bool {
        let half = self.params.half_fov() as i64;
        self.positions.iter().any(|&a| {
            let near = (a.x as i64 - cell.x as i64).abs() <= half
                && (a.y as i64 - cell.y as i64).abs() <= half;
            near && segment_clear(&self.map, a, cell)
        })
    }

    fn update_penalty(&mut self) -> f64 {
        let (decay, rmax) = (self.params.decay(), self.params.rmax());
        let mut reward = 0.0;
        for &cell in self.map.free_cells() {
            let seen = self.seen(cell);
            let r = &mut self.penalty[self.map.index(cell)];
            *r = if seen { 0.0 } else { (*r - decay).max(-rmax) };
            reward += *r as f64;
        }
        reward
    }

    /// The observations of all agents, by the definition in `observation`.
    pub fn observe(&self, config: ObservationConfig, side: usize) -> Vec<f32> {
        let scale = match config.scale {
            ObservationScale::Rmax => 1.0 / self.params.rmax(),
            ObservationScale::Raw => 1.0,
        };
        let agent_code = match config.codes {
            ObservationCodes::PaperText => AGENT_CODE,
            ObservationCodes::Released => OTHER_AGENT_CODE,
        };
        let channels = config.channels.count();
        let mut out = vec![OBSTACLE_CODE * scale; self.positions.len() * channels * side * side];
        for (agent, obs) in out.chunks_exact_mut(channels * side * side).enumerate() {
            let mut images = obs.chunks_exact_mut(side * side);
            if config.channels != crate::observation::Channels::Mini {
                let image = images.next().expect("local image");
                self.local_map(agent, side, scale * agent_code, scale, image);
            }
            if config.channels != crate::observation::Channels::Local {
                let image = images.next().expect("mini image");
                self.mini_map(agent, config, side, scale, image);
            }
        }
        out
    }

    fn code(&self, x: i64, y: i64) -> f32 {
        if self.map.is_obstacle(x, y) {
            OBSTACLE_CODE
        } else {
            self.penalty[y as usize * self.map.width() + x as usize]
        }
    }

    /// `agent_value` is an agent's code, scaled.
    fn local_map(&self, agent: usize, side: usize, agent_value: f32, scale: f32, out: &mut [f32]) {
        let (fov, half) = (self.params.fov(), self.params.half_fov() as i64);
        let at = self.positions[agent];
        for r in 0..fov {
            for c in 0..fov {
                let (x, y) = (at.x as i64 - half + c as i64, at.y as i64 - half + r as i64);
                let agent_here = self
                    .positions
                    .iter()
                    .any(|p| p.x as i64 == x && p.y as i64 == y);
                out[r * side + c] = if agent_here {
                    agent_value
                } else {
                    self.code(x, y) * scale
                };
            }
        }
    }

    fn mini_map(
        &self,
        agent: usize,
        config: ObservationConfig,
        side: usize,
        scale: f32,
        out: &mut [f32],
    ) {
        let fit = self
            .map
            .width()
            .max(self.map.height())
            .div_ceil(self.params.fov());
        let b = config.mini_map_block.unwrap_or(fit).max(1);
        let (w, h) = (self.map.width().div_ceil(b), self.map.height().div_ceil(b));
        for by in 0..h {
            for bx in 0..w {
                let mut codes = Vec::new();
                for j in 0..b {
                    for i in 0..b {
                        codes.push(self.code((b * bx + i) as i64, (b * by + j) as i64));
                    }
                }
                let negative = codes.iter().copied().filter(|&c| c < 0.0).reduce(f32::min);
                let obstacle = codes.contains(&OBSTACLE_CODE);
                let code = match (negative, obstacle) {
                    (Some(low), _) => low,
                    (None, true) => OBSTACLE_CODE,
                    (None, false) => 0.0,
                };
                let in_block = |p: &Cell| p.x as usize / b == bx && p.y as usize / b == by;
                let code = if in_block(&self.positions[agent]) {
                    AGENT_CODE
                } else if config.mark_others_on_mini && self.positions.iter().any(in_block) {
                    OTHER_AGENT_CODE
                } else {
                    code
                };
                out[by * side + bx] = code * scale;
            }
        }
    }
}
