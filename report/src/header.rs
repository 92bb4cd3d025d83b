//! The report's header: how long and with how many seeds the learned policies trained, set
//! against the paper's budget, how they were tested, what computed the cells and wrote the
//! report, and whether the training runs were still improving when they stopped. Every
//! verdict below is weighed by it: a claim about trained policies judged after 800 episodes,
//! or on runs still learning, says little about the paper's 30,000.

use polars::prelude::*;
use store::schema::{cell, cells, convergence as run, episodes, training};

use super::columns::{
    PolicyKey, distinct, f64s, group_rows, named_seed, optional_u32s, strings, trained_keys,
};
use super::training::{Setting, episodes_per_run};
use super::{PENALTY_UNIT, ReportError, ReportWriter};
use plan::cell::CellConfig;
use stats::{least_squares_slope, summarize};

/// The paper's training budget per learned policy, in episodes.
const PAPER_TRAINING_EPISODES: u64 = 30_000;

/// Training slopes are shown per this many episodes.
const SLOPE_EPISODES: f64 = 100.0;

/// The store's tables the header reads.
pub(crate) struct HeaderTables<'a> {
    /// `None` when the sweep kept no cells table.
    pub(crate) cells: Option<&'a DataFrame>,
    pub(crate) episodes: &'a DataFrame,
    pub(crate) training: Option<&'a DataFrame>,
    /// Where runs trained until converged stopped (`None` for runs of fixed length), and
    /// both their policies' tests.
    pub(crate) convergence: Option<&'a DataFrame>,
    pub(crate) checkpoints: Option<&'a DataFrame>,
    /// Every learned run's failures (`failures::of_runs`), for the convergence table.
    pub(crate) failures: &'a super::failures::RunsFailures,
}

/// The header of a report written by the code at commit `writer`.
pub(crate) fn section(
    report: &mut ReportWriter,
    tables: &HeaderTables,
    writer: &str,
) -> Result<(), ReportError> {
    report.heading(2, "How were the policies trained and tested?");
    let commits = match tables.cells {
        Some(cells) => distinct(strings(cells, cells::GIT_COMMIT)?),
        None => Vec::new(),
    };
    if let Some(warning) = dirty_warning(&commits, writer) {
        report.paragraph(&warning);
    }
    let code = format!(
        "- **Code**: cells computed at {}; this report written at {}.",
        commit_list(&commits),
        commit_list(&[writer.to_owned()])
    );
    let testing = testing_line(tables.episodes)?;
    let lines = match tables.cells {
        Some(cells) => [
            Some(training_line(cells, tables.training)?),
            uniform_attention_line(cells)?,
            Some(testing),
            Some(compute_line(cells, tables.training, tables.convergence)?),
            Some(code),
            Some(format!("- **CPU**: {}.", platforms(cells)?)),
        ]
        .into_iter()
        .flatten()
        .collect(),
        None => vec![
            testing,
            code,
            "- **Cells**: the sweep kept no cells table, so its training runs, CPU time and \
             CPUs are not recorded."
                .to_owned(),
        ],
    };
    report.paragraph(&lines.join("\n"));
    if let Some(convergence) = tables.convergence {
        let (episodes, checkpoints) = (tables.episodes, tables.checkpoints);
        super::convergence::section(report, convergence, episodes, checkpoints, tables.failures)?;
    } else if let Some(training) = tables.training {
        improving_section(report, training)?;
    }
    Ok(())
}

/// A line naming the MA-G-PPO policies whose attention was pushed toward uniform: trained
/// with the attention-entropy bonus of our first reading (a configuration without
/// `attention_entropy_term`), where the released code penalises the entropy of the heads'
/// mean (`docs/released-training.md`). Their runs compared mean pooling, not attention.
fn uniform_attention_line(cells: &DataFrame) -> Result<Option<String>, ReportError> {
    let configs = store::columns::optional_strings(cells, cells::TRAINING_CONFIG)?;
    let policies = strings(cells, cell::POLICY)?;
    let held: Vec<String> = distinct(
        policies
            .into_iter()
            .zip(configs)
            .filter(|(_, config)| config.as_deref().is_some_and(attention_held_uniform))
            .map(|(policy, _)| format!("`{policy}`"))
            .collect::<Vec<String>>(),
    );
    Ok((!held.is_empty()).then(|| {
        format!(
            "- **Attention**: held uniform in {}: trained with an attention-entropy bonus on \
             each head, where the released code penalises the entropy of the heads' mean \
             (docs/released-training.md), which pushes the weights toward even (in rq4's runs \
             their entropy stayed at ln(neighbours)); what these runs compare is mean pooling \
             over the neighbours, not attention.",
            held.join(", ")
        )
    }))
}

/// Whether a training configuration (JSON) is MA-G-PPO's with the entropy bonus.
fn attention_held_uniform(config: &str) -> bool {
    let Ok(config) = serde_json::from_str::<serde_json::Value>(config) else {
        return false;
    };
    config["architecture"] == "ma_g_ppo"
        && config
            .get("attention_entropy_term")
            .is_none_or(|term| term == "bonus")
}

/// A line in bold when a commit had uncommitted changes: no commit holds that code, so its
/// numbers cannot be traced to the repository.
fn dirty_warning(cells: &[String], writer: &str) -> Option<String> {
    let mut what: Vec<String> = (cells.iter())
        .filter(|c| is_dirty(c))
        .map(|c| format!("`{c}` computed cells"))
        .collect();
    if is_dirty(writer) {
        what.push(format!("`{writer}` wrote this report"));
    }
    (!what.is_empty()).then(|| {
        format!(
            "**DIRTY**: {}, from a working tree with uncommitted changes; no commit holds \
             exactly that code.",
            what.join("; ")
        )
    })
}

fn is_dirty(commit: &str) -> bool {
    commit.ends_with("-dirty")
}

fn commit_list(commits: &[String]) -> String {
    if commits.is_empty() {
        return "unrecorded commits".to_owned();
    }
    let named: Vec<String> = commits
        .iter()
        .map(|c| match c.as_str() {
            "" => "an unrecorded commit".to_owned(),
            c if is_dirty(c) => format!("`{c}` (**DIRTY**)"),
            c => format!("`{c}`"),
        })
        .collect();
    named.join(", ")
}

/// Episodes per training run (against the paper's) and runs per learned setting.
fn training_line(cells: &DataFrame, training: Option<&DataFrame>) -> PolarsResult<String> {
    let n_trains = optional_u32s(cells, cell::N_TRAIN)?;
    let learned: Vec<usize> = (0..n_trains.len())
        .filter(|&r| n_trains[r].is_some())
        .collect();
    if learned.is_empty() {
        return Ok(format!(
            "- **Training**: none; every policy is a baseline (the paper trained its learned \
             policies {} episodes).",
            thousands(PAPER_TRAINING_EPISODES)
        ));
    }
    let settings = learned_settings(cells)?;
    let runs: Vec<usize> = settings.iter().map(|(_, rows)| rows.len()).collect();
    let budget = match training {
        Some(training) => episodes_per_policy(training)?,
        None => "not recorded (the sweep kept no training table)".to_owned(),
    };
    Ok(format!(
        "- **Training**: {budget} episodes per training run, against the paper's {} per \
         learned policy; {} training runs (seeds) per learned (map, policy, N_train).",
        thousands(PAPER_TRAINING_EPISODES),
        range(&runs)
    ))
}

/// The cells table's learned rows grouped by (map, policy, N_train).
fn learned_settings(cells: &DataFrame) -> PolarsResult<Vec<(Setting, Vec<usize>)>> {
    let (maps, policies) = (strings(cells, cell::MAP)?, strings(cells, cell::POLICY)?);
    let n_trains = optional_u32s(cells, cell::N_TRAIN)?;
    let keys: Vec<Option<Setting>> = (0..cells.height())
        .map(|r| {
            n_trains[r].map(|n| {
                let policy = PolicyKey {
                    policy: policies[r].clone(),
                    n_train: Some(n),
                };
                (maps[r].clone(), policy)
            })
        })
        .collect();
    Ok(group_rows(&keys)
        .into_iter()
        .filter_map(|(key, rows)| key.map(|k| (k, rows)))
        .collect())
}

/// "800" when every learned policy's runs are that long, else "800 (ma-g-ppo), 400 (ma-ppo)".
fn episodes_per_policy(training: &DataFrame) -> PolarsResult<String> {
    let per_run = episodes_per_run(training)?;
    let all: Vec<usize> = per_run.iter().map(|(_, n)| *n).collect();
    if distinct(all.iter().copied()).len() == 1 {
        return Ok(thousands(all[0] as u64));
    }
    let labels: Vec<String> = distinct(per_run.iter().map(|((_, p), _)| p.policy.clone()));
    let parts: Vec<String> = labels
        .iter()
        .map(|label| {
            let of: Vec<usize> = per_run
                .iter()
                .filter(|((_, p), _)| &p.policy == label)
                .map(|(_, n)| *n)
                .collect();
            format!("{} ({label})", range(&of))
        })
        .collect();
    Ok(parts.join(", "))
}

/// Test episodes per cell and N_test, and T, from the episodes table.
fn testing_line(episodes: &DataFrame) -> Result<String, ReportError> {
    let keys = strings(episodes, cell::KEY)?;
    let n_tests = optional_u32s(episodes, episodes::N_TEST)?;
    let plays: Vec<(&String, Option<u32>)> = keys.iter().zip(n_tests).collect();
    let counts: Vec<usize> = group_rows(&plays)
        .into_iter()
        .map(|(_, rows)| rows.len())
        .collect();
    let steps: Vec<usize> = f64s(episodes, episodes::STEPS)?
        .into_iter()
        .map(|s| s as usize)
        .collect();
    Ok(format!(
        "- **Testing**: {} test episodes per cell and N_test, each of T = {} steps.",
        range(&counts),
        range(&steps)
    ))
}

/// What the cells cost, measured, beside what `harness check`'s model estimated for the same
/// cells (each with its training, from its stored configuration), so that a reader sees how
/// far the estimate that budgeted the sweep was from the bill. A cell that took its training
/// run from the cache records only its tests, so the training runs' own wall time (their logs'
/// last) is given too: without it a question whose runs another sweep trained looks cheap.
/// Cells and logs keep wall time, which is a cell's CPU time only on an idle core, so it is
/// called wall time; runs until converged also keep their training thread's own CPU clock
/// (the convergence table's), given beside it.
fn compute_line(
    cells: &DataFrame,
    training: Option<&DataFrame>,
    convergence: Option<&DataFrame>,
) -> PolarsResult<String> {
    let seconds: f64 = f64s(cells, cells::WALL_SECONDS)?.iter().sum();
    let estimated = strings(cells, cells::CONFIG)?
        .iter()
        .map(|config| serde_json::from_str::<CellConfig>(config).map(|c| c.cost().cpu_seconds()))
        .sum::<Result<f64, _>>();
    let estimate = match estimated {
        Ok(estimated) => format!(
            "; `harness check` estimated {:.2} CPU hours for the cells, each with its training",
            estimated / 3600.0
        ),
        Err(_) => String::new(),
    };
    let runs = match training {
        Some(training) => training_runs_clause(training)?,
        None => String::new(),
    };
    let cpu = match convergence {
        Some(convergence) => converged_cpu_clause(convergence)?,
        None => String::new(),
    };
    let cache = match runs.is_empty() {
        true => "",
        false => {
            "; a cell whose training run the cache gave, trained by another sweep, counts \
                  only its tests"
        }
    };
    Ok(format!(
        "- **Compute**: {:.2} hours ({seconds:.0} s) of wall time, the {} cells' summed (a \
         cell runs on one thread: its wall time is its CPU time on an idle core, more beside \
         other jobs{cache}){runs}{cpu}{estimate}.",
        seconds / 3600.0,
        cells.height()
    ))
}

/// "...; the 48 training runs took 7.18 hours of wall time by their logs": a run's wall time
/// is its log's last (the log counts from the run's start, across resumes); one cell holds one
/// run.
fn training_runs_clause(training: &DataFrame) -> PolarsResult<String> {
    let by_setting = super::training_run_seconds(training)?;
    let runs: Vec<f64> = by_setting.into_values().flatten().collect();
    Ok(match runs.len() {
        0 => String::new(),
        n => format!(
            "; the {n} training runs took {:.2} hours of wall time by their logs",
            runs.iter().sum::<f64>() / 3600.0
        ),
    })
}

/// "...; the 28 runs until converged took 4.52 CPU hours to their stops by their training
/// threads' own clock (validations and tests not counted)".
fn converged_cpu_clause(convergence: &DataFrame) -> PolarsResult<String> {
    let cpu = f64s(convergence, run::CPU_SECONDS)?;
    Ok(match cpu.len() {
        0 => String::new(),
        n => format!(
            "; the {n} runs until converged took {:.2} CPU hours to their stops by their \
             training threads' own clock (validations and tests not counted)",
            cpu.iter().sum::<f64>() / 3600.0
        ),
    })
}

/// Each CPU and kernel build with its count of cells: equal bits on every machine are the
/// claim, and the report names the machines. Where cells ran on more than one, each but the
/// one that ran most says which cells it ran, so a reader can tell whose CPU time (and whose
/// wall time, run beside how many others) a row's record holds.
fn platforms(cells: &DataFrame) -> PolarsResult<String> {
    let (cpus, kernels) = (strings(cells, cells::CPU)?, strings(cells, cells::KERNELS)?);
    let platforms: Vec<String> = cpus
        .iter()
        .zip(&kernels)
        .map(|(cpu, kernels)| match (cpu.as_str(), kernels.as_str()) {
            ("", _) => "an unrecorded CPU".to_owned(),
            (cpu, kernels) => format!("{cpu} with {kernels} kernels"),
        })
        .collect();
    let settings: Vec<String> = trained_keys(cells)?
        .into_iter()
        .map(|(map, policy)| format!("{map} {}", policy.label()))
        .collect();
    Ok(platform_counts(&platforms, &settings))
}

/// "80 cells on A" for one platform; for several, "75 cells on A (the others); 5 cells on B
/// (eight_room ma-g-ppo (N_train=2): 5)", the platform that ran most cells first.
fn platform_counts(platforms: &[String], settings: &[String]) -> String {
    let mut groups = group_rows(platforms);
    // Stable: platforms with as many cells keep their order of first appearance.
    groups.sort_by_key(|(_, rows)| std::cmp::Reverse(rows.len()));
    let several = groups.len() > 1;
    groups
        .iter()
        .enumerate()
        .map(|(i, (platform, rows))| {
            let cells = match rows.len() {
                1 => "1 cell".to_owned(),
                n => format!("{n} cells"),
            };
            let counted = format!("{cells} on {platform}");
            match (several, i) {
                (false, _) => counted,
                (true, 0) => format!("{counted} (the others)"),
                (true, _) => {
                    let which: Vec<&String> = rows.iter().map(|&row| &settings[row]).collect();
                    let listed: Vec<String> = group_rows(&which)
                        .into_iter()
                        .map(|(setting, rows)| format!("{setting}: {}", rows.len()))
                        .collect();
                    format!("{counted} ({})", listed.join(", "))
                }
            }
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// "3" for equal values, "2 to 3" otherwise.
fn range(values: &[usize]) -> String {
    let (low, high) = (values.iter().min(), values.iter().max());
    match (low, high) {
        (Some(low), Some(high)) if low == high => thousands(*low as u64),
        (Some(low), Some(high)) => {
            format!("{} to {}", thousands(*low as u64), thousands(*high as u64))
        }
        _ => "no".to_owned(),
    }
}

/// 30000 as "30,000".
fn thousands(value: u64) -> String {
    let digits = value.to_string();
    let mut text = String::new();
    for (i, digit) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            text.push(',');
        }
        text.push(digit);
    }
    text
}

/// One training run's penalties in episode order.
struct Run {
    episode: Vec<f64>,
    penalty: Vec<f64>,
}

impl Run {
    /// The last quarter of the run, at least two episodes (none for a run of one).
    fn last_quarter(&self) -> usize {
        let n = self.episode.len();
        if n < 2 { 0 } else { n.div_ceil(4).max(2) }
    }

    /// The least-squares slope of the penalty over the last quarter, per episode.
    fn slope(&self) -> Option<f64> {
        let window = self.last_quarter();
        let start = self.episode.len() - window;
        least_squares_slope(&self.episode[start..], &self.penalty[start..])
    }
}

/// Whether the runs of one learned setting were still improving: the verdict of the
/// interval of their mean slope.
fn trend(slopes: &[f64], low: f64, high: f64) -> &'static str {
    match slopes.len() {
        0 => "too short",
        1 => "one run: no interval",
        _ if high < 0.0 => "still improving",
        _ if low > 0.0 => "worse",
        _ => "flat",
    }
}

/// The training table's runs, grouped by learned setting in order.
fn runs_by_setting(training: &DataFrame) -> PolarsResult<Vec<(Setting, Vec<Run>)>> {
    let keys = strings(training, cell::KEY)?;
    let (episodes, penalties) = (
        f64s(training, training::EPISODE)?,
        f64s(training, training::PENALTY)?,
    );
    let settings: Vec<Setting> = trained_keys(training)?;
    let run = |rows: &[usize]| {
        let mut points: Vec<(f64, f64)> =
            rows.iter().map(|&r| (episodes[r], penalties[r])).collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        Run {
            episode: points.iter().map(|p| p.0).collect(),
            penalty: points.iter().map(|p| p.1).collect(),
        }
    };
    Ok(group_rows(&settings)
        .into_iter()
        .map(|(setting, rows)| {
            let of_run: Vec<&String> = rows.iter().map(|&r| &keys[r]).collect();
            let runs = group_rows(&of_run)
                .into_iter()
                .map(|(_, within)| run(&within.iter().map(|&i| rows[i]).collect::<Vec<_>>()))
                .collect();
            (setting, runs)
        })
        .collect())
}

/// One row of the improving table: a learned setting's runs and the trend of their slopes.
struct Improving {
    setting: Setting,
    runs: u32,
    /// The shortest run's episodes and last quarter.
    episodes: u32,
    last_quarter: u32,
    /// The mean slope, 10^6 per [`SLOPE_EPISODES`] episodes; `None` when no run has one.
    slope: Option<f64>,
    /// Its interval over runs; `None` with fewer than two runs.
    interval: Option<(f64, f64)>,
    trend: &'static str,
}

impl Improving {
    fn of(setting: Setting, runs: &[Run]) -> Result<Self, ReportError> {
        let per_run: Vec<f64> = (runs.iter())
            .filter_map(Run::slope)
            .map(|s| s * SLOPE_EPISODES / PENALTY_UNIT)
            .collect();
        let (map, policy) = &setting;
        let name = format!(
            "improving\0{map}\0{}\0{}",
            policy.policy,
            policy.n_train.unwrap_or(0)
        );
        let summary = if per_run.is_empty() {
            None
        } else {
            Some(summarize(&per_run, named_seed(&name))?)
        };
        let interval = summary
            .filter(|_| per_run.len() > 1)
            .map(|s| (s.low, s.high));
        let (low, high) = interval.unwrap_or((0.0, 0.0));
        let shortest = runs.iter().min_by_key(|r| r.episode.len());
        Ok(Self {
            runs: runs.len() as u32,
            episodes: shortest.map_or(0, |r| r.episode.len() as u32),
            last_quarter: shortest.map_or(0, |r| r.last_quarter() as u32),
            slope: summary.map(|s| s.mean),
            interval,
            trend: trend(&per_run, low, high),
            setting,
        })
    }
}

/// The table of whether each learned setting's runs were still improving.
fn improving_frame(training: &DataFrame) -> Result<DataFrame, ReportError> {
    let rows: Vec<Improving> = runs_by_setting(training)?
        .into_iter()
        .map(|(setting, runs)| Improving::of(setting, &runs))
        .collect::<Result<_, _>>()?;
    let count = |f: fn(&Improving) -> u32| rows.iter().map(f).collect::<Vec<u32>>();
    let value = |f: fn(&Improving) -> Option<f64>| rows.iter().map(f).collect::<Vec<_>>();
    Ok(df!(
        "map" => rows.iter().map(|r| r.setting.0.as_str()).collect::<Vec<_>>(),
        "policy" => rows.iter().map(|r| r.setting.1.policy.as_str()).collect::<Vec<_>>(),
        "n_train" => rows.iter().map(|r| r.setting.1.n_train).collect::<Vec<_>>(),
        "runs" => count(|r| r.runs),
        "episodes" => count(|r| r.episodes),
        "last_quarter" => count(|r| r.last_quarter),
        "slope" => value(|r| r.slope),
        "slope_ci_low" => value(|r| r.interval.map(|i| i.0)),
        "slope_ci_high" => value(|r| r.interval.map(|i| i.1)),
        "trend" => rows.iter().map(|r| r.trend).collect::<Vec<_>>(),
    )?)
}

fn improving_section(report: &mut ReportWriter, training: &DataFrame) -> Result<(), ReportError> {
    report.heading(
        3,
        "Were the training runs still improving when they stopped?",
    );
    report.paragraph(
        "For each learned (map, policy, N_train): the least-squares slope of each training \
         run's training penalty over its last quarter of episodes (`last_quarter`, at least \
         two), in 10^6 per 100 episodes; `slope` is their mean over the runs, with its 95 % \
         interval over runs (`stats::summarize`). *still improving*: the interval lies \
         below 0 (the penalty was still falling, so longer training may change the verdicts \
         below); *flat*: it holds 0; *worse*: it lies above 0. One run gives no interval. \
         The episodes of one round are played in parallel by one policy, so a run of a few \
         rounds has little trend to measure.",
    );
    let frame = improving_frame(training)?;
    report.table("improving", &frame)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_quarter_has_two_episodes_at_least() {
        let run = |n: usize| Run {
            episode: (0..n).map(|e| e as f64).collect(),
            penalty: (0..n).map(|e| 10.0 - e as f64).collect(),
        };
        assert_eq!(run(800).last_quarter(), 200);
        assert_eq!(run(8).last_quarter(), 2);
        assert_eq!(run(5).last_quarter(), 2);
        assert_eq!(run(1).last_quarter(), 0);
        assert_eq!(run(1).slope(), None);
        assert_eq!(run(8).slope(), Some(-1.0));
    }

    #[test]
    fn trends_read_the_interval() {
        assert_eq!(trend(&[-2.0, -1.0], -2.0, -1.0), "still improving");
        assert_eq!(trend(&[-2.0, 1.0], -2.0, 1.0), "flat");
        assert_eq!(trend(&[1.0, 2.0], 1.0, 2.0), "worse");
        assert_eq!(trend(&[-1.0], -1.0, -1.0), "one run: no interval");
        assert_eq!(trend(&[], 0.0, 0.0), "too short");
    }

    #[test]
    fn the_cells_of_each_lesser_platform_are_named() {
        let owned = |items: &[&str]| items.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let platforms = owned(&["amd", "xeon", "amd", "xeon", "amd", "arm"]);
        let settings = owned(&[
            "a gcs",
            "a p (N_train=2)",
            "a gcs",
            "a p (N_train=2)",
            "b gcs",
            "b p (N_train=4)",
        ]);
        assert_eq!(
            platform_counts(&platforms, &settings),
            "3 cells on amd (the others); 2 cells on xeon (a p (N_train=2): 2); \
             1 cell on arm (b p (N_train=4): 1)"
        );
        let one = owned(&["amd", "amd"]);
        assert_eq!(platform_counts(&one, &settings[..2]), "2 cells on amd");
    }

    #[test]
    fn each_training_run_costs_its_logs_last_wall_time() {
        let training = df!(
            cell::KEY => ["a", "a", "b", "b", "b"],
            cell::MAP => ["open"; 5],
            cell::POLICY => ["ma-g-ppo"; 5],
            cell::N_TRAIN => [4u32; 5],
            training::WALL_SECONDS => [1.0, 3600.0, 2.0, 5000.0, 7200.0],
        )
        .unwrap();
        let line = training_runs_clause(&training).unwrap();
        assert!(
            line.ends_with("the 2 training runs took 3.00 hours of wall time by their logs"),
            "{line}"
        );
        assert_eq!(training_runs_clause(&training.head(Some(0))).unwrap(), "");
    }

    /// Runs until converged keep their training thread's CPU clock: the header sums it,
    /// called CPU, beside the wall times.
    #[test]
    fn runs_until_converged_give_their_threads_cpu_time() {
        let convergence = df!(run::CPU_SECONDS => [1800.0, 5400.0]).unwrap();
        let clause = converged_cpu_clause(&convergence).unwrap();
        assert_eq!(
            clause,
            "; the 2 runs until converged took 2.00 CPU hours to their stops by their training \
             threads' own clock (validations and tests not counted)"
        );
        assert_eq!(
            converged_cpu_clause(&convergence.head(Some(0))).unwrap(),
            ""
        );
    }

    #[test]
    fn dirty_commits_are_named() {
        let cells = ["abc".to_owned(), "def-dirty".to_owned()];
        let warning = dirty_warning(&cells, "ghi").unwrap();
        assert!(warning.starts_with("**DIRTY**: `def-dirty` computed cells,"));
        assert_eq!(dirty_warning(&cells[..1], "ghi"), None);
        assert!(
            dirty_warning(&[], "x-dirty")
                .unwrap()
                .contains("`x-dirty` wrote this report")
        );
        assert_eq!(commit_list(&cells), "`abc`, `def-dirty` (**DIRTY**)");
    }

    #[test]
    fn numbers_get_thousands_separators() {
        assert_eq!(thousands(30_000), "30,000");
        assert_eq!(thousands(800), "800");
        assert_eq!(thousands(1_234_567), "1,234,567");
        assert_eq!(range(&[2, 3, 2]), "2 to 3");
        assert_eq!(range(&[3, 3]), "3");
    }

    #[test]
    fn only_ma_g_ppo_with_the_entropy_bonus_is_held_uniform() {
        assert!(attention_held_uniform(r#"{"architecture":"ma_g_ppo"}"#));
        let bonus = r#"{"architecture":"ma_g_ppo","attention_entropy_term":"bonus"}"#;
        assert!(attention_held_uniform(bonus));
        let released = r#"{"architecture":"ma_g_ppo","attention_entropy_term":"penalty"}"#;
        assert!(!attention_held_uniform(released));
        assert!(!attention_held_uniform(r#"{"architecture":"ma_ppo"}"#));
        assert!(!attention_held_uniform("not json"));
    }
}
