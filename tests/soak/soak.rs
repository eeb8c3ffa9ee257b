//! The soak's run. A bounded closed-loop load of mixed
//! requests (single and batch distances in JSON and in query strings, tables, charts, and
//! requests that must be refused) on a fixed number of keep-alive connections, against the
//! release binary. It records:
//! - the answers by status, and every one that is not the status its request must get;
//! - a random sample of answers checked against the physics: Z·|d| = f·B and
//!   ΔZ = Z²·Δd/(f·B) for distances, the same for every table row and chart point;
//! - the server's RSS each second: its growth from the end of the first 10 % of the run
//!   ("minute 0") to the end must stay under 10 %.
//!
//! It returns a Markdown report and whether every criterion held. Nothing here is timed.

use std::{
    collections::BTreeMap,
    fmt::Write as _,
    io,
    time::{Duration, Instant},
};

use serde_json::Value;

use super::{
    client::{Connection, Target},
    options::Options,
    process::{Placement, start_service, status_field},
};

/// How many answers in one are checked against the physics.
const SAMPLE_ONE_IN: u64 = 8;
/// Largest RSS growth allowed from minute 0 to the end.
const MAX_RSS_GROWTH: f64 = 0.10;

/// A small deterministic generator (SplitMix64), one per connection.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[lo, hi)`.
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// A random rig: focal length in px, baseline (mm), image width, Δd.
#[derive(Debug, Clone, Copy)]
struct Rig {
    f: f64,
    b: f64,
    w: f64,
    dd: f64,
}

impl Rig {
    fn random(rng: &mut Rng) -> Self {
        Self {
            f: rng.range(100.0, 2000.0).round(),
            b: rng.range(10.0, 500.0).round(),
            w: [640.0, 800.0, 1280.0, 1920.0][rng.below(4) as usize],
            dd: [0.1, 0.25, 0.5][rng.below(3) as usize],
        }
    }

    fn json(&self) -> String {
        format!(
            r#""focal_length_px":{},"baseline":{},"image_width":{},"image_height":600,"disparity_error_px":{}"#,
            self.f, self.b, self.w, self.dd
        )
    }

    fn query(&self) -> String {
        format!(
            "focal_length_px={}&baseline={}&image_width={}&image_height=600&disparity_error_px={}",
            self.f, self.b, self.w, self.dd
        )
    }

    /// Whether `z` at disparity `d` obeys Z·|d| = f·B, and `error` is Z²·Δd/(f·B).
    fn obeys(&self, d: f64, z: f64, error: f64) -> bool {
        let fb = self.f * self.b;
        close(z * d.abs(), fb) && close(error, z * z * self.dd / fb)
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs())
}

/// What a request is, what status it must get, and how to check its answer.
#[derive(Debug, Clone)]
enum Kind {
    /// One correspondence, `POST` (JSON) or `GET` (query): disparity `d`.
    Distance {
        rig: Rig,
        d: f64,
    },
    /// A batch: the disparity of each point, `None` for a point off the image.
    Batch {
        rig: Rig,
        points: Vec<Option<f64>>,
    },
    Table {
        rig: Rig,
    },
    Chart {
        rig: Rig,
    },
    /// Must be refused with 422 naming `field`.
    Invalid {
        field: &'static str,
    },
    /// Must be refused with 400.
    Malformed,
}

impl Kind {
    fn expected(&self) -> u16 {
        match self {
            Kind::Invalid { .. } => 422,
            Kind::Malformed => 400,
            _ => 200,
        }
    }

    fn name(&self) -> &'static str {
        match self {
            Kind::Distance { .. } => "distance",
            Kind::Batch { .. } => "batch",
            Kind::Table { .. } => "table",
            Kind::Chart { .. } => "chart",
            Kind::Invalid { .. } => "invalid",
            Kind::Malformed => "malformed",
        }
    }
}

/// The next request of the mix and its kind.
fn next_request(rng: &mut Rng) -> (Vec<u8>, Kind) {
    let rig = Rig::random(rng);
    let x_left = rng.range(rig.w / 2.0, rig.w).round();
    let d = rng.range(1.0, rig.w / 4.0).round().min(x_left);
    let post = |path: &str, body: String| {
        format!(
            "POST {path} HTTP/1.1\r\nhost: soak\r\ncontent-type: application/json\r\n\
             content-length: {}\r\n\r\n{body}",
            body.len()
        )
        .into_bytes()
    };
    match rng.below(20) {
        0..=7 => (
            post(
                "/distance",
                format!(
                    r#"{{{},"x_left":{x_left},"x_right":{}}}"#,
                    rig.json(),
                    x_left - d
                ),
            ),
            Kind::Distance { rig, d },
        ),
        8..=10 => (
            format!(
                "GET /distance?{}&x_left={x_left}&x_right={} HTTP/1.1\r\nhost: soak\r\n\r\n",
                rig.query(),
                x_left - d
            )
            .into_bytes(),
            Kind::Distance { rig, d },
        ),
        11..=12 => {
            let mut points = Vec::new();
            let mut json = Vec::new();
            for i in 0..20 {
                let d = 1.0 + f64::from(i) * 3.0;
                if i % 7 == 6 {
                    json.push(format!(r#"{{"x_left":{},"x_right":10}}"#, rig.w + 5.0));
                    points.push(None);
                } else {
                    json.push(format!(r#"{{"x_left":{x_left},"x_right":{}}}"#, x_left - d));
                    points.push(Some(d));
                }
            }
            let body = format!(
                r#"{{"rig":{{{}}},"points":[{}]}}"#,
                rig.json(),
                json.join(",")
            );
            (post("/distance", body), Kind::Batch { rig, points })
        }
        13..=14 => (
            post(
                "/table",
                format!(
                    r#"{{{},"disparity_min":1,"disparity_max":200,"steps":100}}"#,
                    rig.json()
                ),
            ),
            Kind::Table { rig },
        ),
        15..=16 => (
            post(
                "/chart-data",
                format!(
                    r#"{{{},"x_left":{x_left},"x_right":{},"points":100}}"#,
                    rig.json(),
                    x_left - d
                ),
            ),
            Kind::Chart { rig },
        ),
        17..=18 => (
            post(
                "/distance",
                format!(
                    r#"{{{},"x_left":{},"x_right":10}}"#,
                    rig.json(),
                    rig.w + 1.0
                ),
            ),
            Kind::Invalid { field: "x_left" },
        ),
        _ => (
            post("/distance", format!("{{{},\"x_left\":", rig.json())),
            Kind::Malformed,
        ),
    }
}

/// Whether the answer `body` to a request of `kind` is right; `Err` says what is wrong.
fn check(kind: &Kind, body: &[u8]) -> Result<(), String> {
    let value: Value = serde_json::from_slice(body).map_err(|e| format!("not JSON: {e}"))?;
    let number = |v: &Value, key: &str| {
        v[key]
            .as_f64()
            .ok_or_else(|| format!("no number {key} in {v}"))
    };
    match kind {
        Kind::Distance { rig, d } => {
            let (z, e) = (number(&value, "distance")?, number(&value, "depth_error")?);
            rig.obeys(*d, z, e)
                .then_some(())
                .ok_or_else(|| format!("d = {d}: Z = {z}, ΔZ = {e} for {rig:?}"))
        }
        Kind::Batch { rig, points } => {
            let results = value["results"].as_array().ok_or("no results")?;
            if results.len() != points.len() {
                return Err(format!(
                    "{} results for {} points",
                    results.len(),
                    points.len()
                ));
            }
            for (i, (result, d)) in results.iter().zip(points).enumerate() {
                match d {
                    Some(d) => {
                        let (z, e) = (number(result, "distance")?, number(result, "depth_error")?);
                        if !rig.obeys(*d, z, e) {
                            return Err(format!("point {i}: Z = {z} for d = {d}"));
                        }
                    }
                    None if result["errors"][0]["field"] == format!("points[{i}].x_left") => {}
                    None => return Err(format!("point {i} off the image: {result}")),
                }
            }
            Ok(())
        }
        Kind::Table { rig } => {
            let rows = value["rows"].as_array().ok_or("no rows")?;
            if rows.len() != 100 {
                return Err(format!("{} rows", rows.len()));
            }
            for row in rows {
                let d = number(row, "disparity_px")?;
                let (z, e) = (number(row, "distance")?, number(row, "depth_error")?);
                if !rig.obeys(d, z, e) {
                    return Err(format!("row {row}"));
                }
            }
            Ok(())
        }
        Kind::Chart { rig } => {
            let series = value["series"].as_array().ok_or("no series")?;
            let points = |name: &str| {
                series
                    .iter()
                    .find(|s| s["name"] == name)
                    .and_then(|s| s["points"].as_array())
                    .ok_or_else(|| format!("no {name} series"))
            };
            let (distance, error) = (points("distance")?, points("depth_error")?);
            if distance.len() != 100 || error.len() != 100 {
                return Err(format!("{} and {} points", distance.len(), error.len()));
            }
            for (p, q) in distance.iter().zip(error) {
                let (d, z, e) = (number(p, "x")?, number(p, "y")?, number(q, "y")?);
                if !rig.obeys(d, z, e) {
                    return Err(format!("point {p}, error {q}"));
                }
            }
            Ok(())
        }
        Kind::Invalid { field } => {
            let named = value["errors"]
                .as_array()
                .is_some_and(|errors| errors.iter().any(|e| e["field"] == *field));
            named
                .then_some(())
                .ok_or_else(|| format!("the problem does not name {field}: {value}"))
        }
        Kind::Malformed => (value["status"] == 400)
            .then_some(())
            .ok_or_else(|| format!("not a 400 problem: {value}")),
    }
}

/// What the connections saw.
#[derive(Debug, Default)]
struct Tally {
    statuses: BTreeMap<u16, u64>,
    /// Answers with another status than their request must get, by kind.
    unexpected: BTreeMap<(&'static str, u16), u64>,
    checked: u64,
    wrong: Vec<String>,
    errors: u64,
}

impl Tally {
    fn merge(&mut self, other: Tally) {
        for (k, n) in other.statuses {
            *self.statuses.entry(k).or_default() += n;
        }
        for (k, n) in other.unexpected {
            *self.unexpected.entry(k).or_default() += n;
        }
        self.checked += other.checked;
        self.wrong.extend(other.wrong);
        self.errors += other.errors;
    }
}

/// One connection's loop until `to`.
async fn connection(server: std::net::SocketAddr, seed: u64, to: Instant) -> io::Result<Tally> {
    let mut rng = Rng(seed);
    let mut tally = Tally::default();
    let mut connection = Connection::open(server).await?;
    while Instant::now() < to {
        let (request, kind) = next_request(&mut rng);
        let (status, body) = match connection.exchange_body(&request).await {
            Ok(answer) => answer,
            Err(_) => {
                tally.errors += 1;
                connection = Connection::open(server).await?;
                continue;
            }
        };
        *tally.statuses.entry(status).or_default() += 1;
        if status != kind.expected() {
            *tally.unexpected.entry((kind.name(), status)).or_default() += 1;
        } else if rng.below(SAMPLE_ONE_IN) == 0 {
            tally.checked += 1;
            if let Err(why) = check(&kind, body) {
                tally.wrong.push(format!("{}: {why}", kind.name()));
            }
        }
    }
    Ok(tally)
}

/// Runs the soak for `duration` on `connections` connections; returns the report and whether
/// every criterion held.
pub fn run(
    options: &Options,
    duration: Duration,
    connections: usize,
) -> Result<(String, bool), String> {
    let placement = Placement::detect();
    placement.pin_self()?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| e.to_string())?;
    let healthz = Target::new("healthz", "GET", "/healthz", None);
    let (service, _) = start_service(placement, &options.service_bin, &healthz.bytes)?;
    let idle_rss = service.rss_kib().unwrap_or(0);

    let started = Instant::now();
    let to = started + duration;
    let (tally, rss) = runtime.block_on(async {
        let tasks: Vec<_> = (0..connections)
            .map(|i| tokio::spawn(connection(service.addr, 0x5EED + i as u64, to)))
            .collect();
        let rss = tokio::spawn(rss_each_second(service.pid(), to));
        let mut tally = Tally::default();
        for task in tasks {
            let seen = task.await.map_err(|e| e.to_string())?;
            tally.merge(seen.map_err(|e| format!("a connection failed: {e}"))?);
        }
        let rss = rss.await.map_err(|e| e.to_string())?;
        Ok::<_, String>((tally, rss))
    })?;
    let elapsed = started.elapsed();
    let alive = service.rss_kib().is_some();
    Ok(report(
        &tally,
        &rss,
        idle_rss,
        duration,
        elapsed,
        connections,
        placement,
        alive,
    ))
}

/// The server's RSS (KiB) sampled each second until `to`, with the second it was taken at.
async fn rss_each_second(pid: u32, to: Instant) -> Vec<(u64, u64)> {
    let start = Instant::now();
    let mut samples = Vec::new();
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    while Instant::now() < to {
        tick.tick().await;
        if let Some(kib) = status_field(pid, "VmRSS:") {
            samples.push((start.elapsed().as_secs(), kib));
        }
    }
    samples
}

#[allow(clippy::too_many_arguments)]
fn report(
    tally: &Tally,
    rss: &[(u64, u64)],
    idle_rss: u64,
    duration: Duration,
    elapsed: Duration,
    connections: usize,
    placement: Placement,
    alive: bool,
) -> (String, bool) {
    let total: u64 = tally.statuses.values().sum();
    let unexpected: u64 = tally.unexpected.values().sum();
    let server_errors: u64 = tally
        .statuses
        .iter()
        .filter(|(s, _)| **s >= 500)
        .map(|(_, n)| n)
        .sum();
    // Minute 0: the first sample after a tenth of the run (at least 1 s), once the allocator
    // and the connections have settled.
    let settle = (duration.as_secs() / 10).max(1);
    let start_rss = rss
        .iter()
        .find(|(t, _)| *t >= settle)
        .map_or(0, |(_, kib)| *kib);
    let end_rss = rss.last().map_or(0, |(_, kib)| *kib);
    let peak_rss = rss.iter().map(|(_, kib)| *kib).max().unwrap_or(0);
    let growth = if start_rss > 0 {
        end_rss as f64 / start_rss as f64 - 1.0
    } else {
        f64::NAN
    };

    let verdicts = [
        ("0 answers with an unexpected status", unexpected == 0),
        ("0 server errors (5xx)", server_errors == 0),
        ("0 connection errors", tally.errors == 0),
        (
            "every sampled answer agrees with the physics",
            tally.wrong.is_empty() && tally.checked > 0,
        ),
        ("RSS growth under 10 %", growth < MAX_RSS_GROWTH),
        ("the server is still running", alive),
    ];
    let passed = verdicts.iter().all(|(_, ok)| *ok);

    let mut out = String::new();
    let _ = writeln!(
        out,
        "## Soak: {} s on {connections} connections\n",
        duration.as_secs()
    );
    let _ = writeln!(
        out,
        "Placement: {}. Mix: 40 % POST /distance, 15 % GET /distance, 10 % batches of 20 \
         points (3 off the image), 10 % tables of 100 rows, 10 % charts of 100 points, 10 % \
         422s, 5 % 400s; every rig random.\n",
        placement.describe()
    );
    let _ = writeln!(
        out,
        "| requests | req/s | checked against the physics | wrong | connection errors |\n\
         |---:|---:|---:|---:|---:|\n\
         | {total} | {:.0} | {} (1 in {SAMPLE_ONE_IN}) | {} | {} |\n",
        total as f64 / elapsed.as_secs_f64(),
        tally.checked,
        tally.wrong.len(),
        tally.errors
    );
    let _ = writeln!(out, "| status | answers |\n|---:|---:|");
    for (status, n) in &tally.statuses {
        let _ = writeln!(out, "| {status} | {n} |");
    }
    let _ = writeln!(
        out,
        "\n| RSS idle | at {settle} s (minute 0) | end | peak | growth |\n\
         |---:|---:|---:|---:|---:|\n\
         | {:.1} MiB | {:.1} MiB | {:.1} MiB | {:.1} MiB | {:+.1} % |\n",
        idle_rss as f64 / 1024.0,
        start_rss as f64 / 1024.0,
        end_rss as f64 / 1024.0,
        peak_rss as f64 / 1024.0,
        growth * 100.0
    );
    for ((kind, status), n) in &tally.unexpected {
        let _ = writeln!(out, "- unexpected: {n} × {status} for {kind}");
    }
    for wrong in tally.wrong.iter().take(10) {
        let _ = writeln!(out, "- wrong: {wrong}");
    }
    for (what, ok) in verdicts {
        let _ = writeln!(out, "- {} {what}", if ok { "PASS" } else { "FAIL" });
    }
    (out, passed)
}
