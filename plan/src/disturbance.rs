//! Disturbances a scenario declares for its test episodes: robots lost part-way through an
//! episode, and messages between robots limited to a radius or dropped at random.
//!
//! A disturbance is a pure function of the episode's seed, so every policy of a cell meets the
//! same one: the same robots stop at the same step, the same links are down at the same steps.
//! Values are checked when a disturbance is made (scenario load, or a config read back from a
//! store), so running one cannot fail.

use serde::{Deserialize, Serialize};
use world::seed::purpose;
use world::{Episode, Links, Seed};

/// The name of the undisturbed episodes in the disturbed table.
pub const UNDISTURBED: &str = "none";

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Disturbance {
    pub name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) lose: Option<Loss>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) links: Option<LinkRule>,
}

/// Robots that stop for good: after step `at`, they no longer move, see or send.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Loss {
    pub(crate) robots: LostRobots,
    /// Steps 1..=at run with the whole team, steps at+1..=T without the lost robots.
    pub(crate) at: u32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum LostRobots {
    /// This many, drawn from the episode's seed.
    Count(u32),
    /// These robots, by index.
    Which(Vec<u32>),
}

/// Links limited to a radius and/or dropped with a probability per link and step; made only
/// from values `world::Links` accepts.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "LinkValues", into = "LinkValues")]
pub(crate) struct LinkRule(LinkValues);

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LinkValues {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) radius: Option<f64>,
    #[serde(default)]
    pub(crate) drop: f64,
}

impl TryFrom<LinkValues> for LinkRule {
    type Error = world::ParamError;

    fn try_from(values: LinkValues) -> Result<Self, Self::Error> {
        Links::new(values.radius, values.drop, Seed::new(0))?;
        Ok(Self(values))
    }
}

impl From<LinkRule> for LinkValues {
    fn from(rule: LinkRule) -> Self {
        rule.0
    }
}

impl LinkRule {
    fn links(&self, seed: Seed) -> Links {
        Links::new(self.0.radius, self.0.drop, seed).expect("a link rule is checked when made")
    }
}

impl Loss {
    /// The robots of a team of `agents` that this loss stops, in increasing order: the named
    /// ones that exist, or `Count` of them drawn from `seed` (the episode's).
    fn robots(&self, agents: usize, seed: Seed) -> Vec<usize> {
        match &self.robots {
            LostRobots::Which(which) => {
                let mut lost: Vec<usize> = which.iter().map(|&r| r as usize).collect();
                lost.retain(|&r| r < agents);
                lost.sort_unstable();
                lost.dedup();
                lost
            }
            LostRobots::Count(count) => seed
                .child(purpose::LOST_ROBOTS)
                .choose(agents, *count as usize),
        }
    }
}

/// A disturbance as it plays out in one episode: which robots stop when, which links hold.
#[derive(Clone, Debug, PartialEq)]
pub struct EpisodeDisturbance {
    /// The step after which `lost` stop, and the robots; `None` when no robot is lost.
    pub loss: Option<(u32, Vec<usize>)>,
    links: Option<Links>,
}

impl Disturbance {
    /// How many robots every episode loses, when that is fixed (`None` without a loss).
    pub(crate) fn robots_lost(&self) -> Option<u32> {
        self.lose.as_ref().map(|loss| match &loss.robots {
            LostRobots::Count(count) => *count,
            LostRobots::Which(which) => which.len() as u32,
        })
    }

    /// What this disturbance does in the episode of `seed` with `agents` robots.
    pub fn in_episode(&self, agents: usize, seed: Seed) -> EpisodeDisturbance {
        EpisodeDisturbance {
            loss: self
                .lose
                .as_ref()
                .map(|loss| (loss.at, loss.robots(agents, seed))),
            links: self.links.map(|rule| rule.links(seed)),
        }
    }
}

impl EpisodeDisturbance {
    /// Applies what holds from the start (the links), after the episode's reset.
    pub fn start(&self, episode: &mut Episode) {
        if let Some(links) = self.links {
            episode.set_links(links);
        }
    }

    /// Applies what happens once `done` steps have been taken (the loss).
    pub fn after_step(&self, done: usize, episode: &mut Episode) {
        if let Some((at, lost)) = &self.loss
            && *at as usize == done
        {
            for &robot in lost {
                episode.stop(robot);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drawn_losses_are_distinct_seeded_and_named_ones_kept_in_range() {
        let drawn = Loss {
            robots: LostRobots::Count(2),
            at: 5,
        };
        let seed = Seed::new(7);
        let lost = drawn.robots(6, seed);
        assert_eq!(lost.len(), 2);
        assert!(lost[0] < lost[1] && lost[1] < 6, "{lost:?}");
        assert_eq!(lost, drawn.robots(6, seed));
        let many: std::collections::HashSet<Vec<usize>> =
            (0..40).map(|s| drawn.robots(6, Seed::new(s))).collect();
        assert!(many.len() > 5, "the draw depends on the seed: {many:?}");
        let named = Loss {
            robots: LostRobots::Which(vec![3, 1, 9]),
            at: 5,
        };
        assert_eq!(named.robots(4, seed), vec![1, 3]);
    }

    #[test]
    fn link_rules_are_checked_when_read() {
        let good: LinkRule = serde_json::from_str(r#"{"drop": 0.5}"#).unwrap();
        assert_eq!(serde_json::to_string(&good).unwrap(), r#"{"drop":0.5}"#);
        for bad in [r#"{"drop": 1.5}"#, r#"{"radius": -1.0}"#] {
            let error = serde_json::from_str::<LinkRule>(bad).unwrap_err();
            assert!(error.to_string().contains("must"), "{error}");
        }
    }
}
