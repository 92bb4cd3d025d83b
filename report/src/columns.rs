//! Reading the store's tables column by column, and the key every report groups by.

use polars::prelude::*;
use store::schema::{cell, episodes};

pub(crate) use store::columns::{f64s, optional_u32s, strings, u32s};

/// A policy as the tables name it: its label and, for a learned one, its N_train.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) struct PolicyKey {
    pub(crate) policy: String,
    pub(crate) n_train: Option<u32>,
}

impl PolicyKey {
    pub(crate) fn label(&self) -> String {
        match self.n_train {
            Some(n) => format!("{} (N_train={n})", self.policy),
            None => self.policy.clone(),
        }
    }
}

/// Every row's map and policy (with its N_train), in row order: what the tables of training
/// runs (the training log, the test curve) group by, and the first part of a `GroupKey`.
pub(crate) fn trained_keys(frame: &DataFrame) -> PolarsResult<Vec<(String, PolicyKey)>> {
    let maps = strings(frame, cell::MAP)?;
    let policies = strings(frame, cell::POLICY)?;
    let n_trains = optional_u32s(frame, cell::N_TRAIN)?;
    Ok(maps
        .into_iter()
        .zip(policies)
        .zip(n_trains)
        .map(|((map, policy), n_train)| (map, PolicyKey { policy, n_train }))
        .collect())
}

/// The rows of one (map, policy, N_train, N_test), the unit of the summary.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) struct GroupKey {
    pub(crate) map: String,
    pub(crate) policy: PolicyKey,
    pub(crate) n_test: u32,
}

impl GroupKey {
    /// Every row's group, in row order.
    pub(crate) fn of_rows(frame: &DataFrame) -> PolarsResult<Vec<GroupKey>> {
        let n_tests = u32s(frame, episodes::N_TEST)?;
        Ok(trained_keys(frame)?
            .into_iter()
            .zip(n_tests)
            .map(|((map, policy), n_test)| GroupKey {
                map,
                policy,
                n_test,
            })
            .collect())
    }

    pub(crate) fn label(&self) -> String {
        format!(
            "{}, {}, N_test={}",
            self.map,
            self.policy.label(),
            self.n_test
        )
    }

    pub(crate) fn stem(&self) -> Vec<String> {
        let mut parts = vec![self.map.clone(), self.policy.policy.clone()];
        if let Some(n) = self.policy.n_train {
            parts.push(format!("train{n}"));
        }
        parts.push(format!("test{}", self.n_test));
        parts
    }
}

pub(crate) use stats::grouping::{distinct, group_rows};
pub(crate) use stats::named_seed;
