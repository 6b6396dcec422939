//! "Did you mean …?": the names closest to a mistyped one, by one rule for
//! every message (unknown parameters, properties, operators, keys, rules).

/// Optimal-string-alignment distance over characters: Levenshtein plus
/// adjacent transpositions, so `widht` is one edit from `width`.
pub fn edit_distance(a: &str, b: &str) -> usize {
    let (a, b): (Vec<char>, Vec<char>) = (a.chars().collect(), b.chars().collect());
    // Rows of the distance table for prefixes of `a` of length i - 1, i and i + 1.
    let mut before = vec![0; b.len() + 1];
    let mut previous: Vec<usize> = (0..=b.len()).collect();
    let mut current = vec![0; b.len() + 1];
    for (i, &ca) in a.iter().enumerate() {
        current[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let mut best = (previous[j] + usize::from(ca != cb))
                .min(previous[j + 1] + 1)
                .min(current[j] + 1);
            if i > 0 && j > 0 && ca == b[j - 1] && a[i - 1] == cb {
                best = best.min(before[j - 1] + 1);
            }
            current[j + 1] = best;
        }
        std::mem::swap(&mut before, &mut previous);
        std::mem::swap(&mut previous, &mut current);
    }
    previous[b.len()]
}

/// Indices of the candidates close enough to `word` to be typos of it,
/// closest first (ties in candidate order): at most n / 3 edits for a
/// candidate of n characters, and at least 1 (2 from five characters on). `word` itself is not a suggestion,
/// and candidates whose length differs by more than the limit are not
/// even compared (a huge hostile name costs nothing).
pub fn suggestions<S: AsRef<str>>(word: &str, candidates: &[S]) -> Vec<usize> {
    let length = word.chars().count();
    let mut scored: Vec<(usize, usize)> = candidates
        .iter()
        .enumerate()
        .filter_map(|(i, c)| {
            let c = c.as_ref();
            let n = c.chars().count();
            let limit = (n / 3).max(if n >= 5 { 2 } else { 1 });
            if c == word || n.abs_diff(length) > limit {
                return None;
            }
            let d = edit_distance(word, c);
            (d <= limit).then_some((d, i))
        })
        .collect();
    scored.sort_unstable();
    scored.into_iter().map(|(_, i)| i).collect()
}

/// The closest of `candidates` to `word`, if any is close enough.
pub fn closest<S: AsRef<str>>(word: &str, candidates: &[S]) -> Option<usize> {
    suggestions(word, candidates).first().copied()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_counts_transpositions_once() {
        assert_eq!(edit_distance("widht", "width"), 1);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("é", "e"), 1);
    }

    #[test]
    fn suggestions_are_close_names_closest_first() {
        let names = ["width", "depth", "height", "wide"];
        assert_eq!(suggestions("widht", &names), [0]);
        assert_eq!(suggestions("wid", &names), [3, 0], "closest first");
        assert_eq!(closest("hieght", &names), Some(2));
        assert_eq!(closest("zzzzzzzz", &names), None);
        assert_eq!(closest("width", &names), None, "an exact name is no typo");
        assert!(suggestions(&"x".repeat(100_000), &names).is_empty());
    }
}
