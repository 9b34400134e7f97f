//! "Did you mean" suggestions, for the spec's messages and the CLI's alike.
//!
//! The distance counts a swap of neighbours (`dorp` for `drop`) as one
//! edit, as a typist makes it. A candidate is suggested within a third of
//! the longer word's length (rounded up, at least one edit), so that a
//! short word unlike every candidate (`foo` beside the sensor `cod`) gets
//! no suggestion.
//!
//! ```
//! use yosemitech_spec::suggest::closest;
//! assert_eq!(closest("dorp", &["drop", "delay", "busy"]), Some("drop"));
//! assert_eq!(closest("zzzz", &["drop", "delay", "busy"]), None);
//! ```

/// The candidate closest to `word` by edit distance, if close enough to be a typo.
pub fn closest<'a>(word: &str, candidates: &[&'a str]) -> Option<&'a str> {
    candidates
        .iter()
        .map(|c| (edit_distance(word, c), *c))
        .filter(|(d, c)| *d <= c.len().max(word.len()).div_ceil(3).max(1))
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

/// Edit distance counting a swap of neighbours as one edit (optimal string alignment).
pub fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let width = b.len() + 1;
    let mut d = vec![0usize; (a.len() + 1) * width];
    for (i, row) in d.chunks_mut(width).enumerate() {
        row[0] = i;
    }
    for (j, cell) in d.iter_mut().enumerate().take(width) {
        *cell = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut best =
                (d[(i - 1) * width + j] + 1).min(d[i * width + j - 1] + 1).min(d[(i - 1) * width + j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                best = best.min(d[(i - 2) * width + j - 2] + 1);
            }
            d[i * width + j] = best;
        }
    }
    d[a.len() * width + b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typos() {
        let keys = ["name", "use", "address", "count"];
        assert_eq!(closest("adress", &keys), Some("address"));
        assert_eq!(closest("cuont", &keys), Some("count"));
        assert_eq!(closest("banana", &keys), None);
        assert_eq!(closest("probe_a", &["probe_ab", "other"]), Some("probe_ab"));
        assert_eq!(closest("othr", &["probe_ab", "other"]), Some("other"));
        assert_eq!(closest("zzzzzzzz", &["probe_ab", "other"]), None);
    }

    #[test]
    fn a_swap_of_neighbours_is_one_edit() {
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("dorp", "drop"), 1);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("µS/cm", "uS/cm"), 1);
    }
}
