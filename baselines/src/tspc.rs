//! TSPC, the paper's cyclic-tour baseline: every agent follows one closed tour through
//! viewpoints that together see every free cell, spread evenly along it.
//!
//! The paper picked the viewpoints by hand and placed its agents on the tour; here the
//! viewpoints are a greedy set cover of the visibility sets with redundant ones dropped, and
//! `starts` places agent i at walk position floor(i W / N) of the walk of length W.

use std::sync::Arc;

use world::{Action, Cell, Episode, Seed, World};

use crate::closed_walk::ClosedWalk;
use crate::error::BaselineError;
use crate::patrol::Patrol;
use crate::viewpoints::covering_viewpoints;
use world::Policy;

pub struct Tspc {
    patrol: Patrol,
}

impl Tspc {
    pub fn new(world: &Arc<World>) -> Result<Self, BaselineError> {
        let map = world.map();
        let walk = ClosedWalk::through(map, &covering_viewpoints(world))?;
        Ok(Self {
            patrol: Patrol::new(map, vec![walk]),
        })
    }

    pub fn walk(&self) -> &ClosedWalk {
        &self.patrol.walks()[0]
    }
}

impl Policy for Tspc {
    fn name(&self) -> &str {
        "tspc"
    }

    fn starts(&mut self, world: &World, agents: usize) -> Option<Vec<Cell>> {
        Some(self.patrol.starts(world.map(), agents))
    }

    fn reset(&mut self, episode: &Episode, seed: Seed) {
        self.patrol.reset(episode, seed);
    }

    fn act(&mut self, episode: &Episode, actions: &mut [Action]) {
        self.patrol.act(episode, actions);
    }
}
