//! Which messages get through between robots, when communication is disturbed: only within a
//! radius, and each link down with probability p at each step. The draws depend on the
//! episode's seed, the step and the pair alone, never on who asks or in which order, so every
//! policy of a cell meets the same cuts, and a policy that sends nothing (MA-PPO, the
//! centralised baselines) draws nothing.

use rand::RngExt;

use crate::map::Cell;
use crate::params::ParamError;
use crate::seed::{Seed, purpose};

/// A checked link rule with the episode's stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Links {
    /// Euclidean distance between cells beyond which nothing gets through.
    radius: Option<f64>,
    /// Probability that a link is down at a step.
    drop: f64,
    seed: Seed,
}

impl Links {
    /// `radius` at least 0 and `drop` in [0, 1]; `seed` is the episode's seed.
    pub fn new(radius: Option<f64>, drop: f64, seed: Seed) -> Result<Self, ParamError> {
        if let Some(r) = radius.filter(|r| !(r.is_finite() && *r >= 0.0)) {
            return Err(ParamError::LinkRadius(r));
        }
        if !(0.0..=1.0).contains(&drop) {
            return Err(ParamError::LinkDrop(drop));
        }
        let seed = seed.child(purpose::LINKS);
        Ok(Self { radius, drop, seed })
    }

    /// Whether robots `a` at `at_a` and `b` at `at_b` hear each other at step `time`. A link
    /// is a pair: both directions are up or down together.
    pub(crate) fn up(
        &self,
        time: usize,
        (a, at_a): (usize, Cell),
        (b, at_b): (usize, Cell),
    ) -> bool {
        if let Some(radius) = self.radius {
            let (dx, dy) = (
                f64::from(at_a.x) - f64::from(at_b.x),
                f64::from(at_a.y) - f64::from(at_b.y),
            );
            if dx * dx + dy * dy > radius * radius {
                return false;
            }
        }
        if self.drop == 0.0 {
            return true;
        }
        let pair = [time as u64, a.min(b) as u64, a.max(b) as u64];
        self.seed.descend(&pair).rng().random::<f64>() >= self.drop
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HERE: Cell = Cell { x: 0, y: 0 };

    #[test]
    fn links_are_cut_beyond_the_radius_and_dropped_at_the_given_rate_in_pairs() {
        let near = Links::new(Some(5.0), 0.0, Seed::new(1)).unwrap();
        assert!(near.up(0, (0, HERE), (1, Cell::new(3, 4))));
        assert!(!near.up(0, (0, HERE), (1, Cell::new(4, 4))));
        let half = Links::new(None, 0.5, Seed::new(1)).unwrap();
        let mut up = 0;
        for time in 0..4000 {
            let forth = half.up(time, (0, HERE), (3, HERE));
            assert_eq!(forth, half.up(time, (3, HERE), (0, HERE)));
            up += usize::from(forth);
        }
        assert!((1850..2150).contains(&up), "{up} of 4000 up");
        let again = Links::new(None, 0.5, Seed::new(1)).unwrap();
        assert!(
            (0..50).all(|t| again.up(t, (1, HERE), (2, HERE)) == half.up(t, (1, HERE), (2, HERE)))
        );
        let all = Links::new(None, 1.0, Seed::new(1)).unwrap();
        assert!((0..50).all(|t| !all.up(t, (0, HERE), (1, HERE))));
    }

    #[test]
    fn a_negative_radius_or_a_probability_outside_0_1_is_refused() {
        assert_eq!(
            Links::new(Some(-1.0), 0.0, Seed::new(1)),
            Err(ParamError::LinkRadius(-1.0))
        );
        assert_eq!(
            Links::new(None, 1.5, Seed::new(1)),
            Err(ParamError::LinkDrop(1.5))
        );
        assert!(Links::new(None, f64::NAN, Seed::new(1)).is_err());
    }
}
