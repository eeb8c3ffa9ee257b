//! CSV answers (RFC 4180, a header row naming each column with its unit, CRLF line ends), and
//! the `Accept` negotiation that lets a JSON path answer CSV to curl users.

use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;

use super::respond::Json;

/// The media type of a CSV answer; `header=present` tells readers the first line names columns.
pub const TEXT_CSV: &str = "text/csv; charset=utf-8; header=present";

/// The representation of a `/table` or `/chart-data` answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataFormat {
    /// `application/json`.
    Json,
    /// `text/csv`: a header row naming each column with its unit (`distance_mm`), then one
    /// line per row.
    Csv,
}

/// A CSV document: the header row, then one line per row. A cell that is `None` is left empty;
/// numbers are written as the JSON writes them (shortest round-trip form).
pub fn write<R>(columns: &[String], rows: impl IntoIterator<Item = R>) -> String
where
    R: IntoIterator<Item = Option<f64>>,
{
    let mut out = columns.join(",");
    out.push_str("\r\n");
    for row in rows {
        for (i, value) in row.into_iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            if let Some(value) = value {
                stereo_core::numbers::push_json(&mut out, value);
            }
        }
        out.push_str("\r\n");
    }
    out
}

/// `name_unit`, the CSV header of a column measured in `unit` (`distance_mm`).
pub fn column(name: &str, unit: &str) -> String {
    format!("{name}_{unit}")
}

/// The answer in `format`: `json` as JSON, or `csv()` as a CSV attachment named `filename`.
/// Both vary with `Accept`, which caches must know of the JSON paths (harmless on the CSV
/// ones).
pub fn respond<T: Serialize>(
    format: DataFormat,
    json: T,
    csv: impl FnOnce(&T) -> String,
    filename: &'static str,
) -> Response {
    let vary = (header::VARY, HeaderValue::from_static("accept"));
    match format {
        DataFormat::Json => ([vary], Json(json)).into_response(),
        DataFormat::Csv => (
            [
                vary,
                (header::CONTENT_TYPE, HeaderValue::from_static(TEXT_CSV)),
                (
                    header::CONTENT_DISPOSITION,
                    HeaderValue::from_static(filename),
                ),
            ],
            csv(&json),
        )
            .into_response(),
    }
}

/// The format a JSON path answers in: the better of JSON and CSV by the `Accept` header's
/// q-values (a more specific match wins a tie; JSON wins what remains, including no header, a
/// browser's `*/*` and types we cannot produce).
pub fn negotiate(accept: Option<&HeaderValue>) -> DataFormat {
    let Some(accept) = accept.and_then(|v| v.to_str().ok()) else {
        return DataFormat::Json;
    };
    let json = preference(accept, "application", "json");
    let csv = preference(accept, "text", "csv");
    if csv > json {
        DataFormat::Csv
    } else {
        DataFormat::Json
    }
}

/// `(q, specificity)` of the most specific media range in `accept` matching `kind/subtype`;
/// `(0, 0)` when none does. q is compared in thousandths, as RFC 9110 allows no more digits.
fn preference(accept: &str, kind: &str, subtype: &str) -> (u16, u8) {
    let mut best: Option<(u8, u16)> = None;
    for range in accept.split(',') {
        let mut parts = range.split(';');
        let media = parts.next().unwrap_or_default().trim();
        let Some((k, s)) = media.split_once('/') else {
            continue;
        };
        let specificity = match (k.trim(), s.trim()) {
            (k, s) if k.eq_ignore_ascii_case(kind) && s.eq_ignore_ascii_case(subtype) => 2,
            (k, "*") if k.eq_ignore_ascii_case(kind) => 1,
            ("*", "*") => 0,
            _ => continue,
        };
        let q = parts
            .filter_map(|p| p.trim().strip_prefix("q=").or(p.trim().strip_prefix("Q=")))
            .filter_map(|q| q.trim().parse::<f64>().ok())
            .map(|q| (q.clamp(0.0, 1.0) * 1000.0).round() as u16)
            .next()
            .unwrap_or(1000);
        if best.is_none_or(|(s, _)| specificity > s) {
            best = Some((specificity, q));
        }
    }
    match best {
        Some((specificity, q)) if q > 0 => (q, specificity),
        _ => (0, 0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn accept(value: &'static str) -> DataFormat {
        negotiate(Some(&HeaderValue::from_static(value)))
    }

    /// CSV is chosen only when the client prefers it.
    #[test]
    fn negotiation() {
        assert_eq!(negotiate(None), DataFormat::Json);
        assert_eq!(accept("text/csv"), DataFormat::Csv);
        assert_eq!(accept("text/*"), DataFormat::Csv);
        assert_eq!(accept("text/csv, */*"), DataFormat::Csv);
        assert_eq!(accept("application/json"), DataFormat::Json);
        assert_eq!(accept("*/*"), DataFormat::Json);
        assert_eq!(
            accept("text/html,application/xhtml+xml,application/xml;q=0.9,*/*;q=0.8"),
            DataFormat::Json
        );
        assert_eq!(
            accept("text/csv;q=0.5, application/json;q=0.9"),
            DataFormat::Json
        );
        assert_eq!(
            accept("text/csv;q=0.9, application/json;q=0.5"),
            DataFormat::Csv
        );
        assert_eq!(accept("text/csv;q=0, */*"), DataFormat::Json);
        assert_eq!(accept("image/png"), DataFormat::Json);
    }

    /// Empty cells for absent values, CRLF ends, numbers in their shortest form.
    #[test]
    fn writes_rows() {
        let csv = write(
            &[column("distance", "mm"), "normalized_x".to_owned()],
            [[Some(105.0), None], [Some(0.1), Some(-0.125)]],
        );
        assert_eq!(csv, "distance_mm,normalized_x\r\n105.0,\r\n0.1,-0.125\r\n");
    }
}
