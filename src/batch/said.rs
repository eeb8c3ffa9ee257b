//! The service's warnings over a run: each said once, when the first pair says it, and at the
//! end grouped with how many pairs said the same (the same words, numbers aside: "corners lie
//! 13.4 px off their rows" and "… 12.9 px …" are one warning).

/// The warnings said so far, in the order first said.
#[derive(Debug, Default)]
pub struct Said {
    groups: Vec<Group>,
}

#[derive(Debug)]
struct Group {
    key: String,
    pairs: Vec<String>,
}

impl Said {
    /// Records `pair`'s warnings, and gives the lines to print now: each warning no pair said
    /// before.
    pub fn add(&mut self, pair: &str, warnings: &[String]) -> Vec<String> {
        let mut now = Vec::new();
        for warning in warnings {
            let key = key(warning);
            match self.groups.iter_mut().find(|g| g.key == key) {
                Some(group) => {
                    if group.pairs.last().is_none_or(|p| p != pair) {
                        group.pairs.push(pair.to_owned());
                    }
                }
                None => {
                    now.push(format!("warning {pair}: {warning}"));
                    self.groups.push(Group {
                        key,
                        pairs: vec![pair.to_owned()],
                    });
                }
            }
        }
        now
    }

    /// The closing lines: for each warning more than one pair said, how many and which (the
    /// first ten by name).
    pub fn summary(&self) -> Vec<String> {
        const NAMED: usize = 10;
        self.groups
            .iter()
            .filter(|g| g.pairs.len() > 1)
            .map(|g| {
                let mut sorted = g.pairs.clone();
                sorted.sort();
                let mut names = sorted[..sorted.len().min(NAMED)].join(", ");
                if g.pairs.len() > NAMED {
                    names.push_str(&format!(" and {} more", g.pairs.len() - NAMED));
                }
                format!(
                    "the warning first said of {} was said of {} pairs: {names}",
                    g.pairs[0],
                    g.pairs.len()
                )
            })
            .collect()
    }
}

/// A warning's words with each number as `#`.
fn key(warning: &str) -> String {
    let mut out = String::with_capacity(warning.len());
    let mut in_number = false;
    for c in warning.chars() {
        let digit = c.is_ascii_digit() || (in_number && c == '.');
        if digit {
            if !in_number {
                out.push('#');
            }
        } else {
            out.push(c);
        }
        in_number = digit;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A warning is printed for the first pair that says it; the same words with other
    /// numbers are grouped, and the end names how many pairs said each.
    #[test]
    fn warnings_are_said_once_and_grouped() {
        let mut said = Said::default();
        let rows = |px: &str| format!("matched corners lie {px} px off their rows");
        let first = said.add("0001", &[rows("13.4"), "left has no end marker".to_owned()]);
        assert_eq!(
            first,
            [
                "warning 0001: matched corners lie 13.4 px off their rows",
                "warning 0001: left has no end marker"
            ]
        );
        assert!(said.add("0002", &[rows("12.9")]).is_empty());
        assert!(said.add("0003", &[rows("7")]).is_empty());
        assert_eq!(
            said.add("0004", &["other".to_owned()]),
            ["warning 0004: other"]
        );
        assert_eq!(
            said.summary(),
            ["the warning first said of 0001 was said of 3 pairs: 0001, 0002, 0003"]
        );
        for n in 5..20 {
            said.add(&format!("{n:04}"), &[rows("1.5")]);
        }
        assert!(
            said.summary()[0].ends_with("0011 and 8 more"),
            "{:?}",
            said.summary()
        );
    }
}
