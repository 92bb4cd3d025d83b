//! Choosing few candidates whose sets together cover a universe, or the k that cover most.
//!
//! TSPC needs viewpoints that together see every free cell, and the static-coverage baseline
//! needs the k viewpoints that see the most. Both are NP-hard; the greedy rule (take whatever
//! covers the most still-uncovered elements) is within a factor ln(u) + 1 of the smallest cover
//! and within 1 − 1/e of the best k. The greedy is lazy: a candidate's gain only shrinks as
//! others are chosen, so a stale gain is an upper bound and most candidates are never
//! re-counted.
//!
//! Sets are read through [`Coverage`], on demand, never held all at once: a map's visibility
//! sets as a matrix of bits grew with the square of its free cells (8.6 GB at 512 x 512
//! open), while on demand the greedy holds a bit per element and a gain per candidate.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

const WORD_BITS: usize = u64::BITS as usize;

/// Candidates and the elements `0..universe()` each covers.
pub(crate) trait Coverage {
    fn universe(&self) -> usize;
    fn candidates(&self) -> usize;
    /// Calls `each` once with every element `candidate` covers, all below `universe()`.
    fn elements_of(&self, candidate: usize, each: &mut dyn FnMut(usize));
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
    sets: &'a dyn Coverage,
    /// A bit per element still uncovered.
    uncovered: Vec<u64>,
    /// Gains as last counted; ties pop the lowest index first.
    queue: BinaryHeap<(usize, Reverse<usize>)>,
}

impl<'a> GreedyOrder<'a> {
    fn new(sets: &'a dyn Coverage) -> Self {
        let universe = sets.universe();
        let mut uncovered = vec![u64::MAX; universe.div_ceil(WORD_BITS)];
        if let Some(last) = uncovered.last_mut() {
            let used_bits = universe % WORD_BITS;
            if used_bits != 0 {
                *last = (1 << used_bits) - 1;
            }
        }
        let mut order = Self {
            sets,
            uncovered,
            queue: BinaryHeap::new(),
        };
        order.queue = (0..sets.candidates())
            .map(|candidate| (order.gain(candidate), Reverse(candidate)))
            .collect();
        order
    }

    fn gain(&self, candidate: usize) -> usize {
        let mut gain = 0;
        self.sets.elements_of(candidate, &mut |element| {
            gain += (self.uncovered[element / WORD_BITS] >> (element % WORD_BITS)) as usize & 1;
        });
        gain
    }

    fn take(&mut self, candidate: usize) {
        let uncovered = &mut self.uncovered;
        self.sets.elements_of(candidate, &mut |element| {
            uncovered[element / WORD_BITS] &= !(1 << (element % WORD_BITS));
        });
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
pub(crate) struct SetCover {
    /// In the order the greedy chose them.
    pub(crate) chosen: Vec<usize>,
    /// In increasing order.
    pub(crate) uncoverable: Vec<usize>,
}

/// Greedy set cover, then dropping candidates that became redundant once later ones were
/// chosen, so that every chosen candidate is the only one covering some element.
pub(crate) fn greedy_set_cover(sets: &dyn Coverage) -> SetCover {
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
fn drop_redundant(sets: &dyn Coverage, chosen: &mut Vec<usize>) {
    let mut coverers = vec![0u32; sets.universe()];
    for &candidate in chosen.iter() {
        sets.elements_of(candidate, &mut |element| coverers[element] += 1);
    }
    chosen.retain(|&candidate| {
        let mut redundant = true;
        sets.elements_of(candidate, &mut |element| redundant &= coverers[element] > 1);
        if redundant {
            sets.elements_of(candidate, &mut |element| coverers[element] -= 1);
        }
        !redundant
    });
}

/// The first `k` candidates of the greedy order (all of them if there are fewer), in that order.
/// Once everything coverable is covered the remaining picks add nothing and go to the lowest
/// unchosen indices, so the baseline always gets the `k` positions it asked for, and the result
/// for `k` is a prefix of the result for `k + 1`.
pub(crate) fn greedy_max_coverage(sets: &dyn Coverage, k: usize) -> Vec<usize> {
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

    /// Sets as lists of elements, each sorted and without repeats.
    struct IndexSets {
        universe: usize,
        lists: Vec<Vec<usize>>,
    }

    impl IndexSets {
        fn new(universe: usize, lists: &[Vec<usize>]) -> Self {
            assert!(lists.iter().flatten().all(|&e| e < universe));
            Self {
                universe,
                lists: lists.to_vec(),
            }
        }

        /// Number of elements covered by at least one of `chosen`.
        fn covered_count(&self, chosen: &[usize]) -> usize {
            let mut union: Vec<usize> =
                chosen.iter().flat_map(|&c| self.lists[c].clone()).collect();
            union.sort_unstable();
            union.dedup();
            union.len()
        }
    }

    impl Coverage for IndexSets {
        fn universe(&self) -> usize {
            self.universe
        }

        fn candidates(&self) -> usize {
            self.lists.len()
        }

        fn elements_of(&self, candidate: usize, each: &mut dyn FnMut(usize)) {
            self.lists[candidate].iter().for_each(|&e| each(e));
        }
    }

    fn random_sets(universe: usize, candidates: usize, density: f64, seed: u64) -> IndexSets {
        let mut rng = Pcg64Mcg::seed_from_u64(seed);
        let lists: Vec<Vec<usize>> = (0..candidates)
            .map(|_| (0..universe).filter(|_| rng.random_bool(density)).collect())
            .collect();
        IndexSets::new(universe, &lists)
    }

    fn all_candidates(sets: &IndexSets) -> Vec<usize> {
        (0..sets.candidates()).collect()
    }

    /// Smallest number of candidates covering everything coverable, by trying every subset.
    fn optimal_cover_size(sets: &IndexSets) -> usize {
        let coverable = sets.covered_count(&all_candidates(sets));
        (0u32..1 << sets.candidates())
            .map(subset)
            .filter(|chosen| sets.covered_count(chosen) == coverable)
            .map(|chosen| chosen.len())
            .min()
            .unwrap()
    }

    /// Most elements any `k` candidates cover, by trying every subset of that size.
    fn optimal_coverage(sets: &IndexSets, k: usize) -> usize {
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
    fn eager_greedy_order(sets: &IndexSets) -> Vec<usize> {
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
    fn ties_go_to_the_lowest_index() {
        let sets = IndexSets::new(4, &[vec![2], vec![0, 1], vec![0, 1], vec![3]]);
        assert_eq!(greedy_set_cover(&sets).chosen, vec![1, 0, 3]);
        assert_eq!(greedy_max_coverage(&sets, 4), vec![1, 0, 3, 2]);
    }

    #[test]
    fn drops_candidates_made_redundant_by_later_choices() {
        // Greedy takes 0 first, then 1 and 2, which together cover everything 0 did.
        let sets = IndexSets::new(6, &[vec![1, 2, 3, 4], vec![0, 1, 2], vec![3, 4, 5]]);
        assert_eq!(greedy_set_cover(&sets).chosen, vec![1, 2]);
    }

    #[test]
    fn reports_uncoverable_elements() {
        let sets = IndexSets::new(5, &[vec![0, 1], vec![3]]);
        let cover = greedy_set_cover(&sets);
        assert_eq!(cover.chosen, vec![0, 1]);
        assert_eq!(cover.uncoverable, vec![2, 4]);
    }

    #[test]
    fn empty_universe_needs_no_candidates() {
        let sets = IndexSets::new(0, &[Vec::new(), Vec::new()]);
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
