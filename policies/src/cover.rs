//! Choosing few candidates whose sets together cover a universe, or the k that cover most.
//!
//! TSPC needs viewpoints that together see every free cell, and the static-coverage baseline
//! needs the k viewpoints that see the most. Both are NP-hard; the greedy rule (take whatever
//! covers the most still-uncovered elements) is within a factor ln(u) + 1 of the smallest cover
//! and within 1 − 1/e of the best k. Sets are bit rows so that counting what a candidate adds
//! is a popcount over a few dozen words, and the greedy is lazy: a candidate's gain only shrinks
//! as others are chosen, so a stale gain is an upper bound and most candidates are never
//! re-counted.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use thiserror::Error;

const WORD_BITS: usize = u64::BITS as usize;

#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CoverError {
    #[error("candidate {candidate} has {words} words, expected {expected} for {universe} elements")]
    RowLength {
        candidate: usize,
        words: usize,
        expected: usize,
        universe: usize,
    },
    #[error("candidate {candidate} contains element {element}, outside the universe of {universe}")]
    OutsideUniverse {
        candidate: usize,
        element: usize,
        universe: usize,
    },
}

/// One bit row per candidate over the elements `0..universe`; rows are checked to hold no bits
/// beyond the universe, so popcounts never count phantom elements.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CoverageSets {
    universe: usize,
    candidates: usize,
    words_per_row: usize,
    words: Vec<u64>,
}

impl CoverageSets {
    pub fn from_bit_rows<R: AsRef<[u64]>>(universe: usize, rows: &[R]) -> Result<Self, CoverError> {
        let words_per_row = universe.div_ceil(WORD_BITS);
        let mut words = Vec::with_capacity(rows.len() * words_per_row);
        for (candidate, row) in rows.iter().enumerate() {
            let row = row.as_ref();
            if row.len() != words_per_row {
                return Err(CoverError::RowLength {
                    candidate,
                    words: row.len(),
                    expected: words_per_row,
                    universe,
                });
            }
            if let Some(element) = elements(row).find(|&element| element >= universe) {
                return Err(CoverError::OutsideUniverse {
                    candidate,
                    element,
                    universe,
                });
            }
            words.extend_from_slice(row);
        }
        Ok(Self {
            universe,
            candidates: rows.len(),
            words_per_row,
            words,
        })
    }

    pub fn from_index_lists<L: AsRef<[usize]>>(
        universe: usize,
        lists: &[L],
    ) -> Result<Self, CoverError> {
        let words_per_row = universe.div_ceil(WORD_BITS);
        let mut rows = vec![vec![0u64; words_per_row]; lists.len()];
        for (candidate, (list, row)) in lists.iter().zip(&mut rows).enumerate() {
            for &element in list.as_ref() {
                if element >= universe {
                    return Err(CoverError::OutsideUniverse {
                        candidate,
                        element,
                        universe,
                    });
                }
                row[element / WORD_BITS] |= 1 << (element % WORD_BITS);
            }
        }
        Self::from_bit_rows(universe, &rows)
    }

    pub fn universe(&self) -> usize {
        self.universe
    }

    pub fn candidates(&self) -> usize {
        self.candidates
    }

    pub fn row(&self, candidate: usize) -> &[u64] {
        let start = candidate * self.words_per_row;
        &self.words[start..start + self.words_per_row]
    }

    /// Number of elements covered by at least one of `chosen`.
    pub fn covered_count(&self, chosen: &[usize]) -> usize {
        let mut union = vec![0u64; self.words_per_row];
        for &candidate in chosen {
            for (covered, word) in union.iter_mut().zip(self.row(candidate)) {
                *covered |= word;
            }
        }
        popcount(&union)
    }
}

fn popcount(words: &[u64]) -> usize {
    words.iter().map(|word| word.count_ones() as usize).sum()
}

/// Indices of the set bits, in increasing order.
fn elements(words: &[u64]) -> impl Iterator<Item = usize> + '_ {
    words.iter().enumerate().flat_map(|(index, &word)| {
        let mut remaining = word;
        std::iter::from_fn(move || {
            (remaining != 0).then(|| {
                let bit = remaining.trailing_zeros() as usize;
                remaining &= remaining - 1;
                index * WORD_BITS + bit
            })
        })
    })
}

/// Candidates in greedy order, each with the number of elements it newly covers. Every
/// candidate is eventually yielded, those adding nothing last in index order, so callers decide
/// where to stop.
struct GreedyOrder<'a> {
    sets: &'a CoverageSets,
    uncovered: Vec<u64>,
    /// Gains as last counted; ties pop the lowest index first.
    queue: BinaryHeap<(usize, Reverse<usize>)>,
}

impl<'a> GreedyOrder<'a> {
    fn new(sets: &'a CoverageSets) -> Self {
        let mut uncovered = vec![u64::MAX; sets.words_per_row];
        if let Some(last) = uncovered.last_mut() {
            let used_bits = sets.universe % WORD_BITS;
            if used_bits != 0 {
                *last = (1 << used_bits) - 1;
            }
        }
        let queue = (0..sets.candidates)
            .map(|candidate| (popcount(sets.row(candidate)), Reverse(candidate)))
            .collect();
        Self {
            sets,
            uncovered,
            queue,
        }
    }

    fn gain(&self, candidate: usize) -> usize {
        let row = self.sets.row(candidate);
        row.iter()
            .zip(&self.uncovered)
            .map(|(word, uncovered)| (word & uncovered).count_ones() as usize)
            .sum()
    }

    fn take(&mut self, candidate: usize) {
        for (uncovered, word) in self.uncovered.iter_mut().zip(self.sets.row(candidate)) {
            *uncovered &= !word;
        }
    }
}

impl Iterator for GreedyOrder<'_> {
    type Item = (usize, usize);

    /// A popped candidate whose recounted gain equals its queued gain is the true maximum:
    /// every other queued gain is an upper bound no larger, and an equal one with a lower index
    /// would have popped first.
    fn next(&mut self) -> Option<Self::Item> {
        while let Some((queued_gain, Reverse(candidate))) = self.queue.pop() {
            let gain = self.gain(candidate);
            if gain == queued_gain {
                self.take(candidate);
                return Some((candidate, gain));
            }
            self.queue.push((gain, Reverse(candidate)));
        }
        None
    }
}

/// A cover of every element some candidate covers; elements no candidate covers are listed
/// rather than treated as a failure, since the caller knows whether they can occur.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SetCover {
    /// In the order the greedy chose them.
    pub chosen: Vec<usize>,
    /// In increasing order.
    pub uncoverable: Vec<usize>,
}

/// Greedy set cover, then dropping candidates that became redundant once later ones were
/// chosen, so that every chosen candidate is the only one covering some element.
pub fn greedy_set_cover(sets: &CoverageSets) -> SetCover {
    let mut order = GreedyOrder::new(sets);
    let mut chosen = Vec::new();
    for (candidate, gain) in order.by_ref() {
        if gain == 0 {
            break; // Whatever is still uncovered, no candidate covers.
        }
        chosen.push(candidate);
    }
    drop_redundant(sets, &mut chosen);
    SetCover {
        chosen,
        uncoverable: elements(&order.uncovered).collect(),
    }
}

/// Scans in selection order, so the large early choices are the first dropped when later ones
/// made them unnecessary. One pass suffices: dropping only lowers coverage counts, so a
/// candidate kept as the sole cover of some element stays its sole cover.
fn drop_redundant(sets: &CoverageSets, chosen: &mut Vec<usize>) {
    let mut coverers = vec![0u32; sets.universe];
    for &candidate in chosen.iter() {
        elements(sets.row(candidate)).for_each(|element| coverers[element] += 1);
    }
    chosen.retain(|&candidate| {
        let redundant = elements(sets.row(candidate)).all(|element| coverers[element] > 1);
        if redundant {
            elements(sets.row(candidate)).for_each(|element| coverers[element] -= 1);
        }
        !redundant
    });
}

/// The first `k` candidates of the greedy order (all of them if there are fewer), in that order.
/// Once everything coverable is covered the remaining picks add nothing and go to the lowest
/// unchosen indices, so the baseline always gets the `k` positions it asked for, and the result
/// for `k` is a prefix of the result for `k + 1`.
pub fn greedy_max_coverage(sets: &CoverageSets, k: usize) -> Vec<usize> {
    GreedyOrder::new(sets)
        .take(k)
        .map(|(candidate, _)| candidate)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    fn random_sets(universe: usize, candidates: usize, density: f64, seed: u64) -> CoverageSets {
        let mut rng = Pcg64Mcg::seed_from_u64(seed);
        let lists: Vec<Vec<usize>> = (0..candidates)
            .map(|_| (0..universe).filter(|_| rng.random_bool(density)).collect())
            .collect();
        CoverageSets::from_index_lists(universe, &lists).unwrap()
    }

    fn all_candidates(sets: &CoverageSets) -> Vec<usize> {
        (0..sets.candidates()).collect()
    }

    /// Smallest number of candidates covering everything coverable, by trying every subset.
    fn optimal_cover_size(sets: &CoverageSets) -> usize {
        let coverable = sets.covered_count(&all_candidates(sets));
        (0u32..1 << sets.candidates())
            .map(subset)
            .filter(|chosen| sets.covered_count(chosen) == coverable)
            .map(|chosen| chosen.len())
            .min()
            .unwrap()
    }

    /// Most elements any `k` candidates cover, by trying every subset of that size.
    fn optimal_coverage(sets: &CoverageSets, k: usize) -> usize {
        (0u32..1 << sets.candidates())
            .filter(|mask| mask.count_ones() as usize == k)
            .map(|mask| sets.covered_count(&subset(mask)))
            .max()
            .unwrap()
    }

    fn subset(mask: u32) -> Vec<usize> {
        (0..32).filter(|bit| (mask >> bit) & 1 == 1).collect()
    }

    /// The greedy order recomputed from scratch each step, to check the lazy queue against.
    fn eager_greedy_order(sets: &CoverageSets) -> Vec<usize> {
        let mut chosen: Vec<usize> = Vec::new();
        while chosen.len() < sets.candidates() {
            let covered = sets.covered_count(&chosen);
            let best = (0..sets.candidates())
                .filter(|candidate| !chosen.contains(candidate))
                .max_by_key(|&candidate| {
                    let with = [chosen.as_slice(), &[candidate]].concat();
                    (sets.covered_count(&with) - covered, Reverse(candidate))
                })
                .unwrap();
            chosen.push(best);
        }
        chosen
    }

    #[test]
    fn rejects_rows_of_the_wrong_length() {
        let error = CoverageSets::from_bit_rows(70, &[vec![0, 0], vec![0]]).unwrap_err();
        assert_eq!(
            error,
            CoverError::RowLength {
                candidate: 1,
                words: 1,
                expected: 2,
                universe: 70
            }
        );
    }

    #[test]
    fn rejects_bits_beyond_the_universe() {
        let error = CoverageSets::from_bit_rows(70, &[[0, 1 << 6]]).unwrap_err();
        assert_eq!(
            error,
            CoverError::OutsideUniverse {
                candidate: 0,
                element: 70,
                universe: 70
            }
        );
        let error = CoverageSets::from_index_lists(5, &[vec![0], vec![5]]).unwrap_err();
        assert_eq!(
            error,
            CoverError::OutsideUniverse {
                candidate: 1,
                element: 5,
                universe: 5
            }
        );
    }

    #[test]
    fn bit_rows_and_index_lists_agree() {
        let from_lists = CoverageSets::from_index_lists(130, &[vec![0, 64, 129], vec![]]).unwrap();
        let from_bits = CoverageSets::from_bit_rows(130, &[[1, 1, 2], [0, 0, 0]]).unwrap();
        assert_eq!(from_lists, from_bits);
    }

    #[test]
    fn ties_go_to_the_lowest_index() {
        let sets =
            CoverageSets::from_index_lists(4, &[vec![2], vec![0, 1], vec![0, 1], vec![3]]).unwrap();
        assert_eq!(greedy_set_cover(&sets).chosen, vec![1, 0, 3]);
        assert_eq!(greedy_max_coverage(&sets, 4), vec![1, 0, 3, 2]);
    }

    #[test]
    fn drops_candidates_made_redundant_by_later_choices() {
        // Greedy takes 0 first, then 1 and 2, which together cover everything 0 did.
        let sets =
            CoverageSets::from_index_lists(6, &[vec![1, 2, 3, 4], vec![0, 1, 2], vec![3, 4, 5]])
                .unwrap();
        assert_eq!(greedy_set_cover(&sets).chosen, vec![1, 2]);
    }

    #[test]
    fn reports_uncoverable_elements() {
        let sets = CoverageSets::from_index_lists(5, &[vec![0, 1], vec![3]]).unwrap();
        let cover = greedy_set_cover(&sets);
        assert_eq!(cover.chosen, vec![0, 1]);
        assert_eq!(cover.uncoverable, vec![2, 4]);
    }

    #[test]
    fn empty_universe_needs_no_candidates() {
        let sets = CoverageSets::from_index_lists(0, &[Vec::new(), Vec::new()]).unwrap();
        let cover = greedy_set_cover(&sets);
        assert!(cover.chosen.is_empty() && cover.uncoverable.is_empty());
    }

    #[test]
    fn lazy_greedy_matches_eager_greedy() {
        for seed in 0..30 {
            let sets = random_sets(90, 25, 0.1, seed);
            assert_eq!(
                greedy_max_coverage(&sets, sets.candidates()),
                eager_greedy_order(&sets)
            );
        }
    }

    #[test]
    fn cover_is_complete_and_irredundant() {
        for (seed, density) in [0.02, 0.05, 0.2].into_iter().cycle().take(30).enumerate() {
            let sets = random_sets(200, 60, density, seed as u64);
            let cover = greedy_set_cover(&sets);
            let coverable = sets.covered_count(&all_candidates(&sets));
            assert_eq!(sets.covered_count(&cover.chosen), coverable);
            assert_eq!(coverable + cover.uncoverable.len(), sets.universe());
            for dropped in 0..cover.chosen.len() {
                let mut others = cover.chosen.clone();
                others.remove(dropped);
                assert!(
                    sets.covered_count(&others) < coverable,
                    "seed {seed}: redundant {dropped}"
                );
            }
        }
    }

    #[test]
    fn cover_is_within_the_greedy_bound_of_optimal() {
        for seed in 0..100 {
            let sets = random_sets(12, 10, 0.25, seed);
            let greedy = greedy_set_cover(&sets).chosen.len() as f64;
            let optimal = optimal_cover_size(&sets) as f64;
            let bound = (sets.universe() as f64).ln() + 1.0;
            assert!(
                greedy <= bound * optimal,
                "seed {seed}: {greedy} > {bound} × {optimal}"
            );
        }
    }

    #[test]
    fn max_coverage_is_monotone_and_within_the_greedy_bound() {
        for seed in 0..30 {
            let sets = random_sets(20, 10, 0.2, seed);
            let mut previous = 0;
            for k in 0..=sets.candidates() {
                let chosen = greedy_max_coverage(&sets, k);
                let covered = sets.covered_count(&chosen);
                assert_eq!(chosen.len(), k);
                assert!(covered >= previous, "seed {seed}, k {k}");
                let optimal = optimal_coverage(&sets, k) as f64;
                assert!(
                    covered as f64 >= (1.0 - (-1.0f64).exp()) * optimal,
                    "seed {seed}, k {k}"
                );
                previous = covered;
            }
        }
    }
}
