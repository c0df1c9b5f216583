//! The import report: every feature read is accounted for.

use serde::Serialize;

/// A feature the importer could not turn into geometry, and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Refusal {
    /// The feature's id in its file ([`crate::Feature::fid`]).
    pub fid: u64,
    /// Why it was refused, in words a user understands.
    pub reason: String,
}

/// Refusals that share a reason (up to the numbers in it), counted.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReasonGroup {
    /// The reason, as given for the group's first feature.
    pub reason: String,
    /// How many features were refused for it.
    pub count: usize,
    /// The ids of the first few of them.
    pub examples: Vec<String>,
}

/// How many ids a [`ReasonGroup`] lists.
pub const GROUP_EXAMPLES: usize = 5;

/// The key that groups reasons: the text with every run of digits (and the signs, points and
/// exponents around them) replaced by `#`, so that "vertex 3" and "vertex 7" fall together.
fn reason_key(reason: &str) -> String {
    let chars: Vec<char> = reason.chars().collect();
    let mut out = String::with_capacity(reason.len());
    let mut in_number = false;
    for (i, &c) in chars.iter().enumerate() {
        let next_digit = chars.get(i + 1).is_some_and(char::is_ascii_digit);
        let numeric = c.is_ascii_digit()
            || (matches!(c, '-' | '+') && next_digit)
            || (in_number && matches!(c, '.' | 'e' | 'E'));
        if numeric {
            if !in_number {
                out.push('#');
            }
            in_number = true;
        } else {
            in_number = false;
            out.push(c);
        }
    }
    out
}

/// Groups `(id, reason)` pairs by reason (numbers ignored), largest group first, ties in order of
/// first appearance.
pub fn group_reasons<'a>(items: impl IntoIterator<Item = (String, &'a str)>) -> Vec<ReasonGroup> {
    let mut groups: Vec<(String, ReasonGroup)> = Vec::new();
    for (id, reason) in items {
        let key = reason_key(reason);
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, g)) => {
                g.count += 1;
                if g.examples.len() < GROUP_EXAMPLES {
                    g.examples.push(id);
                }
            }
            None => groups.push((
                key,
                ReasonGroup {
                    reason: reason.to_string(),
                    count: 1,
                    examples: vec![id],
                },
            )),
        }
    }
    let mut out: Vec<ReasonGroup> = groups.into_iter().map(|(_, g)| g).collect();
    out.sort_by_key(|g| std::cmp::Reverse(g.count));
    out
}

/// Formats groups as one line each: `count × reason (e.g. ids)`.
pub fn format_groups(groups: &[ReasonGroup]) -> String {
    groups
        .iter()
        .map(|g| {
            format!(
                "{} × {} (e.g. {}{})",
                g.count,
                g.reason,
                g.examples.join(", "),
                if g.count > g.examples.len() {
                    ", …"
                } else {
                    ""
                }
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// What one reader did with one file.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ImportReport {
    /// Records found in the file.
    pub read: usize,
    /// Features handed on in [`crate::Layer::features`].
    pub imported: usize,
    /// Features refused, with reasons.
    pub refused: Vec<Refusal>,
    /// The refusals grouped by reason, with counts (filled by [`Self::group_refusals`], which
    /// every reader calls last).
    pub refused_by_reason: Vec<ReasonGroup>,
    /// Things the reader noticed that concern the whole layer (CRS found, fields missing, …).
    pub notes: Vec<String>,
}

impl ImportReport {
    /// Records a refused feature.
    pub fn refuse(&mut self, fid: u64, reason: impl Into<String>) {
        self.refused.push(Refusal {
            fid,
            reason: reason.into(),
        });
    }

    /// Fills [`Self::refused_by_reason`] from [`Self::refused`].
    pub fn group_refusals(&mut self) {
        self.refused_by_reason = group_reasons(
            self.refused
                .iter()
                .map(|r| (r.fid.to_string(), r.reason.as_str())),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reasons_group_up_to_their_numbers() {
        let mut r = ImportReport::default();
        r.refuse(1, "non-finite coordinate at vertex 3");
        r.refuse(2, "null geometry");
        r.refuse(3, "non-finite coordinate at vertex 17");
        r.refuse(4, "latitude 95.5° is beyond ±90°");
        r.refuse(5, "latitude -1e3° is beyond ±90°");
        r.refuse(6, "non-finite coordinate at vertex 0");
        r.group_refusals();
        let g = &r.refused_by_reason;
        assert_eq!(g.len(), 3);
        assert_eq!(g[0].count, 3);
        assert_eq!(g[0].examples, ["1", "3", "6"]);
        assert_eq!(g[0].reason, "non-finite coordinate at vertex 3");
        assert_eq!((g[1].count, g[2].count), (2, 1));
        assert!(g[1].reason.starts_with("latitude"));
        let text = format_groups(g);
        assert!(text.starts_with("3 × non-finite"), "{text}");
    }
}
