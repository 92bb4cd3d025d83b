//! The scenario's disturbances, checked at load against its test episodes and team sizes.

use std::path::Path;

use serde_saphyr::Spanned;

use super::error::ScenarioError;
use super::format::{DisturbanceSpec, LinksSpec, LoseSpec};
use crate::disturbance::{Disturbance, LinkRule, LinkValues, Loss, LostRobots, UNDISTURBED};

pub(crate) fn check_disturbances(
    specs: &Spanned<Vec<Spanned<DisturbanceSpec>>>,
    test_steps: u32,
    test_agents: &[u32],
    file: &Path,
) -> Result<Vec<Disturbance>, ScenarioError> {
    let smallest = test_agents.iter().copied().min().unwrap_or(0);
    let mut checked: Vec<Disturbance> = Vec::new();
    for (i, spec) in specs.value.iter().enumerate() {
        let field = format!("disturbances[{i}]");
        let spec = &spec.value;
        let name = &spec.name;
        let fail = |value_field: &str, problem: String| {
            ScenarioError::at(file, name, &format!("{field}{value_field}"), problem)
        };
        let usable = !name.value.is_empty()
            && name.value != UNDISTURBED
            && (name.value.chars()).all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
        if !usable {
            let problem = format!(
                "{:?} is not a usable name (letters, digits, '-' and '_'; not {UNDISTURBED:?})",
                name.value
            );
            return Err(fail(".name", problem));
        }
        if checked.iter().any(|d| d.name == name.value) {
            return Err(fail(
                ".name",
                format!("a second disturbance named {:?}", name.value),
            ));
        }
        if spec.lose.is_none() && spec.links.is_none() {
            return Err(fail("", "give lose, links or both".to_owned()));
        }
        let lose = spec
            .lose
            .as_ref()
            .map(|lose| check_loss(lose, test_steps, smallest, &field, file))
            .transpose()?;
        let links = spec
            .links
            .as_ref()
            .map(|links| check_links(links, &field, file))
            .transpose()?;
        checked.push(Disturbance {
            name: name.value.clone(),
            lose,
            links,
        });
    }
    Ok(checked)
}

/// A loss after a step inside the episode, of fewer robots than the smallest test team.
fn check_loss(
    spec: &Spanned<LoseSpec>,
    test_steps: u32,
    smallest: u32,
    field: &str,
    file: &Path,
) -> Result<Loss, ScenarioError> {
    let at = &spec.value.at;
    if at.value == 0 || at.value >= test_steps {
        let problem = format!(
            "step {} is not inside the test episode (1 to {}, as world.test_steps is {test_steps})",
            at.value,
            test_steps.saturating_sub(1)
        );
        return Err(ScenarioError::at(
            file,
            at,
            &format!("{field}.lose.at"),
            problem,
        ));
    }
    let robots = match (&spec.value.robots, &spec.value.which) {
        (Some(count), None) => {
            if count.value == 0 || count.value >= smallest {
                let problem = format!(
                    "{} robots: lose at least 1 and fewer than the smallest test team ({smallest})",
                    count.value
                );
                let field = format!("{field}.lose.robots");
                return Err(ScenarioError::at(file, count, &field, problem));
            }
            LostRobots::Count(count.value)
        }
        (None, Some(which)) => {
            let mut sorted = which.value.clone();
            sorted.sort_unstable();
            sorted.dedup();
            let problem = if sorted.is_empty() {
                Some("the list is empty".to_owned())
            } else if sorted.len() != which.value.len() {
                Some("a robot is listed twice".to_owned())
            } else if sorted.last().is_some_and(|&r| r >= smallest)
                || sorted.len() as u32 >= smallest
            {
                Some(format!(
                    "robots {:?}: indices below the smallest test team ({smallest}), and fewer of them",
                    which.value
                ))
            } else {
                None
            };
            if let Some(problem) = problem {
                let field = format!("{field}.lose.which");
                return Err(ScenarioError::at(file, which, &field, problem));
            }
            LostRobots::Which(which.value.clone())
        }
        _ => {
            let problem = "give robots (how many) or which (by index), not both".to_owned();
            return Err(ScenarioError::at(
                file,
                spec,
                &format!("{field}.lose"),
                problem,
            ));
        }
    };
    Ok(Loss {
        robots,
        at: at.value,
    })
}

fn check_links(
    spec: &Spanned<LinksSpec>,
    field: &str,
    file: &Path,
) -> Result<LinkRule, ScenarioError> {
    let (radius, drop) = (&spec.value.radius, &spec.value.drop);
    if radius.is_none() && drop.is_none() {
        let problem = "give radius, drop or both".to_owned();
        return Err(ScenarioError::at(
            file,
            spec,
            &format!("{field}.links"),
            problem,
        ));
    }
    let values = |radius: Option<f64>, drop: f64| LinkRule::try_from(LinkValues { radius, drop });
    if let Some(r) = radius
        && let Err(e) = values(Some(r.value), 0.0)
    {
        return Err(ScenarioError::at(
            file,
            r,
            &format!("{field}.links.radius"),
            e,
        ));
    }
    if let Some(d) = drop
        && let Err(e) = values(None, d.value)
    {
        return Err(ScenarioError::at(
            file,
            d,
            &format!("{field}.links.drop"),
            e,
        ));
    }
    Ok(values(
        radius.as_ref().map(|r| r.value),
        drop.as_ref().map_or(0.0, |d| d.value),
    )
    .expect("each value was checked"))
}
