//! HTTP load benchmark: the release binary of the service, over loopback, against a bench-only
//! baseline server (a bare axum handler answering a fixed body of the same size as a
//! `/distance` answer), measured in one run with the same connections, warm-up and duration.
//!
//! Run: `cargo bench --bench load` (options after `--`, see [`USAGE`]). It prints a Markdown
//! report: req/s and the ratio to the baseline, p50/p99/p99.9 latency, CPU use of server and
//! load generator, peak RSS; the 10 000-row table; p99 at half of the saturation load; the time
//! from process start to the first answer; idle RSS. Nothing here asserts a time: this is a
//! measurement, not a test.
//!
//! `--compare NAME=PATH` measures other builds of the service on `/distance` in the same run
//! (another commit), each row against the same baseline.
//!
//! The soak, a pass/fail check under load, is an ignored test: `tests/soak/`.
//!
//! Placement on a 2-core machine: every server process is pinned to CPU 0 and the load
//! generator (one thread, a current-thread tokio runtime, a minimal HTTP/1.1 client) to CPU 1,
//! with `taskset`. Each server therefore runs one tokio worker, and the report shows both
//! sides' CPU use so that a load generator at 100 % (the client, not the server, is the limit)
//! is visible.

use std::{collections::BTreeMap, fs, process::ExitCode, time::Duration};

#[path = "load/client.rs"]
mod client;
#[path = "load/options.rs"]
mod options;
#[path = "load/process.rs"]
mod process;
#[path = "load/report.rs"]
mod report;

use self::{
    client::{Target, closed_loop, fetch, open_loop},
    options::Options,
    process::{Placement, serve_baseline, start_baseline, start_service, status_field},
    report::{Report, machine, report},
};

const DISTANCE_BODY: &str = r#"{"focal_length_px": 35, "baseline": 150, "unit": "mm", "x_left": 400, "x_right": 350, "image_width": 800, "image_height": 600}"#;
const DISTANCE_QUERY: &str = "/distance?focal_length_px=35&baseline=150&unit=mm&x_left=400\
                              &x_right=350&image_width=800&image_height=600";

fn table_body(steps: u32) -> String {
    format!(
        r#"{{"focal_length_px": 35, "baseline": 150, "unit": "mm", "image_width": 800, "image_height": 600, "disparity_min": 1, "disparity_max": 200, "steps": {steps}}}"#
    )
}

const CHART_BODY: &str = r#"{"focal_length_px": 35, "baseline": 150, "unit": "mm", "image_width": 800, "image_height": 600, "x_left": 400, "x_right": 350, "points": 500}"#;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("serve-baseline") {
        return match serve_baseline(&args[1..]) {
            Ok(()) => ExitCode::SUCCESS,
            Err(error) => {
                eprintln!("baseline: {error}");
                ExitCode::FAILURE
            }
        };
    }
    let options = match Options::parse(&args) {
        Ok(options) => options,
        Err(message) => {
            eprintln!("{message}");
            return ExitCode::FAILURE;
        }
    };
    match run(&options) {
        Ok(report) => {
            println!("{report}");
            if let Some(path) = &options.out
                && let Err(error) = fs::write(path, &report)
            {
                eprintln!("cannot write {}: {error}", path.display());
                return ExitCode::FAILURE;
            }
            ExitCode::SUCCESS
        }
        Err(error) => {
            eprintln!("load benchmark failed: {error}");
            ExitCode::FAILURE
        }
    }
}

// The run

fn run(options: &Options) -> Result<String, String> {
    let placement = Placement::detect();
    let machine = machine();
    placement.pin_self()?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| e.to_string())?;

    let healthz = Target::new("healthz", "GET", "/healthz", None);
    let post_distance = Target::new("POST /distance", "POST", "/distance", Some(DISTANCE_BODY));
    let get_distance = Target::new("GET /distance", "GET", DISTANCE_QUERY, None);
    let table_1k = Target::new(
        "POST /table (1 000 rows)",
        "POST",
        "/table",
        Some(&table_body(1000)),
    );
    let table_10k = Target::new(
        "POST /table (10 000 rows)",
        "POST",
        "/table",
        Some(&table_body(10_000)),
    );
    let chart_500 = Target::new(
        "POST /chart-data (500 points)",
        "POST",
        "/chart-data",
        Some(CHART_BODY),
    );

    // Start-up: process spawn to first answered request, over fresh processes.
    let mut starts = Vec::with_capacity(options.starts);
    for _ in 0..options.starts {
        let (server, took) = start_service(placement, &options.service_bin, &healthz.bytes)?;
        starts.push(took);
        drop(server);
    }
    starts.sort_unstable();

    let (service, _) = start_service(placement, &options.service_bin, &healthz.bytes)?;
    let idle_rss_start = service.rss_kib().unwrap_or(0);
    // Every target must answer 200 with JSON before it is measured.
    let mut sizes = BTreeMap::new();
    for target in [
        &post_distance,
        &get_distance,
        &table_1k,
        &table_10k,
        &chart_500,
    ] {
        let (status, body) = fetch(service.addr, &target.bytes).map_err(|e| e.to_string())?;
        if status != 200 || serde_json::from_slice::<serde_json::Value>(&body).is_err() {
            return Err(format!(
                "{} answered {status}: {}",
                target.name,
                String::from_utf8_lossy(&body)
            ));
        }
        sizes.insert(target.name.clone(), body.len());
    }
    let (_, distance_answer) =
        fetch(service.addr, &post_distance.bytes).map_err(|e| e.to_string())?;
    let idle_rss_warm = service.rss_kib().unwrap_or(0);

    let body_file = std::env::temp_dir().join(format!("load-baseline-{}.json", std::process::id()));
    fs::write(&body_file, &distance_answer).map_err(|e| e.to_string())?;
    let baseline_target = Target::new(
        "baseline (fixed body)",
        "POST",
        "/distance",
        Some(DISTANCE_BODY),
    );
    let baseline = start_baseline(placement, &body_file, &baseline_target.bytes)?;
    let _ = fs::remove_file(&body_file);
    let (_, baseline_answer) =
        fetch(baseline.addr, &baseline_target.bytes).map_err(|e| e.to_string())?;
    if baseline_answer != distance_answer {
        return Err("the baseline does not answer the /distance body".to_owned());
    }
    let baseline_idle_rss = baseline.rss_kib().unwrap_or(0);

    let compared = options
        .compare
        .iter()
        .map(|(name, bin)| {
            start_service(placement, bin, &healthz.bytes).map(|(server, _)| (name, server))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let wanted = |target: &Target| {
        options
            .only
            .as_ref()
            .is_none_or(|only| target.name.contains(only.as_str()))
    };
    // Closed loop at every concurrency level; the baseline first at each level.
    let mut rows = Vec::new();
    for &connections in &options.levels {
        eprintln!("measuring {connections} connection(s)...");
        rows.push(closed_loop(
            &runtime,
            &baseline,
            &baseline_target,
            connections,
            options,
        )?);
        for target in [&post_distance, &get_distance, &table_1k, &chart_500] {
            if wanted(target) {
                rows.push(closed_loop(
                    &runtime,
                    &service,
                    target,
                    connections,
                    options,
                )?);
            }
        }
        for (name, server) in &compared {
            for target in [&post_distance, &get_distance] {
                if wanted(target) {
                    let mut row = closed_loop(&runtime, server, target, connections, options)?;
                    row.target = format!("{name}: {}", row.target);
                    rows.push(row);
                }
            }
        }
    }
    let table_row = if wanted(&table_10k) {
        eprintln!("measuring the 10 000-row table...");
        Some(closed_loop(&runtime, &service, &table_10k, 1, options)?)
    } else {
        None
    };

    // Half of the saturation load of POST /distance (its best closed-loop rate in this run).
    let saturation = rows
        .iter()
        .filter(|row| row.target == post_distance.name)
        .map(|row| row.requests_per_sec)
        .fold(0.0, f64::max);
    let half = saturation / 2.0;
    let mut paced = Vec::new();
    if half > 0.0 {
        eprintln!("measuring at half saturation ({half:.0} req/s)...");
        let connections = options.paced_connections;
        paced.push(open_loop(
            &runtime,
            &baseline,
            &baseline_target,
            connections,
            half,
            options,
        )?);
        for target in [&post_distance, &get_distance] {
            if wanted(target) {
                paced.push(open_loop(
                    &runtime,
                    &service,
                    target,
                    connections,
                    half,
                    options,
                )?);
            }
        }
    }
    std::thread::sleep(Duration::from_secs(1));
    let idle_rss_after = service.rss_kib().unwrap_or(0);
    let peak_rss = status_field(service.pid(), "VmHWM:").unwrap_or(0);

    Ok(report(&Report {
        options,
        machine,
        placement,
        rows: &rows,
        table: table_row.as_ref(),
        paced: &paced,
        saturation,
        starts: &starts,
        idle_rss: [idle_rss_start, idle_rss_warm, idle_rss_after],
        peak_rss,
        baseline_idle_rss,
        sizes: &sizes,
    }))
}
