//! The optimal tour by enumeration, and how far the heuristic [`solve`] is from it on random
//! instances small enough to enumerate: the tests' yardstick for the heuristic that TSPC uses.

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::{DistanceMatrix, Tour, TourError, solve};

/// Largest instance [`solve_exact`] accepts; beyond this enumeration takes too long to be useful.
pub(crate) const MAX_EXACT_POINTS: usize = 12;

/// The optimal tour by enumerating orders with point 0 fixed first, abandoning any partial
/// order already as long as the best complete one (distances are non-negative, so it cannot
/// end shorter).
pub(crate) fn solve_exact(distances: &DistanceMatrix) -> Result<Tour, TourError> {
    let points = distances.len();
    if points > MAX_EXACT_POINTS {
        return Err(TourError::TooManyForExact { points });
    }
    if points <= 3 {
        return Ok(Tour::closed(distances, (0..points).collect()));
    }
    let mut search = ExhaustiveSearch {
        distances,
        path: vec![0],
        visited: vec![false; points],
        best: None,
    };
    search.visited[0] = true;
    search.extend(0);
    let (_, order) = search
        .best
        .expect("at least one complete order is enumerated");
    Ok(Tour::closed(distances, order))
}

struct ExhaustiveSearch<'a> {
    distances: &'a DistanceMatrix,
    path: Vec<usize>,
    visited: Vec<bool>,
    best: Option<(u64, Vec<usize>)>,
}

impl ExhaustiveSearch<'_> {
    fn beats_best(&self, length: u64) -> bool {
        self.best.as_ref().is_none_or(|(best, _)| length < *best)
    }

    fn extend(&mut self, path_length: u64) {
        let last = *self.path.last().expect("the path starts at point 0");
        if self.path.len() == self.distances.len() {
            let length = path_length + self.distances.cost(last, 0);
            if self.beats_best(length) {
                self.best = Some((length, self.path.clone()));
            }
            return;
        }
        for next in 1..self.distances.len() {
            let length = path_length + self.distances.cost(last, next);
            if self.visited[next] || !self.beats_best(length) {
                continue;
            }
            self.visited[next] = true;
            self.path.push(next);
            self.extend(length);
            self.path.pop();
            self.visited[next] = false;
        }
    }
}

/// How distances between random plane points are made integral.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PlaneMetric {
    Manhattan,
    RoundedEuclidean,
}

impl PlaneMetric {
    pub(super) fn distance(self, a: (i64, i64), b: (i64, i64)) -> u32 {
        let (dx, dy) = ((a.0 - b.0).abs(), (a.1 - b.1).abs());
        let distance = match self {
            Self::Manhattan => dx + dy,
            Self::RoundedEuclidean => ((dx * dx + dy * dy) as f64).sqrt().round() as i64,
        };
        u32::try_from(distance).expect("coordinates below 2^16 keep distances below 2^18")
    }
}

/// Side of the integer grid random instances are drawn on, about the size of the paper's maps.
const RANDOM_PLANE_SIDE: u16 = 50;

/// A reproducible family of random instances: points drawn uniformly on a
/// [`RANDOM_PLANE_SIDE`]² integer grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct RandomPlaneInstances {
    pub(crate) instances: usize,
    pub(crate) points: usize,
    pub(crate) metric: PlaneMetric,
    pub(crate) seed: u64,
}

/// How far [`solve`] is from [`solve_exact`]; gaps are relative to the optimal length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GapStatistic {
    instances: usize,
    pub(crate) mean_gap: f64,
    max_gap: f64,
    fraction_optimal: f64,
}

/// Measures the heuristic against the exact optimum, so that reports can state how much patrol
/// period the heuristic tour might be wasting. An empty family gives zeros.
pub(crate) fn heuristic_gap(family: &RandomPlaneInstances) -> Result<GapStatistic, TourError> {
    let mut rng = Pcg64Mcg::seed_from_u64(family.seed);
    let mut gaps = Vec::with_capacity(family.instances);
    for _ in 0..family.instances {
        let distances = random_plane_instance(&mut rng, family)?;
        let optimum = solve_exact(&distances)?.length();
        gaps.push(relative_gap(solve(&distances).length(), optimum));
    }
    let count = family.instances.max(1) as f64;
    Ok(GapStatistic {
        instances: family.instances,
        mean_gap: gaps.iter().sum::<f64>() / count,
        max_gap: gaps.iter().copied().fold(0.0, f64::max),
        fraction_optimal: gaps.iter().filter(|&&gap| gap == 0.0).count() as f64 / count,
    })
}

pub(super) fn random_plane_instance(
    rng: &mut Pcg64Mcg,
    family: &RandomPlaneInstances,
) -> Result<DistanceMatrix, TourError> {
    let coordinates: Vec<(i64, i64)> = (0..family.points)
        .map(|_| {
            let x = rng.random_range(0..RANDOM_PLANE_SIDE);
            let y = rng.random_range(0..RANDOM_PLANE_SIDE);
            (i64::from(x), i64::from(y))
        })
        .collect();
    DistanceMatrix::from_fn(family.points, |from, to| {
        family.metric.distance(coordinates[from], coordinates[to])
    })
}

/// A zero-length optimum only arises when all points coincide, and then every tour is optimal.
fn relative_gap(length: u64, optimum: u64) -> f64 {
    if optimum == 0 {
        0.0
    } else {
        (length - optimum) as f64 / optimum as f64
    }
}
