//! A cell's title, what it is without its key ("open ma-g-ppo@fast-v2-hl300 N_train=2 rep 6"),
//! and its setting and repetition read back from one. The sweep writes titles into its record
//! (`sweep.json`'s labels), and a report groups a setting's repetitions not run by reading them
//! back: both sides are here, so the format cannot change under one of them.

use crate::cell::CellConfig;

/// Between a title's setting and its repetition.
const REPETITION: &str = " rep ";

/// Map, policy, N_train and repetition.
pub fn title(cell: &CellConfig) -> String {
    let n_train = cell
        .n_train
        .map_or(String::new(), |n| format!(" N_train={n}"));
    let setting = format!("{} {}{n_train}", cell.map.name, cell.policy.label());
    format!("{setting}{REPETITION}{}", cell.repetition)
}

/// A [`title`]'s setting (map, policy, N_train) and repetition; `None` for any other text.
pub fn setting_and_repetition(title: &str) -> Option<(&str, u32)> {
    let (setting, repetition) = title.rsplit_once(REPETITION)?;
    Some((setting, repetition.parse().ok()?))
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::scenario::Scenario;

    #[test]
    fn a_title_reads_back_as_its_setting_and_repetition() {
        let text = "name: t\nseed: 1\nmaps:\n  - inline: {name: a, grid: \"....\\n....\\n\"}\n\
                    world: {fov: 3, train_steps: 4, test_steps: 4}\npolicies:\n  \
                    - ma-g-ppo: {profile: fast-v2, episodes: 10, set: {network: compact}}\n  - baseline: {name: random}\n\
                    agents: {train: [2], test: [2]}\nrepetitions: 12\ntest_episodes: 1\n";
        let scenario = Scenario::parse(text, Path::new("t.yaml")).unwrap();
        let titles: Vec<String> = scenario.cells().iter().map(|c| title(&c.config)).collect();
        assert!(titles.contains(&"a ma-g-ppo@fast-v2 N_train=2 rep 11".to_owned()));
        assert!(titles.contains(&"a random rep 0".to_owned()));
        for (cell, title) in scenario.cells().iter().zip(&titles) {
            let (setting, repetition) = setting_and_repetition(title).unwrap();
            assert_eq!(repetition, cell.config.repetition, "{title}");
            assert!(title.starts_with(setting), "{title}");
        }
        assert_eq!(setting_and_repetition("a random rep x"), None);
        assert_eq!(setting_and_repetition("a random"), None);
    }
}
