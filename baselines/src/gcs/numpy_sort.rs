//! numpy 1.x's `argsort` with its default kind ("quicksort"), ported step by step.
//!
//! The released GCS orders cells by penalty with `np.argsort` and reads the result backwards.
//! Penalties tie constantly (every cell unseen since the start holds the same value), and
//! numpy's default sort is an introsort whose order among equal keys is not stable: it
//! depends on the partitioning, so only the same algorithm gives the same hot spots. This is
//! numpy 1.x's `aquicksort` (median-of-three quicksort, insertion sort below 16 elements,
//! heapsort past a depth limit), the sort the authors' figures ran on; numpy 2.x may dispatch
//! to SIMD sorts with yet other tie orders. Keys compare with `<` only, as numpy's `LT` does
//! for values without NaN.

/// Partitions at most this long minus one are finished by insertion sort (numpy's
/// `SMALL_QUICKSORT`).
const SMALL_QUICKSORT: isize = 15;

/// numpy's `PYA_QS_STACK`: the larger partition is pushed, so the stack holds at most
/// log2(n) entries.
const STACK: usize = 128;

/// Writes into `order` the indices `0..keys.len()` sorted by key ascending, exactly as numpy
/// 1.x's `np.argsort(keys)` does, ties included. `order` is resized to fit.
pub(crate) fn argsort(keys: &[f64], order: &mut Vec<u32>) {
    order.clear();
    order.extend(0..keys.len() as u32);
    introsort(keys, order);
}

fn introsort(keys: &[f64], order: &mut [u32]) {
    let key = |order: &[u32], i: isize| keys[order[i as usize] as usize];
    let (mut pl, mut pr) = (0isize, order.len() as isize - 1);
    let mut stack = [(0isize, 0isize, 0i32); STACK];
    let mut pushed = 0;
    let mut depth_left = 2 * most_significant_bit(order.len()) as i32;
    loop {
        if depth_left < 0 {
            heapsort(keys, &mut order[pl as usize..=pr as usize]);
        } else {
            while pr - pl > SMALL_QUICKSORT {
                let pm = pl + ((pr - pl) >> 1);
                if key(order, pm) < key(order, pl) {
                    order.swap(pm as usize, pl as usize);
                }
                if key(order, pr) < key(order, pm) {
                    order.swap(pr as usize, pm as usize);
                }
                if key(order, pm) < key(order, pl) {
                    order.swap(pm as usize, pl as usize);
                }
                let pivot = key(order, pm);
                let (mut pi, mut pj) = (pl, pr - 1);
                order.swap(pm as usize, pj as usize);
                loop {
                    pi += 1;
                    while key(order, pi) < pivot {
                        pi += 1;
                    }
                    pj -= 1;
                    while pivot < key(order, pj) {
                        pj -= 1;
                    }
                    if pi >= pj {
                        break;
                    }
                    order.swap(pi as usize, pj as usize);
                }
                order.swap(pi as usize, (pr - 1) as usize);
                depth_left -= 1;
                if pi - pl < pr - pi {
                    stack[pushed] = (pi + 1, pr, depth_left);
                    pr = pi - 1;
                } else {
                    stack[pushed] = (pl, pi - 1, depth_left);
                    pl = pi + 1;
                }
                pushed += 1;
            }
            insertion_sort(keys, order, pl, pr);
        }
        if pushed == 0 {
            return;
        }
        pushed -= 1;
        (pl, pr, depth_left) = stack[pushed];
    }
}

/// numpy's `npy_get_msb`: floor(log2(n)), 0 for n < 2.
fn most_significant_bit(n: usize) -> u32 {
    n.checked_ilog2().unwrap_or(0)
}

fn insertion_sort(keys: &[f64], order: &mut [u32], pl: isize, pr: isize) {
    for pi in pl + 1..=pr {
        let moving = order[pi as usize];
        let value = keys[moving as usize];
        let mut pj = pi;
        while pj > pl && value < keys[order[(pj - 1) as usize] as usize] {
            order[pj as usize] = order[(pj - 1) as usize];
            pj -= 1;
        }
        order[pj as usize] = moving;
    }
}

/// numpy's `aheapsort` on one partition, with its one-based heap indexing.
fn heapsort(keys: &[f64], part: &mut [u32]) {
    let mut n = part.len();
    for top in (1..=n >> 1).rev() {
        let moving = part[top - 1];
        sift_down(keys, part, moving, top, n);
    }
    while n > 1 {
        let moving = part[n - 1];
        part[n - 1] = part[0];
        n -= 1;
        sift_down(keys, part, moving, 1, n);
    }

    fn sift_down(keys: &[f64], part: &mut [u32], moving: u32, top: usize, n: usize) {
        let key = |part: &[u32], i: usize| keys[part[i - 1] as usize];
        let value = keys[moving as usize];
        let (mut i, mut j) = (top, top << 1);
        while j <= n {
            if j < n && key(part, j) < key(part, j + 1) {
                j += 1;
            }
            if value < key(part, j) {
                part[i - 1] = part[j - 1];
                i = j;
                j += j;
            } else {
                break;
            }
        }
        part[i - 1] = moving;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Keys with few distinct values, so that almost every comparison is a tie: `family` 0
    /// cycles through five values, `family` 1 is mostly zeros with plateaus (like a penalty
    /// map). The same formulas in numpy give the orders pinned below.
    fn tie_heavy_keys(family: u8, multiplier: u64, length: usize) -> Vec<f64> {
        (0..length as u64)
            .map(|i| match family {
                0 => (i * multiplier + i / 7) % 5,
                _ if i % 13 < 9 => 0,
                _ => (i / 50 * multiplier) % 4,
            })
            .map(|value| value as f64)
            .collect()
    }

    /// (family, multiplier, length, sum over positions p of (p + 1) * order[p], first six
    /// indices), as numpy 1.24.4 printed them with `kind="quicksort"` (the default).
    const NUMPY_QUICKSORT: [(u8, u64, usize, u64, [u32; 6]); 8] = [
        (0, 3, 17, 1255, [0, 13, 5, 8, 16, 2]),
        (0, 7, 100, 246925, [0, 33, 35, 40, 42, 47]),
        (0, 11, 2500, 3871669136, [0, 1536, 482, 1532, 1527, 486]),
        (0, 13, 3001, 6695587411, [0, 953, 2520, 958, 961, 2517]),
        (1, 3, 17, 1114, [0, 14, 13, 12, 11, 10]),
        (1, 7, 100, 232474, [0, 67, 66, 65, 60, 59]),
        (1, 11, 2500, 3459964970, [0, 1576, 1575, 1574, 1573, 1568]),
        (1, 13, 3001, 6005971410, [0, 1852, 1853, 1854, 1859, 1860]),
    ];

    /// The same with `kind="heapsort"`, numpy's fallback past the depth limit.
    const NUMPY_HEAPSORT: [(u8, u64, usize, u64, [u32; 6]); 8] = [
        (0, 3, 17, 1213, [13, 0, 5, 16, 8, 2]),
        (0, 7, 100, 249296, [68, 5, 82, 98, 26, 70]),
        (0, 11, 2500, 3927875829, [9, 753, 1672, 600, 442, 2026]),
        (0, 13, 3001, 6796968777, [1050, 2501, 923, 2708, 2175, 565]),
        (1, 3, 17, 1496, [1, 2, 3, 4, 5, 6]),
        (1, 7, 100, 288579, [91, 43, 96, 92, 4, 21]),
        (1, 11, 2500, 3944006313, [2014, 966, 2057, 2015, 1964, 482]),
        (1, 13, 3001, 6855529439, [1188, 577, 2445, 147, 2348, 35]),
    ];

    fn check(pinned: &[(u8, u64, usize, u64, [u32; 6])], sort: impl Fn(&[f64], &mut Vec<u32>)) {
        for &(family, multiplier, length, weighted, first) in pinned {
            let keys = tie_heavy_keys(family, multiplier, length);
            let mut order = Vec::new();
            sort(&keys, &mut order);
            let case = format!("family {family}, multiplier {multiplier}, length {length}");
            assert!(
                order.is_sorted_by_key(|&i| keys[i as usize] as u64),
                "{case}"
            );
            assert_eq!(order[..6], first, "{case}");
            let sum: u64 = (1..).zip(&order).map(|(p, &i)| p * u64::from(i)).sum();
            assert_eq!(sum, weighted, "{case}");
        }
    }

    #[test]
    fn sorts_like_numpy_1x_ties_included() {
        check(&NUMPY_QUICKSORT, argsort);
    }

    #[test]
    fn heapsort_fallback_sorts_like_numpy_1x() {
        check(&NUMPY_HEAPSORT, |keys, order| {
            order.clear();
            order.extend(0..keys.len() as u32);
            heapsort(keys, order);
        });
    }

    #[test]
    fn empty_and_single_keys() {
        let mut order = vec![7];
        argsort(&[], &mut order);
        assert!(order.is_empty());
        argsort(&[2.0], &mut order);
        assert_eq!(order, [0]);
    }
}
