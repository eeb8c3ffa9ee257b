//! `/table` as CSV (RFC 4180, with a header row and the JSON's column names), and the choice
//! between CSV and JSON: an explicit `format` first, then the `Accept` header.

use axum::http::HeaderValue;

use super::types::{TableFormat, TableResponse, TableRow};

/// The media type of a CSV table; `header=present` tells readers the first line names columns.
pub const TEXT_CSV: &str = "text/csv; charset=utf-8; header=present";

/// The header row: the members of a JSON [`TableRow`], in the same order.
pub const COLUMNS: [&str; 5] = [
    "distance",
    "disparity_px",
    "normalized_x",
    "projection_factor",
    "depth_error",
];

fn cells(row: &TableRow) -> [f64; 5] {
    [
        row.distance,
        row.disparity_px,
        row.normalized_x,
        row.projection_factor,
        row.depth_error,
    ]
}

/// The table's rows as CSV, numbers written exactly as the JSON writes them (shortest
/// round-trip form), lines ended with CRLF.
pub fn table(table: &TableResponse) -> String {
    let mut out = String::with_capacity(80 + table.rows.len() * 96);
    out.push_str(&COLUMNS.join(","));
    out.push_str("\r\n");
    let mut buffer = ryu::Buffer::new();
    for row in &table.rows {
        for (i, value) in cells(row).into_iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            out.push_str(buffer.format(value));
        }
        out.push_str("\r\n");
    }
    out
}

/// The format to answer in: `explicit` when given, else the better of JSON and CSV by the
/// `Accept` header's q-values (a more specific match wins a tie; JSON wins what remains,
/// including no header, a browser's `*/*` and types we cannot produce).
pub fn negotiate(explicit: Option<TableFormat>, accept: Option<&HeaderValue>) -> TableFormat {
    if let Some(format) = explicit {
        return format;
    }
    let Some(accept) = accept.and_then(|v| v.to_str().ok()) else {
        return TableFormat::Json;
    };
    let json = preference(accept, "application", "json");
    let csv = preference(accept, "text", "csv");
    if csv > json {
        TableFormat::Csv
    } else {
        TableFormat::Json
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
    use crate::api::wire::params::Unit;

    fn accept(value: &'static str) -> TableFormat {
        negotiate(None, Some(&HeaderValue::from_static(value)))
    }

    /// CSV is chosen only when the client prefers it; an explicit format beats the header.
    #[test]
    fn negotiation() {
        assert_eq!(negotiate(None, None), TableFormat::Json);
        assert_eq!(accept("text/csv"), TableFormat::Csv);
        assert_eq!(accept("text/*"), TableFormat::Csv);
        assert_eq!(accept("text/csv, */*"), TableFormat::Csv);
        assert_eq!(accept("application/json"), TableFormat::Json);
        assert_eq!(accept("*/*"), TableFormat::Json);
        assert_eq!(
            accept("text/html,application/xhtml+xml,application/xml;q=0.9,*/*;q=0.8"),
            TableFormat::Json
        );
        assert_eq!(
            accept("text/csv;q=0.5, application/json;q=0.9"),
            TableFormat::Json
        );
        assert_eq!(
            accept("text/csv;q=0.9, application/json;q=0.5"),
            TableFormat::Csv
        );
        assert_eq!(accept("text/csv;q=0, */*"), TableFormat::Json);
        assert_eq!(accept("image/png"), TableFormat::Json);
        assert_eq!(
            negotiate(
                Some(TableFormat::Json),
                Some(&HeaderValue::from_static("text/csv"))
            ),
            TableFormat::Json
        );
    }

    /// The header names the JSON members, and each number is the JSON's number.
    #[test]
    fn csv_rows() {
        let row = TableRow {
            distance: 105.0,
            disparity_px: 50.0,
            normalized_x: -0.125,
            projection_factor: 0.23333333333333334,
            depth_error: 1.05,
        };
        let csv = table(&TableResponse {
            unit: Unit::Mm,
            focal_length_px: 35.0,
            baseline: 150.0,
            disparity_error_px: 0.5,
            x_left: 400.0,
            rows: vec![row],
        });
        assert_eq!(
            csv,
            "distance,disparity_px,normalized_x,projection_factor,depth_error\r\n\
             105.0,50.0,-0.125,0.23333333333333334,1.05\r\n"
        );
        let json = serde_json::to_value(row).unwrap();
        let keys: Vec<&str> = json
            .as_object()
            .unwrap()
            .keys()
            .map(String::as_str)
            .collect();
        assert_eq!(keys, COLUMNS);
    }
}
