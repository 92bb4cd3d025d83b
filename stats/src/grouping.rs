//! Rows grouped by key in order of first appearance, so that tables and figures list groups as
//! the store lists cells, whatever polars' hash order.

/// The distinct values of `items` in order of first appearance.
pub fn distinct<T: Clone + PartialEq>(items: impl IntoIterator<Item = T>) -> Vec<T> {
    let mut seen: Vec<T> = Vec::new();
    for item in items {
        if !seen.contains(&item) {
            seen.push(item);
        }
    }
    seen
}

/// Row indices grouped by key, groups in order of first appearance.
pub fn group_rows<T: Clone + PartialEq>(keys: &[T]) -> Vec<(T, Vec<usize>)> {
    let mut groups: Vec<(T, Vec<usize>)> = Vec::new();
    for (row, key) in keys.iter().enumerate() {
        match groups.iter_mut().find(|(k, _)| k == key) {
            Some((_, rows)) => rows.push(row),
            None => groups.push((key.clone(), vec![row])),
        }
    }
    groups
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_keep_first_appearance_order() {
        let keys = ["b", "a", "b", "c", "a"];
        let groups = group_rows(&keys);
        assert_eq!(
            groups,
            vec![("b", vec![0, 2]), ("a", vec![1, 4]), ("c", vec![3])]
        );
        assert_eq!(distinct(keys), vec!["b", "a", "c"]);
    }
}
