//! serde's refusal of one request member, said in the API's own words: what the member must
//! be and what it got (`unit must be one of mm, cm, m, in, ft, got `meters``), never serde's
//! (`unknown variant`, `invalid type: string`, `expected f64`). Echoed values are short: numbers
//! in their shortest exact form, text cut to [`ECHO`] characters.

use serde_json::Value;

use stereo_core::numbers::{Num, clip};

/// The most characters of a caller's text that a message echoes.
pub const ECHO: usize = 40;

/// What serde said about a member, parsed.
#[derive(Debug, PartialEq)]
pub enum Complaint<'a> {
    /// `unknown field `x`, expected one of `a`, `b``: the member and the known ones.
    UnknownField { name: &'a str, known: Vec<&'a str> },
    /// `unknown variant `x`, expected one of `a`, `b``: the allowed values.
    UnknownVariant { allowed: Vec<&'a str> },
    /// `invalid type: …, expected …` or `invalid value: …, expected …`.
    Mismatch { got: &'a str, expected: &'a str },
    /// `duplicate field `x``.
    Duplicate { name: &'a str },
    /// `missing field `x``.
    Missing { name: &'a str },
    /// A message of the API's own (such as `must not be null; …`), passed on as it is.
    Own(&'a str),
}

/// Parses serde_json's message, without its ` at line … column …` suffix.
pub fn parse<'a>(text: &'a str) -> Complaint<'a> {
    let text = text.split(" at line ").next().unwrap_or(text);
    let quoted = |list: &'a str| -> Vec<&'a str> { list.split('`').skip(1).step_by(2).collect() };
    if let Some(rest) = text.strip_prefix("unknown field `")
        && let Some((name, expected)) = rest.split_once('`')
    {
        return Complaint::UnknownField {
            name,
            known: quoted(expected),
        };
    }
    if let Some(rest) = text.strip_prefix("unknown variant `")
        && let Some((_, expected)) = rest.split_once("`, expected ")
    {
        return Complaint::UnknownVariant {
            allowed: quoted(expected),
        };
    }
    for prefix in ["invalid type: ", "invalid value: "] {
        if let Some(rest) = text.strip_prefix(prefix)
            && let Some((got, expected)) = rest.rsplit_once(", expected ")
        {
            return Complaint::Mismatch { got, expected };
        }
    }
    let named = |prefix: &str| {
        text.strip_prefix(prefix)
            .and_then(|rest| rest.split('`').next())
    };
    if let Some(name) = named("duplicate field `") {
        return Complaint::Duplicate { name };
    }
    if let Some(name) = named("missing field `") {
        return Complaint::Missing { name };
    }
    Complaint::Own(text)
}

/// The message for a member that serde refused: `text` is serde's message, `value` the member
/// as given (a list member's message is about one of its items).
pub fn message(text: &str, value: Option<&Value>) -> String {
    match parse(text) {
        Complaint::UnknownField { name, known } => unknown_field(name, &known),
        Complaint::UnknownVariant { allowed } => one_of(&allowed, value),
        Complaint::Mismatch { got, expected } => {
            // A list member's message is about an item when serde saw something in it.
            let item =
                value.is_some_and(Value::is_array) && got != "sequence" && expected != "a sequence";
            let expected = expectation(expected);
            let got = given(got);
            let hint = decimal_comma_hint(&got, &expected);
            if item {
                format!("every item must be {expected}, got {got}{hint}")
            } else {
                format!("must be {expected}, got {got}{hint}")
            }
        }
        Complaint::Duplicate { .. } => "is given more than once; give it once".to_owned(),
        Complaint::Missing { .. } => "is required".to_owned(),
        Complaint::Own(text) => text.to_owned(),
    }
}

/// `unknown field `x`; did you mean `y`?` for a near miss, else the members there are.
pub fn unknown_field(name: &str, known: &[&str]) -> String {
    let name = clip(name, ECHO);
    let nearest = known
        .iter()
        .map(|k| (stereo_core::numbers::edit_distance(&name, k), *k))
        .min()
        .filter(|(distance, _)| *distance <= name.chars().count() / 2);
    match (nearest, known) {
        (Some((_, nearest)), _) => format!("unknown field `{name}`; did you mean `{nearest}`?"),
        (None, []) => format!("unknown field `{name}`; this object takes no members"),
        (None, known) => format!(
            "unknown field `{name}`; the members here are {}",
            known.join(", ")
        ),
    }
}

/// `must be one of a, b, c, got …` (`must be a or b` for two).
fn one_of(allowed: &[&str], value: Option<&Value>) -> String {
    let choices = match allowed {
        [] => "one of the documented values".to_owned(),
        [one] => (*one).to_owned(),
        [a, b] => format!("{a} or {b}"),
        many => format!("one of {}", many.join(", ")),
    };
    match value {
        Some(value) => format!("must be {choices}, got {}", describe(value)),
        None => format!("must be {choices}"),
    }
}

/// serde's expectation in words. The others a request member can meet are already words:
/// `a whole number` and `an object` (the API's own visitors), `a string`.
fn expectation(expected: &str) -> String {
    match expected {
        "f64" => "a number".to_owned(),
        "a sequence" => "a list".to_owned(),
        other => other.to_owned(),
    }
}

/// serde's `Unexpected` in words: `string "x"` is `` `x` ``, `floating point `1.5`` is 1.5,
/// `sequence` is a list.
fn given(got: &str) -> String {
    if let Some(text) = got.strip_prefix("string ") {
        let text = serde_json::from_str::<String>(text).unwrap_or_else(|_| text.to_owned());
        return format!("`{}`", clip(&text, ECHO));
    }
    for prefix in ["floating point `", "integer `", "boolean `"] {
        if let Some(rest) = got.strip_prefix(prefix) {
            let raw = rest.trim_end_matches('`');
            return match raw.parse::<f64>() {
                Ok(number) => Num(number).to_string(),
                Err(_) => clip(raw, ECHO),
            };
        }
    }
    match got {
        "sequence" => "a list".to_owned(),
        "map" => "an object".to_owned(),
        "unit value" | "null" => "null".to_owned(),
        other => clip(other, ECHO),
    }
}

/// A JSON value in words, for messages: text in backticks (cut short), numbers exact.
pub fn describe(value: &Value) -> String {
    match value {
        Value::Null => "null".to_owned(),
        Value::Bool(b) => b.to_string(),
        Value::Number(n) => n
            .as_f64()
            .map_or_else(|| n.to_string(), |x| Num(x).to_string()),
        Value::String(s) => format!("`{}`", clip(s, ECHO)),
        Value::Array(_) => "a list".to_owned(),
        Value::Object(_) => "an object".to_owned(),
    }
}

/// `0,54` where a number belongs is a decimal comma.
fn decimal_comma_hint(got: &str, expected: &str) -> &'static str {
    let text = got.trim_matches('`');
    let comma = text.matches(',').count() == 1 && text.replace(',', ".").parse::<f64>().is_ok();
    if expected == "a number" && comma {
        "; use a dot for decimals"
    } else {
        ""
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// serde's wording never reaches the caller: each refusal says what was expected and
    /// what was given.
    #[test]
    fn refusals_in_our_words() {
        let cases = [
            (
                "unknown variant `meters`, expected one of `mm`, `cm`, `m`, `in`, `ft`",
                json!("meters"),
                "must be one of mm, cm, m, in, ft, got `meters`",
            ),
            (
                "unknown variant `cubic`, expected `linear` or `log`",
                json!("cubic"),
                "must be linear or log, got `cubic`",
            ),
            (
                "invalid type: string \"0,54\", expected f64",
                json!("0,54"),
                "must be a number, got `0,54`; use a dot for decimals",
            ),
            (
                "invalid type: string \"abc\", expected f64 at line 1 column 9",
                json!("abc"),
                "must be a number, got `abc`",
            ),
            (
                "invalid type: floating point `1242.5`, expected a whole number",
                json!(1242.5),
                "must be a whole number, got 1242.5",
            ),
            (
                "invalid type: boolean `true`, expected f64",
                json!(true),
                "must be a number, got true",
            ),
            (
                "invalid type: sequence, expected f64",
                json!([1]),
                "must be a number, got a list",
            ),
            (
                "invalid type: string \"x\", expected f64",
                json!([1, "x"]),
                "every item must be a number, got `x`",
            ),
            (
                "invalid type: integer `5`, expected a sequence",
                json!(5),
                "must be a list, got 5",
            ),
            (
                "invalid type: map, expected f64",
                json!({}),
                "must be a number, got an object",
            ),
        ];
        for (serde, value, ours) in cases {
            assert_eq!(message(serde, Some(&value)), ours, "{serde}");
        }
    }

    /// Long or odd echoes stay short: a 1e308 is written `1e308`, long text is cut.
    #[test]
    fn echoes_are_short() {
        assert_eq!(
            message(
                "invalid type: floating point `1e308`, expected a whole number",
                Some(&json!(1e308))
            ),
            "must be a whole number, got 1e308"
        );
        let long = "x".repeat(10_000);
        let text = format!("invalid type: string \"{long}\", expected f64");
        assert!(message(&text, Some(&json!(long))).len() < 100);
        assert!(unknown_field(&long, &["a"]).len() < 120);
    }

    /// A misspelt member gets the nearest known name; a stranger one gets the list.
    #[test]
    fn unknown_members() {
        assert_eq!(stereo_core::numbers::edit_distance("kitten", "sitting"), 3);
        assert_eq!(
            message(
                "unknown field `baselin`, expected one of `baseline`, `unit`",
                None
            ),
            "unknown field `baselin`; did you mean `baseline`?"
        );
        assert_eq!(
            message(
                "unknown field `colour`, expected one of `baseline`, `unit`",
                None
            ),
            "unknown field `colour`; the members here are baseline, unit"
        );
        assert_eq!(
            message("duplicate field `a`", None),
            "is given more than once; give it once"
        );
        assert_eq!(
            message("must not be null; leave the member out", None),
            "must not be null; leave the member out"
        );
    }
}
