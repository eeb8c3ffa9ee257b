//! The load benchmark's Markdown report.

use std::{collections::BTreeMap, fmt::Write as _, fs, time::Duration};

use super::{client::Row, options::Options, process::Placement};

pub struct Report<'a> {
    pub options: &'a Options,
    pub machine: String,
    pub placement: Placement,
    pub rows: &'a [Row],
    pub table: Option<&'a Row>,
    pub paced: &'a [Row],
    pub saturation: f64,
    pub starts: &'a [Duration],
    pub idle_rss: [u64; 3],
    pub peak_rss: u64,
    pub baseline_idle_rss: u64,
    pub sizes: &'a BTreeMap<String, usize>,
}

pub fn ms(d: Duration) -> String {
    format!("{:.3}", d.as_secs_f64() * 1e3)
}

pub fn mib(kib: u64) -> String {
    format!("{:.1}", kib as f64 / 1024.0)
}

pub fn machine() -> String {
    let cpu = fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines().find_map(|l| {
                l.strip_prefix("model name")
                    .map(|v| v.trim_start_matches([' ', '\t', ':']).to_owned())
            })
        })
        .unwrap_or_else(|| "unknown CPU".to_owned());
    let cpus = std::thread::available_parallelism().map_or(0, |n| n.get());
    let kernel = fs::read_to_string("/proc/sys/kernel/osrelease").unwrap_or_default();
    format!("{cpu}, {cpus} CPUs, Linux {}", kernel.trim())
}

pub fn report(r: &Report<'_>) -> String {
    let mut out = String::new();
    let o = r.options;
    let _ = writeln!(out, "## Load benchmark\n");
    let _ = writeln!(out, "- Machine: {}", r.machine);
    let _ = writeln!(out, "- Placement: {}", r.placement.describe());
    let _ = writeln!(
        out,
        "- Each row: fresh keep-alive connections, {} warm-up then {} measured; latency from \
         send to last byte of the answer.",
        humantime::format_duration(o.warmup),
        humantime::format_duration(o.duration)
    );
    let sizes: Vec<String> = r.sizes.iter().map(|(k, v)| format!("{k} {v} B")).collect();
    let _ = writeln!(out, "- Answer sizes: {}\n", sizes.join(", "));

    let _ = writeln!(out, "### Throughput and latency (closed loop)\n");
    let _ = writeln!(
        out,
        "| connections | endpoint | req/s | vs baseline | p50 ms | p99 ms | p99.9 ms | server CPU | client CPU | server peak RSS MiB | non-200 |"
    );
    let _ = writeln!(
        out,
        "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    let mut baseline = 0.0;
    for row in r.rows {
        if row.target.starts_with("baseline") {
            baseline = row.requests_per_sec;
        }
        let ratio = if baseline > 0.0 {
            format!("{:.0} %", 100.0 * row.requests_per_sec / baseline)
        } else {
            "-".to_owned()
        };
        let _ = writeln!(
            out,
            "| {} | {} | {:.0} | {} | {} | {} | {} | {:.0} % | {:.0} % | {} | {} |",
            row.connections,
            row.target,
            row.requests_per_sec,
            ratio,
            ms(row.p50),
            ms(row.p99),
            ms(row.p999),
            100.0 * row.readings.server_cpu,
            100.0 * row.readings.client_cpu,
            mib(row.readings.peak_rss_kib),
            row.non_200 + row.errors,
        );
    }

    if let Some(t) = r.table {
        let _ = writeln!(out, "\n### The 10 000-row table, one connection\n");
        let _ = writeln!(
            out,
            "| req/s | p50 ms | p99 ms | p99.9 ms | max ms | non-200 |"
        );
        let _ = writeln!(out, "|---:|---:|---:|---:|---:|---:|");
        let _ = writeln!(
            out,
            "| {:.0} | {} | {} | {} | {} | {} |",
            t.requests_per_sec,
            ms(t.p50),
            ms(t.p99),
            ms(t.p999),
            ms(t.max),
            t.non_200 + t.errors
        );
    }

    let _ = writeln!(
        out,
        "\n### At half of saturation ({:.0} req/s, half of POST /distance's best {:.0}), open loop, {} connections\n",
        r.saturation / 2.0,
        r.saturation,
        o.paced_connections
    );
    let _ = writeln!(out, "Latency runs from each request's scheduled time.\n");
    let _ = writeln!(
        out,
        "| endpoint | achieved req/s | p50 ms | p99 ms | p99.9 ms | max ms | server CPU | non-200 |"
    );
    let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|---:|---:|");
    for row in r.paced {
        let _ = writeln!(
            out,
            "| {} | {:.0} | {} | {} | {} | {} | {:.0} % | {} |",
            row.target,
            row.requests_per_sec,
            ms(row.p50),
            ms(row.p99),
            ms(row.p999),
            ms(row.max),
            100.0 * row.readings.server_cpu,
            row.non_200 + row.errors
        );
    }

    let pick = |q: f64| {
        r.starts
            .get(((q * r.starts.len() as f64) as usize).min(r.starts.len().saturating_sub(1)))
            .copied()
            .unwrap_or_default()
    };
    let _ = writeln!(out, "\n### Start-up and memory\n");
    let _ = writeln!(
        out,
        "- Process start to first answered request (`GET /healthz`), {} starts: min {} ms, median {} ms, max {} ms.",
        r.starts.len(),
        ms(r.starts.first().copied().unwrap_or_default()),
        ms(pick(0.5)),
        ms(r.starts.last().copied().unwrap_or_default())
    );
    let [start, warm, after] = r.idle_rss;
    let _ = writeln!(
        out,
        "- Service RSS: {} MiB idle after start, {} MiB after one request per endpoint, peak {} MiB under load (VmHWM), {} MiB idle after the run.",
        mib(start),
        mib(warm),
        mib(r.peak_rss),
        mib(after)
    );
    let _ = writeln!(
        out,
        "- Baseline RSS idle: {} MiB.",
        mib(r.baseline_idle_rss)
    );
    out
}
