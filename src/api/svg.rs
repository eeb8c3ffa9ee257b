//! `/chart.svg`'s renderer, below the routes as [`super::csv`] is: the chart data drawn as a self-contained SVG (no scripts, fonts, styles or
//! images from elsewhere), for people who would rather look than read and for reports.
//!
//! Layout: disparity on x; distance on the left y axis; depth error on its own right y axis,
//! because it spans a different range; the measured point marked on the distance curve. The
//! plot group carries its data ranges as `data-*` attributes so that a reader (or a test) can
//! map any vertex back to data.

use std::fmt::Write;

use crate::api::wire::chart::{AxisScale, ChartPoint, ChartResponse};
use stereo_core::numbers::short;

/// Canvas size; the `viewBox` lets it scale to any width.
const WIDTH: f64 = 800.0;
const HEIGHT: f64 = 480.0;
/// The plot area inside the canvas, leaving room for the title, legend and both axes.
const LEFT: f64 = 84.0;
const RIGHT: f64 = 716.0;
const TOP: f64 = 64.0;
const BOTTOM: f64 = 420.0;

const DISTANCE_COLOUR: &str = "#1565c0";
const ERROR_COLOUR: &str = "#c62828";
const MARKER_COLOUR: &str = "#2e7d32";

/// A map from a data interval onto a pixel interval, linear or logarithmic.
#[derive(Debug, Clone, Copy)]
struct Scale {
    min: f64,
    max: f64,
    from: f64,
    to: f64,
    log: bool,
}

impl Scale {
    fn new((min, max): (f64, f64), from: f64, to: f64) -> Self {
        Self {
            min,
            max,
            from,
            to,
            log: false,
        }
    }

    /// A logarithmic scale over `(min, max)`, both positive.
    fn log((min, max): (f64, f64), from: f64, to: f64) -> Self {
        Self {
            log: true,
            ..Self::new((min, max), from, to)
        }
    }

    fn f(&self, value: f64) -> f64 {
        if self.log { value.log10() } else { value }
    }

    fn at(&self, value: f64) -> f64 {
        let (lo, hi) = (self.f(self.min), self.f(self.max));
        let span = hi - lo;
        let t = if span > 0.0 {
            (self.f(value) - lo) / span
        } else {
            0.0
        };
        self.from + (self.to - self.from) * t
    }

    /// Whether `value` can be drawn: inside the interval (and positive on a log scale).
    fn contains(&self, value: f64) -> bool {
        (self.min..=self.max).contains(&value) && (!self.log || value > 0.0)
    }

    /// The tick values of this scale.
    fn ticks(&self) -> Vec<f64> {
        if self.log {
            decade_ticks((self.min, self.max))
        } else {
            ticks((self.min, self.max))
        }
    }
}

/// The y range of a log axis: whole decades around the positive values in `(min, max)`.
fn decade_range((min, max): (f64, f64)) -> (f64, f64) {
    if !(min.is_finite() && max.is_finite() && min > 0.0) {
        return (1.0, 10.0);
    }
    let low = 10f64.powf(min.log10().floor());
    let high = 10f64.powf(max.log10().ceil());
    (low, if high > low { high } else { low * 10.0 })
}

/// The powers of ten in `[min, max]`, thinned to at most eight.
fn decade_ticks((min, max): (f64, f64)) -> Vec<f64> {
    let first = (min.log10() - 1e-9).ceil() as i32;
    let last = (max.log10() + 1e-9).floor() as i32;
    let every = ((last - first + 1) as f64 / 8.0).ceil().max(1.0) as usize;
    (first..=last)
        .step_by(every)
        .map(|e| 10f64.powi(e))
        .collect()
}

/// A step of 1, 2 or 5 × 10ⁿ giving about `target` intervals across `span`.
fn nice_step(span: f64, target: f64) -> f64 {
    let raw = span / target;
    let magnitude = 10f64.powf(raw.log10().floor());
    let step = match raw / magnitude {
        n if n <= 1.0 => 1.0,
        n if n <= 2.0 => 2.0,
        n if n <= 5.0 => 5.0,
        _ => 10.0,
    } * magnitude;
    if step.is_finite() && step > 0.0 {
        step
    } else {
        1.0
    }
}

/// The y range for values up to `max`: from 0 to the next tick at or above it.
fn value_range(max: f64) -> (f64, f64) {
    if !(max.is_finite() && max > 0.0) {
        return (0.0, 1.0);
    }
    let step = nice_step(max, 5.0);
    (0.0, (max / step).ceil() * step)
}

/// Tick values inside `[min, max]`, at most a dozen.
fn ticks((min, max): (f64, f64)) -> Vec<f64> {
    let step = nice_step(max - min, 6.0);
    let first = (min / step).ceil();
    (0..12)
        .map(|i| (first + f64::from(i)) * step)
        .take_while(|v| *v <= max + step * 1e-9)
        .collect()
}

/// Text safe inside an XML element or a double-quoted attribute.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            c => out.push(c),
        }
    }
    out
}

fn extent(points: &[ChartPoint], of: fn(&ChartPoint) -> f64) -> (f64, f64) {
    points
        .iter()
        .map(of)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
}

fn polyline(out: &mut String, id: &str, colour: &str, points: &[ChartPoint], x: Scale, y: Scale) {
    let _ = write!(
        out,
        r#"<polyline id="{id}" fill="none" stroke="{colour}" stroke-width="2" stroke-linejoin="round" points=""#
    );
    for (i, p) in points.iter().filter(|p| !y.log || p.y > 0.0).enumerate() {
        let sep = if i == 0 { "" } else { " " };
        let _ = write!(out, "{sep}{:.2},{:.2}", x.at(p.x), y.at(p.y));
    }
    out.push_str("\"/>\n");
}

/// The chart as an SVG document.
pub fn chart(chart: &ChartResponse) -> String {
    let empty = Vec::new();
    let series = |name: &str| {
        chart
            .series
            .iter()
            .find(|s| s.name == name)
            .map_or(&empty, |s| &s.points)
    };
    let (distance, error) = (series("distance"), series("depth_error"));
    let label = |name: &str| {
        chart
            .series
            .iter()
            .find(|s| s.name == name)
            .map_or(String::new(), |s| s.label.clone())
    };
    let x_range = extent(distance, |p| p.x);
    let x_range = if x_range.0.is_finite() {
        x_range
    } else {
        (0.0, 1.0)
    };
    let log = chart.y_axis.scale == AxisScale::Log;
    let positive = |points: &[ChartPoint]| {
        points
            .iter()
            .map(|p| p.y)
            .filter(|y| *y > 0.0)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            })
    };
    let (y, e) = if log {
        (
            Scale::log(decade_range(positive(distance)), BOTTOM, TOP),
            Scale::log(decade_range(positive(error)), BOTTOM, TOP),
        )
    } else {
        (
            Scale::new(value_range(extent(distance, |p| p.y).1), BOTTOM, TOP),
            Scale::new(value_range(extent(error, |p| p.y).1), BOTTOM, TOP),
        )
    };
    let (y_range, e_range) = ((y.min, y.max), (e.min, e.max));
    let x = Scale::new(x_range, LEFT, RIGHT);
    let unit = escape(&chart.y_axis.unit);

    let mut out = String::with_capacity(4096 + 32 * (distance.len() + error.len()));
    let _ = writeln!(out, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" role="img" aria-labelledby="chart-title chart-desc" font-family="system-ui, -apple-system, 'Segoe UI', Roboto, sans-serif" font-size="12">"#
    );
    let _ = writeln!(
        out,
        r#"<title id="chart-title">Distance and depth error against disparity</title>"#
    );
    let marker_text = chart.marker.map(|m| {
        format!(
            "the measured point is at d = {} px, Z = {} {unit}",
            short(m.x),
            short(m.y)
        )
    });
    let _ = writeln!(
        out,
        r#"<desc id="chart-desc">Distance Z in {unit} (left axis) and depth error ΔZ in {unit} (right axis) for disparities from {} px to {} px{}.</desc>"#,
        short(x_range.0),
        short(x_range.1),
        marker_text
            .as_ref()
            .map_or(String::new(), |t| format!("; {t}"))
    );
    let _ = writeln!(
        out,
        r##"<rect width="{WIDTH}" height="{HEIGHT}" fill="#ffffff"/>"##
    );
    let _ = writeln!(
        out,
        r##"<text x="{LEFT}" y="24" font-size="16" font-weight="600" fill="#212121">Distance and depth error against disparity</text>"##
    );
    // Legend.
    for (i, (colour, text)) in [
        (DISTANCE_COLOUR, label("distance")),
        (ERROR_COLOUR, label("depth_error")),
    ]
    .into_iter()
    .enumerate()
    {
        let lx = LEFT + 300.0 * i as f64;
        let _ = writeln!(
            out,
            r##"<line x1="{lx}" y1="44" x2="{}" y2="44" stroke="{colour}" stroke-width="3"/><text x="{}" y="48" fill="#212121">{}</text>"##,
            lx + 24.0,
            lx + 30.0,
            escape(&text)
        );
    }
    let _ = writeln!(
        out,
        r#"<g id="plot" data-x-min="{}" data-x-max="{}" data-y-min="{}" data-y-max="{}" data-y2-min="{}" data-y2-max="{}" data-y-scale="{}">"#,
        x_range.0,
        x_range.1,
        y_range.0,
        y_range.1,
        e_range.0,
        e_range.1,
        if log { "log" } else { "linear" }
    );
    let _ = writeln!(
        out,
        r##"<rect id="plot-area" x="{LEFT}" y="{TOP}" width="{}" height="{}" fill="#fafafa" stroke="#9e9e9e"/>"##,
        RIGHT - LEFT,
        BOTTOM - TOP
    );
    // Grid and ticks: x below, distance on the left, error on the right.
    out.push_str(r##"<g id="x-axis" fill="#424242" text-anchor="middle">"##);
    for t in ticks(x_range) {
        let px = x.at(t);
        let _ = write!(
            out,
            r##"<line x1="{px:.2}" y1="{TOP}" x2="{px:.2}" y2="{BOTTOM}" stroke="#e0e0e0"/><text x="{px:.2}" y="{}">{}</text>"##,
            BOTTOM + 18.0,
            short(t)
        );
    }
    let _ = writeln!(
        out,
        r##"<text id="x-label" x="{}" y="{}" font-size="13" fill="#212121">{}</text></g>"##,
        (LEFT + RIGHT) / 2.0,
        BOTTOM + 44.0,
        escape(&chart.x_axis.label)
    );
    let _ = write!(
        out,
        r#"<g id="y-axis" fill="{DISTANCE_COLOUR}" text-anchor="end">"#
    );
    for t in y.ticks() {
        let py = y.at(t);
        let _ = write!(
            out,
            r##"<line x1="{LEFT}" y1="{py:.2}" x2="{RIGHT}" y2="{py:.2}" stroke="#e0e0e0"/><text x="{}" y="{:.2}">{}</text>"##,
            LEFT - 6.0,
            py + 4.0,
            short(t)
        );
    }
    let _ = writeln!(
        out,
        r#"<text id="y-label" transform="translate(18 {}) rotate(-90)" text-anchor="middle" font-size="13">{}</text></g>"#,
        (TOP + BOTTOM) / 2.0,
        escape(&chart.y_axis.label)
    );
    let _ = write!(
        out,
        r#"<g id="y2-axis" fill="{ERROR_COLOUR}" text-anchor="start">"#
    );
    for t in e.ticks() {
        let _ = write!(
            out,
            r#"<text x="{}" y="{:.2}">{}</text>"#,
            RIGHT + 6.0,
            e.at(t) + 4.0,
            short(t)
        );
    }
    let _ = writeln!(
        out,
        r#"<text id="y2-label" transform="translate({} {}) rotate(90)" text-anchor="middle" font-size="13">Depth error ΔZ ({unit})</text></g>"#,
        WIDTH - 14.0,
        (TOP + BOTTOM) / 2.0,
    );
    polyline(&mut out, "depth-error-curve", ERROR_COLOUR, error, x, e);
    polyline(&mut out, "distance-curve", DISTANCE_COLOUR, distance, x, y);
    if let (Some(m), Some(text)) = (chart.marker, marker_text) {
        if x.contains(m.x) && y.contains(m.y) {
            let (cx, cy) = (x.at(m.x), y.at(m.y));
            let anchor = if cx > (LEFT + RIGHT) / 2.0 {
                "end"
            } else {
                "start"
            };
            let tx = if anchor == "end" {
                cx - 10.0
            } else {
                cx + 10.0
            };
            let _ = writeln!(
                out,
                r##"<g id="marker"><circle id="measured-point" cx="{cx:.2}" cy="{cy:.2}" r="5" fill="{MARKER_COLOUR}" stroke="#ffffff" stroke-width="1.5"/><text x="{tx:.2}" y="{:.2}" text-anchor="{anchor}" fill="{MARKER_COLOUR}" font-weight="600">d = {} px, Z = {} {unit}</text></g>"##,
                (cy - 10.0).max(TOP + 14.0),
                short(m.x),
                short(m.y)
            );
        } else {
            let _ = writeln!(
                out,
                r#"<text id="marker-note" x="{RIGHT}" y="{}" text-anchor="end" fill="{MARKER_COLOUR}">{} (outside the plotted range)</text>"#,
                TOP - 4.0,
                escape(&text)
            );
        }
    }
    out.push_str("</g>\n</svg>\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Steps are 1, 2 or 5 times a power of ten; ranges end on a tick.
    #[test]
    fn nice_numbers() {
        assert_eq!(nice_step(100.0, 5.0), 20.0);
        assert_eq!(nice_step(7.0, 6.0), 2.0);
        assert_eq!(nice_step(0.3, 6.0), 0.05);
        assert_eq!(value_range(5250.0), (0.0, 6000.0));
        assert_eq!(value_range(0.0), (0.0, 1.0));
        assert_eq!(ticks((0.0, 6000.0)).len(), 7);
        assert_eq!(ticks((1.0, 200.0)), vec![50.0, 100.0, 150.0, 200.0]);
    }

    /// A log axis spans whole decades and ticks at the powers of ten; its positions are
    /// equal for equal ratios.
    #[test]
    fn log_axis() {
        assert_eq!(decade_range((4.2, 380.0)), (1.0, 1000.0));
        assert_eq!(decade_range((10.0, 10.0)), (10.0, 100.0));
        assert_eq!(decade_ticks((1.0, 1000.0)), vec![1.0, 10.0, 100.0, 1000.0]);
        assert_eq!(decade_ticks((1e-3, 1e13)).len(), 6);
        let s = Scale::log((1.0, 1000.0), 300.0, 0.0);
        assert_eq!(s.at(1.0), 300.0);
        assert!((s.at(10.0) - 200.0).abs() < 1e-9);
        assert!((s.at(100.0) - 100.0).abs() < 1e-9);
        assert!(!s.contains(0.0));
    }

    /// Text is escaped for XML.
    #[test]
    fn escaping() {
        assert_eq!(escape(r#"a<b & "c">"#), "a&lt;b &amp; &quot;c&quot;&gt;");
    }
}
