//! "Did you mean …?": the known names closest to a name that was not recognised (a config key, a
//! method, a mapping key, a simulator preset or override), for error messages.
//!
//! A candidate is close when its optimal-string-alignment distance (Damerau–Levenshtein with
//! adjacent transpositions, `strsim::osa_distance`) to the name is at most [`MAX_DISTANCE`] —
//! comparing whole names and, for dotted keys (`ranging.range_std`), also their last parts, so
//! the flat `range_sdt` finds `ranging.range_std` — or when it starts with the name.

/// Largest edit distance of a suggestion.
pub const MAX_DISTANCE: usize = 2;

/// Most suggestions returned.
pub const MAX_SUGGESTIONS: usize = 3;

/// Shortest name that is completed by a prefix match (shorter ones match too much).
const MIN_PREFIX: usize = 3;

/// The part of a dotted key after its last dot (the whole key when it has none).
fn last_part(key: &str) -> &str {
    key.rsplit_once('.').map_or(key, |(_, field)| field)
}

/// How close `candidate` is to `got`: an edit distance, [`MAX_DISTANCE`] + 1 for a prefix match,
/// None when it is not close.
fn closeness(got: &str, candidate: &str) -> Option<usize> {
    let whole = strsim::osa_distance(got, candidate);
    let parts = strsim::osa_distance(last_part(got), last_part(candidate));
    let d = whole.min(parts);
    // A distance as long as the name itself would suggest anything of that length.
    if d <= MAX_DISTANCE && d < got.chars().count() {
        return Some(d);
    }
    let prefix =
        got.chars().count() >= MIN_PREFIX && (candidate.starts_with(got) || last_part(candidate).starts_with(last_part(got)));
    prefix.then_some(MAX_DISTANCE + 1)
}

/// Up to [`MAX_SUGGESTIONS`] of `candidates` close to `got`, closest first (ties in the order
/// given); empty when none is close or `got` is itself a candidate.
pub fn did_you_mean<'a>(got: &str, candidates: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
    let mut close: Vec<(usize, &str)> = Vec::new();
    for c in candidates {
        if c == got {
            return Vec::new();
        }
        if let Some(d) = closeness(got, c) {
            close.push((d, c));
        }
    }
    close.sort_by_key(|(d, _)| *d);
    close.into_iter().take(MAX_SUGGESTIONS).map(|(_, c)| c).collect()
}

/// The suggestions as a message fragment: ` (did you mean `a`?)`, ` (did you mean `a` or `b`?)`,
/// or the empty string when there are none.
pub fn phrase<S: AsRef<str>>(suggestions: &[S]) -> String {
    let quoted: Vec<String> = suggestions.iter().map(|s| format!("`{}`", s.as_ref())).collect();
    match quoted.split_last() {
        None => String::new(),
        Some((last, [])) => format!(" (did you mean {last}?)"),
        Some((last, rest)) => format!(" (did you mean {} or {last}?)", rest.join(", ")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEYS: [&str; 5] =
        ["ranging.range_std", "ranging.tdoa_std", "robust.significance", "unscented.alpha", "sage_husa.alpha"];

    #[test]
    fn a_transposition_or_a_dropped_letter_is_found() {
        assert_eq!(did_you_mean("rekff", ["ekf", "rekf", "riekf", "ukf"]), ["rekf", "ekf", "riekf"]);
        assert_eq!(did_you_mean("ranging.range_sdt", KEYS), ["ranging.range_std"]);
        assert_eq!(did_you_mean("imu_topc", ["time_source", "imu_topic", "uwb"]), ["imu_topic"]);
    }

    #[test]
    fn a_flat_field_finds_its_dotted_key() {
        assert_eq!(did_you_mean("range_sdt", KEYS), ["ranging.range_std"]);
        assert_eq!(did_you_mean("robust.alpha", KEYS), ["unscented.alpha", "sage_husa.alpha"]);
    }

    #[test]
    fn a_prefix_is_completed_after_the_close_names() {
        assert_eq!(did_you_mean("signif", KEYS), ["robust.significance"]);
        assert!(did_you_mean("cr", ["criekf", "ckf"]).is_empty(), "a two-letter name is no prefix");
    }

    #[test]
    fn far_names_exact_names_and_the_limit() {
        assert!(did_you_mean("kalman", ["ekf", "rekf", "uwb_ls"]).is_empty());
        assert!(did_you_mean("rekf", ["ekf", "rekf"]).is_empty(), "a known name needs no suggestion");
        assert!(did_you_mean("x", ["y", "z"]).is_empty(), "one letter is not a typo of another");
        assert_eq!(did_you_mean("ab", ["abc", "abd", "abe", "abf"]).len(), MAX_SUGGESTIONS);
    }

    #[test]
    fn the_phrase_reads_as_english() {
        assert_eq!(phrase::<&str>(&[]), "");
        assert_eq!(phrase(&["rekf"]), " (did you mean `rekf`?)");
        assert_eq!(phrase(&["a", "b", "c"]), " (did you mean `a`, `b` or `c`?)");
    }
}
