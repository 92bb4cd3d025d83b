//! Emergent behaviour measured (RQ3): per agent the dominant period of its motion (the
//! periodogram's peak), its phase against agent 0 (a least-squares harmonic fit at the team's
//! period, with smartcore), and its role, stationary or touring (k-means on motion features
//! with linfa, seeded), so the report states as numbers what the paper saw in plots.

use linfa::DatasetBase;
use linfa::traits::{Fit, Predict};
use linfa_clustering::KMeans;
use ndarray::Array2;
use polars::prelude::*;
use rand_core_06::SeedableRng;
use smartcore::linalg::basic::arrays::Array;
use smartcore::linalg::basic::matrix::DenseMatrix;
use smartcore::linear::linear_regression::{LinearRegression, LinearRegressionParameters};

use super::columns::{distinct, named_seed};
use super::markdown::number;
use super::motion::{Motion, distance_from_centre};
use super::{ReportError, ReportWriter};

/// Periods shorter than this many steps are not looked for: a step's jitter, not a rhythm.
const SHORTEST_PERIOD: usize = 20;
/// A period must repeat at least this often within the episode.
const FEWEST_CYCLES: usize = 2;

/// A signal's fitted harmonic `amplitude * cos(2 pi t / period - phase) + offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Harmonic {
    amplitude: f64,
    /// Radians.
    phase: f64,
    /// The share of the signal's variance the harmonic explains.
    r_squared: f64,
}

/// The period (in steps) of the strongest frequency of `signal`'s periodogram, between
/// [`FEWEST_CYCLES`] cycles per episode and [`SHORTEST_PERIOD`] steps; `None` for a signal
/// without variation or too short to hold two such cycles.
fn dominant_period(signal: &[f64]) -> Option<f64> {
    let n = signal.len();
    let mean = signal.iter().sum::<f64>() / n.max(1) as f64;
    let centred: Vec<f64> = signal.iter().map(|v| v - mean).collect();
    if centred.iter().all(|v| v.abs() < 1e-12) {
        return None;
    }
    let power = |k: usize| {
        let omega = std::f64::consts::TAU * k as f64 / n as f64;
        let (re, im) = centred
            .iter()
            .enumerate()
            .fold((0.0, 0.0), |(re, im), (t, v)| {
                let angle = omega * t as f64;
                (re + v * angle.cos(), im - v * angle.sin())
            });
        re * re + im * im
    };
    (FEWEST_CYCLES..=n / SHORTEST_PERIOD)
        .map(|k| (k, power(k)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| n as f64 / k as f64)
}

/// Least-squares fit of `a cos(w t) + b sin(w t) + c` with `w = 2 pi / period`.
fn fit_harmonic(signal: &[f64], period: f64) -> Option<Harmonic> {
    let omega = std::f64::consts::TAU / period;
    let rows: Vec<Vec<f64>> = (0..signal.len())
        .map(|t| vec![(omega * t as f64).cos(), (omega * t as f64).sin()])
        .collect();
    let x = DenseMatrix::from_2d_vec(&rows).ok()?;
    let y = signal.to_vec();
    let model: LinearRegression<f64, f64, DenseMatrix<f64>, Vec<f64>> =
        LinearRegression::fit(&x, &y, LinearRegressionParameters::default()).ok()?;
    let (a, b) = (
        *model.coefficients().get((0, 0)),
        *model.coefficients().get((1, 0)),
    );
    let fitted = model.predict(&x).ok()?;
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let total: f64 = y.iter().map(|v| (v - mean).powi(2)).sum();
    let residual: f64 = y.iter().zip(&fitted).map(|(v, f)| (v - f).powi(2)).sum();
    Some(Harmonic {
        amplitude: a.hypot(b),
        phase: b.atan2(a),
        r_squared: if total > 0.0 {
            1.0 - residual / total
        } else {
            0.0
        },
    })
}

/// An angle difference in degrees, wrapped into (-180, 180].
fn wrapped_degrees(radians: f64) -> f64 {
    let degrees = radians.to_degrees().rem_euclid(360.0);
    if degrees > 180.0 {
        degrees - 360.0
    } else {
        degrees
    }
}

/// One agent's rhythm in one signal.
struct Rhythm {
    motion: usize,
    agent: usize,
    signal: &'static str,
    period: Option<f64>,
    team_period: Option<f64>,
    harmonic: Option<Harmonic>,
    phase_to_agent_0: Option<f64>,
}

fn rhythms(motions: &[Motion]) -> Vec<Rhythm> {
    (motions.iter().enumerate())
        .flat_map(|(index, motion)| motion_rhythms(index, motion))
        .collect()
}

/// The rhythms of every agent of one motion, `motions[index]`.
fn motion_rhythms(index: usize, motion: &Motion) -> Vec<Rhythm> {
    let mut rows = Vec::new();
    for (signal, values) in motion.signals() {
        let periods: Vec<Option<f64>> = values.iter().map(|v| dominant_period(v)).collect();
        let found: Vec<f64> = periods.iter().flatten().copied().collect();
        let team_period = stats::median(&found).ok();
        let harmonics: Vec<Option<Harmonic>> = values
            .iter()
            .map(|v| team_period.and_then(|p| fit_harmonic(v, p)))
            .collect();
        for agent in 0..motion.agents {
            let phase = match (harmonics[0], harmonics[agent]) {
                (Some(first), Some(this)) => Some(wrapped_degrees(this.phase - first.phase)),
                _ => None,
            };
            rows.push(Rhythm {
                motion: index,
                agent,
                signal,
                period: periods[agent],
                team_period,
                harmonic: harmonics[agent],
                phase_to_agent_0: phase,
            });
        }
    }
    rows
}

/// Motion features of one agent, for the roles.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Features {
    /// Root mean square distance from its own mean position (cells).
    radius_of_gyration: f64,
    /// Share of steps in which it changed cell.
    moving_share: f64,
    /// Mean distance from the map's centre (cells): where the agent keeps, which the paper's
    /// open map with four agents describes ("one agent at the centre", "the other three ...
    /// around the periphery"). Not a feature of the roles, which say how an agent moves.
    centre_distance: f64,
}

fn features(x: &[f64], y: &[f64], centre: (f64, f64)) -> Features {
    let n = x.len().max(1) as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let spread = x
        .iter()
        .zip(y)
        .map(|(a, b)| (a - mx).powi(2) + (b - my).powi(2))
        .sum::<f64>()
        / n;
    let moves = x
        .windows(2)
        .zip(y.windows(2))
        .filter(|(a, b)| a[0] != a[1] || b[0] != b[1])
        .count();
    let from_centre = x
        .iter()
        .zip(y)
        .map(|(&a, &b)| distance_from_centre(a, b, centre));
    Features {
        radius_of_gyration: spread.sqrt(),
        moving_share: moves as f64 / (x.len().max(2) - 1) as f64,
        centre_distance: from_centre.sum::<f64>() / n,
    }
}

/// What an agent does over a recorded episode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    /// Keeps near one place (the smaller cluster of radius of gyration).
    Stationary,
    Touring,
}

impl Role {
    /// The role as the roles table and the statements name it.
    fn name(self) -> &'static str {
        match self {
            Role::Stationary => "stationary",
            Role::Touring => "touring",
        }
    }
}

/// Roles of every agent of `motions` on one map: 2-means on the standardised features of all
/// its agents (every policy and N_test), the cluster of smaller mean radius of gyration being
/// "stationary". With fewer than two distinct feature vectors every agent is "touring".
fn roles(features: &[Features], seed: u64) -> Vec<Role> {
    let distinct_points = distinct(
        features
            .iter()
            .map(|f| (f.radius_of_gyration.to_bits(), f.moving_share.to_bits())),
    );
    if distinct_points.len() < 2 {
        return vec![Role::Touring; features.len()];
    }
    let columns = [
        standardised(features.iter().map(|f| f.radius_of_gyration).collect()),
        standardised(features.iter().map(|f| f.moving_share).collect()),
    ];
    let data = Array2::from_shape_fn((features.len(), 2), |(i, j)| columns[j][i]);
    let dataset = DatasetBase::from(data.clone());
    let rng = rand_pcg_03::Pcg64Mcg::seed_from_u64(seed);
    let Ok(model) = KMeans::params_with_rng(2, rng).fit(&dataset) else {
        return vec![Role::Touring; features.len()];
    };
    let labels = model.predict(&data);
    let spread_of = |cluster: usize| {
        let members: Vec<f64> = labels
            .iter()
            .zip(features)
            .filter(|(l, _)| **l == cluster)
            .map(|(_, f)| f.radius_of_gyration)
            .collect();
        members.iter().sum::<f64>() / members.len().max(1) as f64
    };
    let stationary = if spread_of(0) <= spread_of(1) { 0 } else { 1 };
    labels
        .iter()
        .map(|&l| {
            if l == stationary {
                Role::Stationary
            } else {
                Role::Touring
            }
        })
        .collect()
}

fn standardised(values: Vec<f64>) -> Vec<f64> {
    let n = values.len().max(1) as f64;
    let mean = values.iter().sum::<f64>() / n;
    let std = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    values
        .iter()
        .map(|v| if std > 0.0 { (v - mean) / std } else { 0.0 })
        .collect()
}

pub(crate) fn section(report: &mut ReportWriter, motions: &[Motion]) -> Result<(), ReportError> {
    report.heading(
        2,
        "Emergent behaviour, measured: what roles and rhythms emerge?",
    );
    report.paragraph(&format!(
        "Per agent of every recorded episode: the dominant period of y(t) and of sin(theta(t)) \
         (the periodogram's peak, periods from {SHORTEST_PERIOD} steps to half the episode); \
         a least-squares harmonic fit at the team's period (the median of its agents' \
         periods), whose phase against agent 0 is `phase_to_agent_0` (degrees) and whose \
         share of explained variance is `r_squared` (a phase means little when it is low); \
         a role, stationary or touring, by 2-means on the agents' radius of gyration \
         and share of steps moved, pooled per map; and where each agent keeps, its mean \
         distance from the map's centre (`centre_distance`, cells)."
    ));
    let rhythm = rhythms(motions);
    let rhythm_frame = rhythm_frame(motions, &rhythm)?;
    let roles = agent_roles(motions);
    let role_frame = role_frame(motions, &roles)?;
    let statements: Vec<String> = (0..motions.len())
        .map(|index| {
            format!(
                "- {}",
                summary(&motions[index], index, &rhythm, &roles).statement
            )
        })
        .collect();
    report.paragraph(&statements.join("\n"));
    report.heading(3, "Periods and phases");
    report.table("rhythm", &rhythm_frame)?;
    report.heading(3, "Roles");
    report.table("roles", &role_frame)
}

fn rhythm_frame(motions: &[Motion], rows: &[Rhythm]) -> PolarsResult<DataFrame> {
    let harmonic = |f: fn(&Harmonic) -> f64| -> Vec<Option<f64>> {
        rows.iter().map(|r| r.harmonic.as_ref().map(f)).collect()
    };
    let named = rows.iter().map(|r| (r.motion, r.agent));
    let mut columns = agent_columns(motions, named);
    columns.extend([
        Column::new(
            "signal".into(),
            rows.iter().map(|r| r.signal).collect::<Vec<_>>(),
        ),
        Column::new(
            "period".into(),
            rows.iter().map(|r| r.period).collect::<Vec<_>>(),
        ),
        Column::new(
            "team_period".into(),
            rows.iter().map(|r| r.team_period).collect::<Vec<_>>(),
        ),
        Column::new("amplitude".into(), harmonic(|h| h.amplitude)),
        Column::new(
            "phase_to_agent_0".into(),
            rows.iter().map(|r| r.phase_to_agent_0).collect::<Vec<_>>(),
        ),
        Column::new("r_squared".into(), harmonic(|h| h.r_squared)),
    ]);
    DataFrame::new(rows.len(), columns)
}

/// The columns that name an agent of a recorded episode, `(motions index, agent)` per row:
/// map, policy, n_train, n_test, agent.
fn agent_columns(
    motions: &[Motion],
    rows: impl Iterator<Item = (usize, usize)> + Clone,
) -> Vec<Column> {
    let group = |(motion, _): (usize, usize)| &motions[motion].group;
    vec![
        Column::new(
            "map".into(),
            rows.clone()
                .map(|r| group(r).map.clone())
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "policy".into(),
            rows.clone()
                .map(|r| group(r).policy.policy.clone())
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "n_train".into(),
            rows.clone()
                .map(|r| group(r).policy.n_train)
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "n_test".into(),
            rows.clone().map(|r| group(r).n_test).collect::<Vec<_>>(),
        ),
        Column::new(
            "agent".into(),
            rows.map(|(_, a)| a as u32).collect::<Vec<_>>(),
        ),
    ]
}

/// An agent of a recorded episode (`motions[motion]`), its features and its role.
struct AgentRole {
    motion: usize,
    agent: usize,
    features: Features,
    role: Role,
}

/// Every agent's role, pooled per map as [`pooled_roles`] pools them.
fn agent_roles(motions: &[Motion]) -> Vec<AgentRole> {
    let mut rows = Vec::new();
    for map in distinct(motions.iter().map(|m| m.group.map.clone())) {
        let indices: Vec<usize> = (0..motions.len())
            .filter(|&i| motions[i].group.map == map)
            .collect();
        let pool: Vec<&Motion> = indices.iter().map(|&i| &motions[i]).collect();
        rows.extend(pooled_roles(&pool).into_iter().map(|role| AgentRole {
            motion: indices[role.motion],
            ..role
        }));
    }
    rows
}

/// The roles of every agent of `pool`, motions of one map (`motion` indexes `pool`): one
/// 2-means over all of them, so that "stationary" means still next to the map's other
/// recorded agents, not merely the stiller half of one team.
fn pooled_roles(pool: &[&Motion]) -> Vec<AgentRole> {
    let Some(first) = pool.first() else {
        return Vec::new();
    };
    let agents: Vec<(usize, usize, Features)> = (pool.iter().enumerate())
        .flat_map(|(i, m)| (0..m.agents).map(move |a| (i, a, features(&m.x[a], &m.y[a], m.centre))))
        .collect();
    let features: Vec<Features> = agents.iter().map(|a| a.2).collect();
    let roles = roles(&features, named_seed(&first.group.map).value());
    agents
        .into_iter()
        .zip(roles)
        .map(|((motion, agent, features), role)| AgentRole {
            motion,
            agent,
            features,
            role,
        })
        .collect()
}

fn role_frame(motions: &[Motion], rows: &[AgentRole]) -> PolarsResult<DataFrame> {
    let mut columns = agent_columns(motions, rows.iter().map(|r| (r.motion, r.agent)));
    columns.extend([
        Column::new(
            "radius_of_gyration".into(),
            rows.iter()
                .map(|r| r.features.radius_of_gyration)
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "moving_share".into(),
            rows.iter()
                .map(|r| r.features.moving_share)
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "centre_distance".into(),
            rows.iter()
                .map(|r| r.features.centre_distance)
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "role".into(),
            rows.iter().map(|r| r.role.name()).collect::<Vec<_>>(),
        ),
    ]);
    DataFrame::new(rows.len(), columns)
}

/// The roles one episode shows: what a behaviour claim tests, and a row of the store's table
/// of measured episodes holds. None of each where an episode's motion gives no roles.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct EpisodeRoles {
    pub(crate) stationary: u32,
    pub(crate) touring: u32,
    /// The touring agents share a rhythm in y(t) or in sin(theta(t)): each one's own period
    /// within `PERIOD_TOLERANCE` of the team's, and their phase differences at the team's
    /// period steady over the episode (`phase_wander` at most `PHASE_WANDER` degrees).
    pub(crate) periodic: bool,
    /// Every stationary agent kept nearer the map's centre than every touring one;
    /// `None` without both roles.
    pub(crate) centred: Option<bool>,
}

/// What one episode shows (a recorded one, or one a behaviour claim replays).
struct EpisodeBehaviour {
    roles: EpisodeRoles,
    /// The report's sentence about it.
    statement: String,
}

/// How far (relative) an agent's period may be from the team's and still be the same rhythm.
const PERIOD_TOLERANCE: f64 = 0.1;
/// Windows an episode is cut into to see whether the phase differences hold.
const PHASE_WINDOWS: usize = 4;
/// The most a touring agent's phase difference to the others may wander between windows
/// (degrees from its circular mean) for the rhythm to count as one.
///
/// Not the share of variance one harmonic explains over the whole episode: a pair of agents
/// whose common period drifts by a step, or whose path is a sawtooth, fits one fixed sine
/// poorly (R^2 0.49, rejected by the first rule we used, 0.5) while keeping its phase
/// difference to within a few degrees; and a phase difference is what the paper describes.
const PHASE_WANDER: f64 = 30.0;

/// How far the phase differences of `agents` to the first of them wander over the episode's
/// windows, fitted at `period`: the largest distance (degrees) of a window's difference from
/// that agent's circular mean; `None` when a window cannot be fitted.
fn phase_wander(signals: &[Vec<f64>], agents: &[usize], period: f64) -> Option<f64> {
    let (&first, others) = agents.split_first()?;
    let length = signals[first].len() / PHASE_WINDOWS;
    if (length as f64) < FEWEST_CYCLES as f64 * period {
        return None;
    }
    let mut wander: f64 = 0.0;
    for &agent in others {
        let differences = (0..PHASE_WINDOWS)
            .map(|w| {
                let window = |a: usize| &signals[a][w * length..(w + 1) * length];
                let reference = fit_harmonic(window(first), period)?;
                Some(fit_harmonic(window(agent), period)?.phase - reference.phase)
            })
            .collect::<Option<Vec<f64>>>()?;
        let (sin, cos) = differences
            .iter()
            .fold((0.0, 0.0), |(s, c), d| (s + d.sin(), c + d.cos()));
        let mean = sin.atan2(cos);
        for d in differences {
            wander = wander.max(wrapped_degrees(d - mean).abs());
        }
    }
    Some(wander)
}

/// The roles of `pool[index]`, pooled with the rest of `pool` (motions of one map, as the
/// report pools a map's recorded episodes); `None` when `index` is outside it.
pub(crate) fn measure(pool: &[&Motion], index: usize) -> Option<EpisodeRoles> {
    let motion = pool.get(index)?;
    let rhythm = motion_rhythms(index, motion);
    Some(summary(motion, index, &rhythm, &pooled_roles(pool)).roles)
}

/// The behaviour of `motion`, whose rows in `rhythm` and `roles` are those of `index`.
fn summary(
    motion: &Motion,
    index: usize,
    rhythm: &[Rhythm],
    roles: &[AgentRole],
) -> EpisodeBehaviour {
    let of = |signal: &'static str| {
        rhythm
            .iter()
            .filter(move |r| r.motion == index && r.signal == signal)
    };
    let touring: Vec<usize> = roles
        .iter()
        .filter(|r| r.motion == index && r.role == Role::Touring)
        .map(|r| r.agent)
        .collect();
    let on_the_team_period = |r: &Rhythm| match (r.period, r.team_period) {
        (Some(own), Some(team)) => (own - team).abs() <= PERIOD_TOLERANCE * team,
        _ => false,
    };
    // Each signal's phase wander, fitted once for the verdict and the sentence alike.
    let wanders = motion.signals().map(|(signal, values)| {
        let period = of(signal).next().and_then(|r| r.team_period);
        let wander = period.and_then(|p| phase_wander(values, &touring, p));
        (signal, wander)
    });
    let wander = |signal: &str| wanders.iter().find(|(s, _)| *s == signal).and_then(|w| w.1);
    let periodic = !touring.is_empty()
        && wanders.iter().any(|&(signal, wander)| {
            of(signal)
                .filter(|r| touring.contains(&r.agent))
                .all(on_the_team_period)
                && wander.is_some_and(|w| w <= PHASE_WANDER)
        });
    let describe = |signal: &'static str, name: &str| -> String {
        let Some(period) = of(signal).next().and_then(|r| r.team_period) else {
            return format!("{name}: no rhythm");
        };
        let phases: Vec<String> = of(signal)
            .skip(1)
            .map(|r| r.phase_to_agent_0.map_or("-".into(), number))
            .collect();
        let fit: Vec<String> = of(signal)
            .map(|r| r.harmonic.map_or("-".into(), |h| number(h.r_squared)))
            .collect();
        let wander = wander(signal).map_or("-".into(), number);
        format!(
            "{name} period {} steps, phases to agent 0 [{}] degrees (R^2 [{}]), touring \
             agents' phase differences wander {wander} degrees over {PHASE_WINDOWS} windows",
            number(period),
            phases.join(", "),
            fit.join(", ")
        )
    };
    let stationary = motion.agents - touring.len();
    let distances = distances(roles, index);
    let statement = format!(
        "{}: {}; {}; {stationary} stationary and {} touring agents{}.",
        motion.group.label(),
        describe("y", "y(t)"),
        describe("sin_theta", "sin(theta(t))"),
        touring.len(),
        placement(&distances)
    );
    EpisodeBehaviour {
        roles: EpisodeRoles {
            stationary: stationary as u32,
            touring: touring.len() as u32,
            periodic,
            centred: centred(&distances),
        },
        statement,
    }
}

/// The mean distances from the map's centre of `motions[index]`'s stationary agents and of
/// its touring ones.
fn distances(roles: &[AgentRole], index: usize) -> [Vec<f64>; 2] {
    [Role::Stationary, Role::Touring].map(|role| {
        (roles.iter())
            .filter(|r| r.motion == index && r.role == role)
            .map(|r| r.features.centre_distance)
            .collect()
    })
}

/// Whether every stationary agent keeps nearer the map's centre than every touring one, by
/// their [`distances`] (the paper's open map with four agents: "one agent at the centre", the
/// others "around the periphery"); `None` without both roles.
fn centred([still, moving]: &[Vec<f64>; 2]) -> Option<bool> {
    let farthest_still = still.iter().copied().reduce(f64::max)?;
    let nearest_moving = moving.iter().copied().reduce(f64::min)?;
    Some(farthest_still < nearest_moving)
}

/// Where the roles keep, by their [`distances`]: ", on average [..] (stationary) and [..]
/// (touring) cells from the map's centre", and whether they are [`centred`]; nothing for an
/// episode without agents.
fn placement(distances: &[Vec<f64>; 2]) -> String {
    let listed = |values: &[f64]| values.iter().map(|&v| number(v)).collect::<Vec<_>>();
    let mut parts = Vec::new();
    for (values, role) in distances.iter().zip([Role::Stationary, Role::Touring]) {
        if !values.is_empty() {
            parts.push(format!("[{}] ({})", listed(values).join(", "), role.name()));
        }
    }
    if parts.is_empty() {
        return String::new();
    }
    let nearest = match centred(distances) {
        Some(true) => ", every stationary agent nearer it than every touring one",
        Some(false) => ", a touring agent as near it as a stationary one",
        None => "",
    };
    format!(
        ", on average {} cells from the map's centre{nearest}",
        parts.join(" and ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wave(period: f64, phase: f64, steps: usize) -> Vec<f64> {
        (0..steps)
            .map(|t| 3.0 * (std::f64::consts::TAU * t as f64 / period - phase).cos() + 10.0)
            .collect()
    }

    #[test]
    fn the_periodogram_finds_the_period_and_the_fit_the_phase() {
        let signal = wave(250.0, 1.0, 2000);
        assert_eq!(dominant_period(&signal), Some(250.0));
        let fit = fit_harmonic(&signal, 250.0).unwrap();
        assert!((fit.amplitude - 3.0).abs() < 1e-9, "{fit:?}");
        assert!((fit.phase - 1.0).abs() < 1e-9, "{fit:?}");
        assert!((fit.r_squared - 1.0).abs() < 1e-9, "{fit:?}");
        assert_eq!(dominant_period(&[5.0; 100]), None);
        assert_eq!(
            dominant_period(&[1.0, 2.0, 1.0]),
            None,
            "too short for two cycles"
        );
    }

    /// A sawtooth of `period` steps shifted by `shift` steps, its period drifting by `drift`
    /// steps over the episode.
    fn sawtooth(period: f64, shift: f64, drift: f64, steps: usize) -> Vec<f64> {
        (0..steps)
            .map(|t| {
                let local = period + drift * t as f64 / steps as f64;
                ((t as f64 + shift) / local).fract()
            })
            .collect()
    }

    #[test]
    fn a_drifting_sawtooth_keeps_its_phase_difference_and_another_period_does_not() {
        let pair = vec![
            sawtooth(43.5, 0.0, 0.5, 2000),
            sawtooth(43.5, 11.0, 0.5, 2000),
        ];
        let period = dominant_period(&pair[0]).unwrap();
        let steady = phase_wander(&pair, &[0, 1], period).unwrap();
        assert!(steady < 10.0, "{steady}");
        let apart = vec![
            sawtooth(43.5, 0.0, 0.0, 2000),
            sawtooth(47.0, 0.0, 0.0, 2000),
        ];
        let wander = phase_wander(&apart, &[0, 1], period).unwrap();
        assert!(wander > PHASE_WANDER, "{wander}");
    }

    #[test]
    fn phase_differences_wrap() {
        assert!((wrapped_degrees(std::f64::consts::PI) - 180.0).abs() < 1e-9);
        assert!((wrapped_degrees(-std::f64::consts::FRAC_PI_2) + 90.0).abs() < 1e-9);
        assert!((wrapped_degrees(3.0 * std::f64::consts::PI) - 180.0).abs() < 1e-9);
    }

    #[test]
    fn still_and_moving_agents_get_their_roles() {
        let still = Features {
            radius_of_gyration: 0.5,
            moving_share: 0.05,
            centre_distance: 3.0,
        };
        let moving = Features {
            radius_of_gyration: 12.0,
            moving_share: 0.95,
            centre_distance: 3.0,
        };
        let roles = roles(&[moving, still, moving, moving], 7);
        use Role::{Stationary, Touring};
        assert_eq!(roles, vec![Touring, Stationary, Touring, Touring]);
        assert_eq!(super::roles(&[still, still], 7), vec![Touring, Touring]);
        let f = features(&[0.0, 1.0, 1.0, 0.0], &[0.0, 0.0, 0.0, 0.0], (1.0, 0.5));
        assert_eq!(f.radius_of_gyration, 0.5);
        assert!((f.moving_share - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(
            f.centre_distance, 0.5,
            "cell centres half a cell either side"
        );
    }

    #[test]
    fn where_the_roles_keep_is_said_of_each_episode() {
        use Role::{Stationary, Touring};
        let agent = |motion, role, centre_distance| AgentRole {
            motion,
            agent: 0,
            features: Features {
                radius_of_gyration: 1.0,
                moving_share: 0.5,
                centre_distance,
            },
            role,
        };
        let roles = [
            agent(0, Stationary, 1.5),
            agent(0, Touring, 20.0),
            agent(0, Touring, 18.0),
            agent(1, Stationary, 19.0),
            agent(1, Touring, 18.0),
            agent(2, Touring, 7.0),
        ];
        let placement = |index| placement(&distances(&roles, index));
        let centred = placement(0);
        assert!(
            centred.contains("[1.500] (stationary) and [20.00, 18.00] (touring)"),
            "{centred}"
        );
        assert!(centred.ends_with("every stationary agent nearer it than every touring one"));
        assert!(placement(1).ends_with("a touring agent as near it as a stationary one"));
        let touring = placement(2);
        assert_eq!(
            touring,
            ", on average [7.000] (touring) cells from the map's centre"
        );
        assert_eq!(placement(3), "");
        let judged = (0..4)
            .map(|i| super::centred(&distances(&roles, i)))
            .collect::<Vec<_>>();
        assert_eq!(judged, [Some(true), Some(false), None, None]);
    }
}
