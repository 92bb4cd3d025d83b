//! Short closed tours through points known only by their pairwise distances.
//!
//! TSPC patrols its viewpoints in a fixed cycle, so the tour length is the patrol period: every
//! step saved is a step sooner that each cell is seen again. Maps have about a hundred
//! viewpoints, too many for an exact solver but few enough for full O(n²) local-search passes,
//! so the tour is built by nearest neighbour and then improved by 2-opt and Or-opt until neither
//! finds a strictly shorter tour. Distances are integers, so "strictly shorter" is exact and the
//! search always terminates. The exact solver (`tour/exact.rs`, in tests only) measures how far
//! that heuristic is from optimal on instances small enough to enumerate.

use thiserror::Error;

#[cfg(test)]
mod exact;

/// Or-opt moves segments of up to this many consecutive points; longer segments are rarely
/// worth the extra scan and are partly covered by 2-opt reversals.
const MAX_OR_OPT_SEGMENT: usize = 3;

#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum TourError {
    #[error("distance matrix row {row} has {len} entries, expected {expected}")]
    NotSquare {
        row: usize,
        len: usize,
        expected: usize,
    },
    #[error("distance from point {point} to itself is {distance}, expected 0")]
    NonzeroDiagonal { point: usize, distance: u32 },
    #[error("distance {from}->{to} is {forward} but {to}->{from} is {backward}")]
    Asymmetric {
        from: usize,
        to: usize,
        forward: u32,
        backward: u32,
    },
    #[cfg(test)]
    #[error(
        "exact solver accepts at most {} points, got {points}",
        exact::MAX_EXACT_POINTS
    )]
    TooManyForExact { points: usize },
}

/// Symmetric distances with a zero diagonal, checked once here so that the solvers can rely on
/// them: 2-opt's gain formula is only valid when reversing a segment keeps its length.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct DistanceMatrix {
    points: usize,
    row_major: Vec<u32>,
}

impl DistanceMatrix {
    pub(crate) fn from_rows<R: AsRef<[u32]>>(rows: &[R]) -> Result<Self, TourError> {
        let points = rows.len();
        let mut row_major = Vec::with_capacity(points * points);
        for (row, entries) in rows.iter().enumerate() {
            let entries = entries.as_ref();
            if entries.len() != points {
                return Err(TourError::NotSquare {
                    row,
                    len: entries.len(),
                    expected: points,
                });
            }
            row_major.extend_from_slice(entries);
        }
        Self::validated(points, row_major)
    }

    #[cfg(test)]
    fn from_fn(
        points: usize,
        mut distance: impl FnMut(usize, usize) -> u32,
    ) -> Result<Self, TourError> {
        let row_major = (0..points)
            .flat_map(|from| (0..points).map(move |to| (from, to)))
            .map(|(from, to)| distance(from, to))
            .collect();
        Self::validated(points, row_major)
    }

    fn validated(points: usize, row_major: Vec<u32>) -> Result<Self, TourError> {
        let matrix = Self { points, row_major };
        for from in 0..points {
            let distance = matrix.get(from, from);
            if distance != 0 {
                return Err(TourError::NonzeroDiagonal {
                    point: from,
                    distance,
                });
            }
            for to in from + 1..points {
                let (forward, backward) = (matrix.get(from, to), matrix.get(to, from));
                if forward != backward {
                    return Err(TourError::Asymmetric {
                        from,
                        to,
                        forward,
                        backward,
                    });
                }
            }
        }
        Ok(matrix)
    }

    fn len(&self) -> usize {
        self.points
    }

    fn get(&self, from: usize, to: usize) -> u32 {
        self.row_major[from * self.points + to]
    }

    /// Widened so that sums of several distances cannot overflow.
    fn cost(&self, from: usize, to: usize) -> u64 {
        u64::from(self.get(from, to))
    }
}

/// A closed tour: the visiting order, starting at point 0, and the length including the edge
/// back from the last point to the first.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Tour {
    order: Vec<usize>,
    length: u64,
}

impl Tour {
    fn closed(distances: &DistanceMatrix, mut order: Vec<usize>) -> Self {
        if let Some(start) = order.iter().position(|&point| point == 0) {
            order.rotate_left(start);
        }
        let length = tour_length(distances, &order);
        Self { order, length }
    }

    pub(crate) fn order(&self) -> &[usize] {
        &self.order
    }

    #[cfg(test)]
    fn length(&self) -> u64 {
        self.length
    }
}

/// Length of the closed tour visiting `order` and returning to its first point.
fn tour_length(distances: &DistanceMatrix, order: &[usize]) -> u64 {
    let closing = order.iter().skip(1).chain(order.first());
    order
        .iter()
        .zip(closing)
        .map(|(&from, &to)| distances.cost(from, to))
        .sum()
}

/// The heuristic tour: nearest neighbour from point 0, then 2-opt and Or-opt to a local optimum
/// of both. Deterministic: fixed scan order, first improvement, ties to the lowest index.
pub(crate) fn solve(distances: &DistanceMatrix) -> Tour {
    let mut order = nearest_neighbour_order(distances);
    improve_to_local_optimum(distances, &mut order);
    Tour::closed(distances, order)
}

fn nearest_neighbour_order(distances: &DistanceMatrix) -> Vec<usize> {
    let points = distances.len();
    let mut visited = vec![false; points];
    let mut order = Vec::with_capacity(points);
    let mut current = 0;
    while order.len() < points {
        visited[current] = true;
        order.push(current);
        let nearest = (0..points)
            .filter(|&candidate| !visited[candidate])
            .min_by_key(|&candidate| distances.get(current, candidate));
        match nearest {
            Some(next) => current = next,
            None => break,
        }
    }
    order
}

/// Alternates full passes of both neighbourhoods; a round in which neither changes the tour
/// proves it is a local optimum of both.
fn improve_to_local_optimum(distances: &DistanceMatrix, order: &mut Vec<usize>) {
    loop {
        let two_opt_improved = two_opt_pass(distances, order);
        let or_opt_improved = or_opt_pass(distances, order);
        if !two_opt_improved && !or_opt_improved {
            return;
        }
    }
}

/// Tries replacing every pair of non-adjacent edges (a, b), (c, d) by (a, c), (b, d), which
/// reverses the path from b to c, applying each strictly shorter one as soon as it is found.
fn two_opt_pass(distances: &DistanceMatrix, order: &mut [usize]) -> bool {
    let points = order.len();
    let mut improved = false;
    for first in 0..points.saturating_sub(2) {
        for second in first + 2..points {
            if first == 0 && second == points - 1 {
                continue; // The two edges share point order[0].
            }
            let (a, b) = (order[first], order[first + 1]);
            let (c, d) = (order[second], order[(second + 1) % points]);
            let removed = distances.cost(a, b) + distances.cost(c, d);
            let added = distances.cost(a, c) + distances.cost(b, d);
            if added < removed {
                order[first + 1..=second].reverse();
                improved = true;
            }
        }
    }
    improved
}

/// A segment of consecutive tour positions and where to reinsert it.
struct SegmentMove {
    start: usize,
    len: usize,
    /// Index into the rest of the tour (read from just after the segment), after which the
    /// segment goes.
    after: usize,
    reversed: bool,
}

/// Tries moving every segment of 1 to [`MAX_OR_OPT_SEGMENT`] points to every other edge in
/// both orientations, applying each strictly shorter move as soon as it is found.
fn or_opt_pass(distances: &DistanceMatrix, order: &mut Vec<usize>) -> bool {
    let points = order.len();
    let mut improved = false;
    for len in 1..=MAX_OR_OPT_SEGMENT.min(points.saturating_sub(3)) {
        for start in 0..points {
            if let Some(found) = first_improving_insertion(distances, order, start, len) {
                apply_segment_move(order, &found);
                improved = true;
            }
        }
    }
    improved
}

/// The segment at `start` is cut out, joining its neighbours p and n; it is then inserted into
/// an edge (c, e) of the remaining cycle other than (p, n) itself.
fn first_improving_insertion(
    distances: &DistanceMatrix,
    order: &[usize],
    start: usize,
    len: usize,
) -> Option<SegmentMove> {
    let points = order.len();
    let at = |offset: usize| order[(start + offset) % points];
    let (previous, first, last, next) = (at(points - 1), at(0), at(len - 1), at(len));
    let cut_saving = distances.cost(previous, first) + distances.cost(last, next);
    let cut_cost = distances.cost(previous, next);
    let rest = |index: usize| at(len + index);
    (0..points - len - 1).find_map(|after| {
        let (c, e) = (rest(after), rest(after + 1));
        let removed = cut_saving + distances.cost(c, e);
        let forward = cut_cost + distances.cost(c, first) + distances.cost(last, e);
        let backward = cut_cost + distances.cost(c, last) + distances.cost(first, e);
        let reversed = if forward < removed {
            false
        } else if backward < removed {
            true
        } else {
            return None;
        };
        Some(SegmentMove {
            start,
            len,
            after,
            reversed,
        })
    })
}

fn apply_segment_move(order: &mut Vec<usize>, found: &SegmentMove) {
    let points = order.len();
    let at = |offset: usize| order[(found.start + offset) % points];
    let mut segment: Vec<usize> = (0..found.len).map(at).collect();
    if found.reversed {
        segment.reverse();
    }
    let rest: Vec<usize> = (found.len..points).map(at).collect();
    let (head, tail) = rest.split_at(found.after + 1);
    *order = [head, &segment, tail].concat();
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    use super::exact::*;
    use super::*;

    fn random_instance(points: usize, metric: PlaneMetric, seed: u64) -> DistanceMatrix {
        let family = RandomPlaneInstances {
            instances: 1,
            points,
            metric,
            seed,
        };
        random_plane_instance(&mut Pcg64Mcg::seed_from_u64(seed), &family).unwrap()
    }

    fn assert_permutation(order: &[usize], points: usize) {
        let mut sorted = order.to_vec();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..points).collect::<Vec<_>>());
    }

    fn edge_sum(distances: &DistanceMatrix, order: &[usize]) -> u64 {
        let n = order.len();
        (0..n)
            .map(|i| u64::from(distances.get(order[i], order[(i + 1) % n])))
            .sum()
    }

    #[test]
    fn rejects_non_square_matrix() {
        let error = DistanceMatrix::from_rows(&[vec![0, 1], vec![1]]).unwrap_err();
        assert_eq!(
            error,
            TourError::NotSquare {
                row: 1,
                len: 1,
                expected: 2
            }
        );
    }

    #[test]
    fn rejects_nonzero_diagonal() {
        let error = DistanceMatrix::from_rows(&[[0, 1], [1, 4]]).unwrap_err();
        assert_eq!(
            error,
            TourError::NonzeroDiagonal {
                point: 1,
                distance: 4
            }
        );
    }

    #[test]
    fn rejects_asymmetric_matrix() {
        let error = DistanceMatrix::from_rows(&[[0, 1], [2, 0]]).unwrap_err();
        assert_eq!(
            error,
            TourError::Asymmetric {
                from: 0,
                to: 1,
                forward: 1,
                backward: 2
            }
        );
    }

    #[test]
    fn exact_solver_refuses_large_instances() {
        let distances = random_instance(MAX_EXACT_POINTS + 1, PlaneMetric::Manhattan, 1);
        assert_eq!(
            solve_exact(&distances).unwrap_err(),
            TourError::TooManyForExact {
                points: MAX_EXACT_POINTS + 1
            }
        );
    }

    #[test]
    fn trivial_instances_give_the_obvious_tour() {
        for points in 0..=3 {
            let distances =
                DistanceMatrix::from_fn(points, |a, b| a.abs_diff(b) as u32 * 5).unwrap();
            let expected = if points < 2 {
                0
            } else {
                10 * (points as u64 - 1)
            };
            for tour in [solve(&distances), solve_exact(&distances).unwrap()] {
                assert_eq!(tour.order(), (0..points).collect::<Vec<_>>());
                assert_eq!(tour.length(), expected);
            }
        }
    }

    #[test]
    fn exact_solver_finds_the_square_perimeter() {
        // Corners of a 10 × 10 square listed in crossing order; the optimum walks the perimeter.
        let corners = [(0, 0), (10, 10), (10, 0), (0, 10)];
        let distances = DistanceMatrix::from_fn(4, |a, b| {
            PlaneMetric::RoundedEuclidean.distance(corners[a], corners[b])
        })
        .unwrap();
        assert_eq!(solve_exact(&distances).unwrap().length(), 40);
        assert_eq!(solve(&distances).length(), 40);
    }

    #[test]
    fn tour_is_a_permutation_with_length_equal_to_its_edges() {
        for seed in 0..20 {
            for metric in [PlaneMetric::Manhattan, PlaneMetric::RoundedEuclidean] {
                let distances = random_instance(5 + seed as usize * 3, metric, seed);
                let tour = solve(&distances);
                assert_permutation(tour.order(), distances.len());
                assert_eq!(tour.order()[0], 0);
                assert_eq!(tour.length(), edge_sum(&distances, tour.order()));
            }
        }
    }

    #[test]
    fn no_improving_two_opt_move_remains() {
        for seed in 0..10 {
            let distances = random_instance(40, PlaneMetric::RoundedEuclidean, seed);
            let tour = solve(&distances);
            let n = tour.order().len();
            for i in 0..n {
                for j in i + 1..n {
                    let mut candidate = tour.order().to_vec();
                    candidate[i..=j].reverse();
                    assert!(
                        edge_sum(&distances, &candidate) >= tour.length(),
                        "seed {seed}: reverse {i}..={j}"
                    );
                }
            }
        }
    }

    #[test]
    fn no_improving_or_opt_move_remains() {
        for seed in 0..10 {
            let distances = random_instance(30, PlaneMetric::Manhattan, seed);
            let tour = solve(&distances);
            let n = tour.order().len();
            for len in 1..=MAX_OR_OPT_SEGMENT {
                for start in 0..n {
                    let mut rest = tour.order().to_vec();
                    rest.rotate_left(start);
                    let mut segment: Vec<usize> = rest.drain(..len).collect();
                    for _ in 0..2 {
                        segment.reverse();
                        for insert_at in 0..=rest.len() {
                            let mut candidate = rest.clone();
                            candidate.splice(insert_at..insert_at, segment.iter().copied());
                            assert!(
                                edge_sum(&distances, &candidate) >= tour.length(),
                                "seed {seed}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn solving_is_deterministic() {
        let distances = random_instance(60, PlaneMetric::Manhattan, 7);
        assert_eq!(solve(&distances), solve(&distances));
    }

    /// On seed 2024 the heuristic is optimal on 98.5 % (Manhattan) and 100 % (rounded
    /// Euclidean) of the instances, mean gap 0.06 % and 0 %, worst single instance 7.2 %. Over
    /// seeds 0..100 the worst mean gap was 0.18 %. The bound of 0.4 % sits above that spread but
    /// below what a weaker search reaches on this seed: nearest neighbour alone is 7.9 % / 8.7 %
    /// above optimal, and with 2-opt but no Or-opt 0.52 % / 0.22 %.
    #[test]
    fn heuristic_is_close_to_optimal_on_small_random_instances() {
        for metric in [PlaneMetric::Manhattan, PlaneMetric::RoundedEuclidean] {
            let family = RandomPlaneInstances {
                instances: 200,
                points: 8,
                metric,
                seed: 2024,
            };
            let gap = heuristic_gap(&family).unwrap();
            println!("{metric:?}: {gap:?}");
            assert!(gap.mean_gap < 0.004, "{metric:?}: {gap:?}");
        }
    }
}
