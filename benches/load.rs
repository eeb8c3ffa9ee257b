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
//! `--soak DUR` runs the soak instead (see [`soak`]): mixed requests, a fixed number of
//! connections, statuses counted, a sample of answers checked against the physics, RSS growth.
//!
//! Placement on a 2-core machine: every server process is pinned to CPU 0 and the load
//! generator (one thread, a current-thread tokio runtime, a minimal HTTP/1.1 client) to CPU 1,
//! with `taskset`. Each server therefore runs one tokio worker, and the report shows both
//! sides' CPU use so that a load generator at 100 % (the client, not the server, is the limit)
//! is visible.

use std::{
    collections::BTreeMap,
    fmt::Write as _,
    fs,
    io::{self, Read, Write},
    net::{SocketAddr, TcpListener as StdListener, TcpStream as StdStream},
    path::{Path, PathBuf},
    process::{Child, Command, ExitCode, Stdio},
    sync::Arc,
    time::{Duration, Instant},
};

use axum::{
    Router,
    body::Bytes,
    extract::State,
    http::{HeaderValue, header},
    response::IntoResponse,
    routing::get,
    serve::ListenerExt,
};
use tokio::{
    io::{AsyncReadExt, AsyncWriteExt},
    net::TcpStream,
    runtime::Runtime,
    sync::{Mutex, mpsc},
};

#[path = "load/soak.rs"]
mod soak;

/// The service binary, built by cargo with the bench profile (the release settings).
const SERVICE_BIN: &str = env!("CARGO_BIN_EXE_stereo-distance");

const USAGE: &str = "\
usage: cargo bench --bench load -- [options]
  --warmup DUR         warm-up before each measurement, not recorded (default 1s)
  --duration DUR       measured time per endpoint and concurrency (default 5s)
  --concurrency LIST   connections, comma-separated (default 1,16,64,256)
  --paced-connections N  connections for the half-saturation run (default 64)
  --starts N           process starts timed for start-up latency (default 20)
  --out FILE           also write the report to FILE
  --service-bin PATH   the service binary to measure (default: the one cargo built for the
                       bench, with the release profile); for profiling a build with symbols
  --only TEXT          measure only the endpoints whose name contains TEXT (and the baseline)
  --soak DUR           run the soak for DUR instead (mixed load, answers checked, RSS growth)
  --soak-connections N connections of the soak (default 32)";

/// The seed's example 1: f = 35 px, B = 150 mm, 800×600, x 400 / 350 → 105 mm.
const DISTANCE_BODY: &str = r#"{"focal_length_px": 35, "baseline": 150, "unit": "mm", "x_left": 400, "x_right": 350, "image_width": 800, "image_height": 600}"#;
const DISTANCE_QUERY: &str = "/distance?focal_length_px=35&baseline=150&unit=mm&x_left=400\
                              &x_right=350&image_width=800&image_height=600";

fn table_body(steps: u32) -> String {
    format!(
        r#"{{"focal_length_px": 35, "baseline": 150, "unit": "mm", "image_width": 800, "image_height": 600, "disparity_min": 1, "disparity_max": 200, "steps": {steps}}}"#
    )
}

const CHART_BODY: &str = r#"{"focal_length_px": 35, "baseline": 150, "unit": "mm", "image_width": 800, "image_height": 600, "x_left": 400, "x_right": 350, "points": 500}"#;

// ---------------------------------------------------------------------------------------------
// Options

#[derive(Debug, Clone)]
struct Options {
    warmup: Duration,
    duration: Duration,
    levels: Vec<usize>,
    paced_connections: usize,
    starts: usize,
    out: Option<PathBuf>,
    service_bin: PathBuf,
    only: Option<String>,
    soak: Option<Duration>,
    soak_connections: usize,
}

impl Options {
    fn parse(args: &[String]) -> Result<Self, String> {
        let mut options = Options {
            warmup: Duration::from_secs(1),
            duration: Duration::from_secs(5),
            levels: vec![1, 16, 64, 256],
            paced_connections: 64,
            starts: 20,
            out: None,
            service_bin: PathBuf::from(SERVICE_BIN),
            only: None,
            soak: None,
            soak_connections: 32,
        };
        let mut args = args.iter();
        while let Some(flag) = args.next() {
            // cargo passes `--bench` to every bench binary.
            if flag == "--bench" {
                continue;
            }
            let mut value = || {
                args.next()
                    .ok_or_else(|| format!("{flag} needs a value\n{USAGE}"))
            };
            match flag.as_str() {
                "--warmup" => options.warmup = duration(value()?)?,
                "--duration" => options.duration = duration(value()?)?,
                "--concurrency" => {
                    options.levels = value()?
                        .split(',')
                        .map(|n| count(n.trim()))
                        .collect::<Result<_, _>>()?
                }
                "--paced-connections" => options.paced_connections = count(value()?)?,
                "--starts" => options.starts = count(value()?)?,
                "--out" => options.out = Some(PathBuf::from(value()?)),
                "--service-bin" => options.service_bin = PathBuf::from(value()?),
                "--only" => options.only = Some(value()?.clone()),
                "--soak" => options.soak = Some(duration(value()?)?),
                "--soak-connections" => options.soak_connections = count(value()?)?,
                "-h" | "--help" => return Err(USAGE.to_owned()),
                other => return Err(format!("unknown option {other}\n{USAGE}")),
            }
        }
        if options.duration.is_zero() {
            return Err("--duration must be more than 0".to_owned());
        }
        Ok(options)
    }
}

fn duration(text: &str) -> Result<Duration, String> {
    humantime::parse_duration(text).map_err(|error| format!("{text:?}: {error}"))
}

fn count(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if n > 0 => Ok(n),
        _ => Err(format!("{text:?} is not a positive whole number")),
    }
}

// ---------------------------------------------------------------------------------------------
// Entry point

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
    // The soak passes only when every criterion held; the benchmark measures and passes.
    let outcome = match options.soak {
        Some(duration) => soak::run(&options, duration, options.soak_connections),
        None => run(&options).map(|report| (report, true)),
    };
    match outcome {
        Ok((report, passed)) => {
            println!("{report}");
            if let Some(path) = &options.out
                && let Err(error) = fs::write(path, &report)
            {
                eprintln!("cannot write {}: {error}", path.display());
                return ExitCode::FAILURE;
            }
            if passed {
                ExitCode::SUCCESS
            } else {
                ExitCode::FAILURE
            }
        }
        Err(error) => {
            eprintln!("load benchmark failed: {error}");
            ExitCode::FAILURE
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The baseline server (bench only; never part of the shipped binary)

/// `serve-baseline PORT BODY_FILE`: answers every `/distance` request, GET or POST, with the
/// bytes of BODY_FILE as `application/json`, after reading the request body, on the same tokio
/// runtime and TCP_NODELAY setting as the service.
fn serve_baseline(args: &[String]) -> Result<(), String> {
    let [port, body_file] = args else {
        return Err("usage: serve-baseline PORT BODY_FILE".to_owned());
    };
    let port: u16 = port.parse().map_err(|_| format!("bad port {port:?}"))?;
    let body = Bytes::from(fs::read(body_file).map_err(|e| format!("{body_file}: {e}"))?);
    let runtime = Runtime::new().map_err(|e| e.to_string())?;
    runtime.block_on(async move {
        let listener = tokio::net::TcpListener::bind(("127.0.0.1", port))
            .await
            .map_err(|e| e.to_string())?;
        let listener = listener.tap_io(|stream| {
            let _ = stream.set_nodelay(true);
        });
        let app = Router::new()
            .route("/distance", get(fixed).post(fixed))
            .with_state(body);
        axum::serve(listener, app).await.map_err(|e| e.to_string())
    })
}

async fn fixed(State(body): State<Bytes>, _request: Bytes) -> impl IntoResponse {
    (
        [(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/json"),
        )],
        body,
    )
}

// ---------------------------------------------------------------------------------------------
// Processes: pinning, start-up, RSS and CPU time

/// How processes are placed on CPUs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Placement {
    /// Servers on CPU 0, load generator on CPU 1.
    Pinned,
    /// No `taskset` or fewer than 2 CPUs: left to the scheduler.
    Shared,
}

impl Placement {
    fn detect() -> Self {
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let taskset = Command::new("taskset")
            .arg("-V")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if cpus >= 2 && taskset {
            Placement::Pinned
        } else {
            Placement::Shared
        }
    }

    /// Pins this process (the load generator) to CPU 1. Call before starting any thread.
    fn pin_self(self) -> Result<(), String> {
        if self == Placement::Shared {
            return Ok(());
        }
        let pid = std::process::id().to_string();
        let status = Command::new("taskset")
            .args(["-a", "-p", "-c", "1", &pid])
            .stdout(Stdio::null())
            .status()
            .map_err(|e| format!("taskset: {e}"))?;
        status
            .success()
            .then_some(())
            .ok_or_else(|| "taskset could not pin the load generator".to_owned())
    }

    /// A command for a server process, on CPU 0 when pinned.
    fn server(self, program: &str) -> Command {
        match self {
            Placement::Pinned => {
                let mut command = Command::new("taskset");
                command.args(["-c", "0", program]);
                command
            }
            Placement::Shared => Command::new(program),
        }
    }

    fn describe(self) -> &'static str {
        match self {
            Placement::Pinned => {
                "servers pinned to CPU 0 and the load generator to CPU 1 with `taskset` \
                 (each server runs one tokio worker; the generator is one thread)"
            }
            Placement::Shared => {
                "not pinned (fewer than 2 CPUs or no `taskset`): servers and load generator \
                 share the CPUs, so the figures are lower bounds"
            }
        }
    }
}

/// A server process, killed when dropped.
struct Server {
    child: Child,
    addr: SocketAddr,
}

impl Server {
    /// Starts `command` listening on `addr` and waits for the first answer to `probe`; returns
    /// the server and the time from spawn to that answer.
    fn start(
        mut command: Command,
        addr: SocketAddr,
        probe: &[u8],
    ) -> Result<(Self, Duration), String> {
        let started = Instant::now();
        let child = command
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(|e| format!("cannot start {command:?}: {e}"))?;
        let mut server = Server { child, addr };
        loop {
            match fetch(addr, probe) {
                Ok((200, _)) => return Ok((server, started.elapsed())),
                Ok((status, body)) => {
                    return Err(format!(
                        "{command:?} answered {status}: {}",
                        String::from_utf8_lossy(&body)
                    ));
                }
                Err(_) if started.elapsed() < Duration::from_secs(10) => {
                    if let Ok(Some(status)) = server.child.try_wait() {
                        return Err(format!("{command:?} exited with {status}"));
                    }
                    std::thread::sleep(Duration::from_micros(200));
                }
                Err(error) => return Err(format!("{command:?} never answered: {error}")),
            }
        }
    }

    fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Resident set size now, in KiB.
    fn rss_kib(&self) -> Option<u64> {
        status_field(self.pid(), "VmRSS:")
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn status_field(pid: u32, field: &str) -> Option<u64> {
    let status = fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find_map(|line| line.strip_prefix(field))
        .and_then(|rest| rest.trim().trim_end_matches("kB").trim().parse().ok())
}

/// CPU time used so far by every thread of `pid` ("self" for this process), from schedstat.
fn cpu_time(pid: &str) -> Duration {
    let Ok(tasks) = fs::read_dir(format!("/proc/{pid}/task")) else {
        return Duration::ZERO;
    };
    let nanos: u64 = tasks
        .filter_map(Result::ok)
        .filter_map(|task| fs::read_to_string(task.path().join("schedstat")).ok())
        .filter_map(|s| s.split_whitespace().next()?.parse::<u64>().ok())
        .sum();
    Duration::from_nanos(nanos)
}

fn free_port() -> Result<SocketAddr, String> {
    let listener = StdListener::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    listener.local_addr().map_err(|e| e.to_string())
}

fn start_service(
    placement: Placement,
    bin: &Path,
    probe: &[u8],
) -> Result<(Server, Duration), String> {
    let addr = free_port()?;
    let mut command = placement.server(&bin.to_string_lossy());
    command
        .env("HOST", "127.0.0.1")
        .env("PORT", addr.port().to_string());
    Server::start(command, addr, probe)
}

fn start_baseline(placement: Placement, body_file: &Path, probe: &[u8]) -> Result<Server, String> {
    let addr = free_port()?;
    let me = std::env::current_exe().map_err(|e| e.to_string())?;
    let mut command = placement.server(&me.to_string_lossy());
    command
        .arg("serve-baseline")
        .arg(addr.port().to_string())
        .arg(body_file);
    Server::start(command, addr, probe).map(|(server, _)| server)
}

// ---------------------------------------------------------------------------------------------
// A minimal HTTP/1.1 client: one request at a time per keep-alive connection

/// A request written out once, sent as is every time.
#[derive(Debug, Clone)]
struct Target {
    name: String,
    bytes: Arc<[u8]>,
}

impl Target {
    fn new(name: &str, method: &str, path: &str, body: Option<&str>) -> Self {
        let mut text = format!("{method} {path} HTTP/1.1\r\nhost: 127.0.0.1\r\n");
        if let Some(body) = body {
            let _ = write!(
                text,
                "content-type: application/json\r\ncontent-length: {}\r\n\r\n{body}",
                body.len()
            );
        } else {
            text.push_str("\r\n");
        }
        Self {
            name: name.to_owned(),
            bytes: text.into_bytes().into(),
        }
    }
}

/// Where the head of a response ends, its status and its body length.
struct Head {
    len: usize,
    status: u16,
    content_length: usize,
}

fn parse_head(buf: &[u8]) -> io::Result<Option<Head>> {
    let Some(end) = buf.windows(4).position(|w| w == b"\r\n\r\n") else {
        return Ok(None);
    };
    let bad = |what: &str| io::Error::new(io::ErrorKind::InvalidData, what.to_owned());
    let head = std::str::from_utf8(&buf[..end]).map_err(|_| bad("non-UTF-8 head"))?;
    let mut lines = head.split("\r\n");
    let status = lines
        .next()
        .and_then(|line| line.split(' ').nth(1))
        .and_then(|code| code.parse().ok())
        .ok_or_else(|| bad("no status line"))?;
    let mut content_length = None;
    for line in lines {
        let Some((name, value)) = line.split_once(':') else {
            continue;
        };
        if name.eq_ignore_ascii_case("content-length") {
            content_length = value.trim().parse().ok();
        } else if name.eq_ignore_ascii_case("transfer-encoding") {
            return Err(bad("chunked responses are not supported by this client"));
        }
    }
    Ok(Some(Head {
        len: end + 4,
        status,
        content_length: content_length.ok_or_else(|| bad("no content-length"))?,
    }))
}

/// One blocking request on a fresh connection: for set-up and start-up timing.
fn fetch(addr: SocketAddr, request: &[u8]) -> io::Result<(u16, Vec<u8>)> {
    let mut stream = StdStream::connect(addr)?;
    stream.set_nodelay(true)?;
    stream.set_read_timeout(Some(Duration::from_secs(10)))?;
    stream.write_all(request)?;
    let mut buf = Vec::with_capacity(4096);
    let mut chunk = [0u8; 64 * 1024];
    loop {
        if let Some(head) = parse_head(&buf)? {
            let total = head.len + head.content_length;
            while buf.len() < total {
                let n = stream.read(&mut chunk)?;
                if n == 0 {
                    return Err(io::ErrorKind::UnexpectedEof.into());
                }
                buf.extend_from_slice(&chunk[..n]);
            }
            return Ok((head.status, buf[head.len..total].to_vec()));
        }
        let n = stream.read(&mut chunk)?;
        if n == 0 {
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
        buf.extend_from_slice(&chunk[..n]);
    }
}

/// A keep-alive connection of the load generator.
struct Connection {
    addr: SocketAddr,
    stream: TcpStream,
    buf: Vec<u8>,
}

impl Connection {
    async fn open(addr: SocketAddr) -> io::Result<Self> {
        let stream = TcpStream::connect(addr).await?;
        stream.set_nodelay(true)?;
        Ok(Self {
            addr,
            stream,
            buf: Vec::with_capacity(64 * 1024),
        })
    }

    /// One exchange, recorded in `recorded` with its latency from `since` when `since` lies
    /// in the measured window (at or after `from`). A failed exchange counts as an error and
    /// the connection is opened again.
    async fn measure(
        &mut self,
        request: &[u8],
        since: Instant,
        from: Instant,
        recorded: &mut Recorded,
    ) -> io::Result<()> {
        match self.exchange(request).await {
            Ok(status) if since >= from => recorded.record(since.elapsed(), status),
            Ok(_) => {}
            Err(_) => {
                recorded.errors += 1;
                *self = Connection::open(self.addr).await?;
            }
        }
        Ok(())
    }

    /// Sends `request` and reads the whole response; returns its status.
    async fn exchange(&mut self, request: &[u8]) -> io::Result<u16> {
        self.exchange_body(request).await.map(|(status, _)| status)
    }

    /// Sends `request` and reads the whole response; returns its status and body.
    async fn exchange_body(&mut self, request: &[u8]) -> io::Result<(u16, &[u8])> {
        self.stream.write_all(request).await?;
        self.buf.clear();
        loop {
            if let Some(head) = parse_head(&self.buf)? {
                let total = head.len + head.content_length;
                self.buf.reserve(total.saturating_sub(self.buf.len()));
                while self.buf.len() < total {
                    self.fill().await?;
                }
                return Ok((head.status, &self.buf[head.len..total]));
            }
            self.fill().await?;
        }
    }

    async fn fill(&mut self) -> io::Result<()> {
        if self.buf.capacity() - self.buf.len() < 16 * 1024 {
            self.buf.reserve(64 * 1024);
        }
        match self.stream.read_buf(&mut self.buf).await? {
            0 => Err(io::ErrorKind::UnexpectedEof.into()),
            _ => Ok(()),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Measuring

/// What one connection saw in the measured window.
#[derive(Debug, Default)]
struct Recorded {
    latencies_ns: Vec<u64>,
    statuses: BTreeMap<u16, u64>,
    errors: u64,
}

impl Recorded {
    fn merge(&mut self, other: Recorded) {
        self.latencies_ns.extend(other.latencies_ns);
        for (status, n) in other.statuses {
            *self.statuses.entry(status).or_default() += n;
        }
        self.errors += other.errors;
    }

    fn record(&mut self, latency: Duration, status: u16) {
        self.latencies_ns.push(latency.as_nanos() as u64);
        *self.statuses.entry(status).or_default() += 1;
    }
}

/// Server-side readings over the measured window.
#[derive(Debug, Default, Clone, Copy)]
struct Readings {
    server_cpu: f64,
    client_cpu: f64,
    peak_rss_kib: u64,
}

/// One measured row.
#[derive(Debug, Clone)]
struct Row {
    target: String,
    connections: usize,
    requests_per_sec: f64,
    p50: Duration,
    p99: Duration,
    p999: Duration,
    max: Duration,
    non_200: u64,
    errors: u64,
    readings: Readings,
}

impl Row {
    fn new(
        target: &str,
        connections: usize,
        window: Duration,
        mut recorded: Recorded,
        readings: Readings,
    ) -> Self {
        recorded.latencies_ns.sort_unstable();
        let at = |q: f64| -> Duration {
            let n = recorded.latencies_ns.len();
            if n == 0 {
                return Duration::ZERO;
            }
            let rank = ((q * n as f64).ceil() as usize).clamp(1, n);
            Duration::from_nanos(recorded.latencies_ns[rank - 1])
        };
        let ok = recorded.statuses.get(&200).copied().unwrap_or(0);
        let all: u64 = recorded.statuses.values().sum();
        Self {
            target: target.to_owned(),
            connections,
            requests_per_sec: all as f64 / window.as_secs_f64(),
            p50: at(0.50),
            p99: at(0.99),
            p999: at(0.999),
            max: at(1.0),
            non_200: all - ok,
            errors: recorded.errors,
            readings,
        }
    }
}

/// Watches `pid` over `[from, to]`: CPU time of it and of this process, and its peak RSS
/// sampled every 50 ms.
async fn watch(pid: u32, from: Instant, to: Instant) -> Readings {
    let task = pid.to_string();
    tokio::time::sleep_until(from.into()).await;
    let (server0, client0) = (cpu_time(&task), cpu_time("self"));
    let started = Instant::now();
    let mut peak = 0;
    while Instant::now() < to {
        peak = peak.max(status_field(pid, "VmRSS:").unwrap_or(0));
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let wall = started.elapsed().as_secs_f64();
    Readings {
        server_cpu: (cpu_time(&task) - server0).as_secs_f64() / wall,
        client_cpu: (cpu_time("self") - client0).as_secs_f64() / wall,
        peak_rss_kib: peak,
    }
}

/// Waits for every connection and the watcher, and makes their figures one row.
async fn gather(
    target: &Target,
    window: Duration,
    tasks: Vec<tokio::task::JoinHandle<io::Result<Recorded>>>,
    watcher: tokio::task::JoinHandle<Readings>,
) -> Result<Row, String> {
    let connections = tasks.len();
    let mut recorded = Recorded::default();
    for task in tasks {
        let connection = task.await.map_err(|e| e.to_string())?;
        recorded.merge(connection.map_err(|e| format!("{}: {e}", target.name))?);
    }
    let readings = watcher.await.map_err(|e| e.to_string())?;
    Ok(Row::new(
        &target.name,
        connections,
        window,
        recorded,
        readings,
    ))
}

/// Closed loop: `connections` connections each send the next request as soon as the last is
/// answered, for the warm-up and then the measured window.
fn closed_loop(
    runtime: &Runtime,
    server: &Server,
    target: &Target,
    connections: usize,
    options: &Options,
) -> Result<Row, String> {
    runtime.block_on(async {
        let start = Instant::now();
        let from = start + options.warmup;
        let to = from + options.duration;
        let watcher = tokio::spawn(watch(server.pid(), from, to));
        let mut tasks = Vec::with_capacity(connections);
        for _ in 0..connections {
            let request = Arc::clone(&target.bytes);
            let addr = server.addr;
            tasks.push(tokio::spawn(async move {
                let mut recorded = Recorded::default();
                let mut connection = Connection::open(addr).await?;
                loop {
                    let sent = Instant::now();
                    if sent >= to {
                        return Ok::<_, io::Error>(recorded);
                    }
                    connection
                        .measure(&request, sent, from, &mut recorded)
                        .await?;
                }
            }));
        }
        gather(target, options.duration, tasks, watcher).await
    })
}

/// Open loop at `rate` requests per second: a pacer releases requests on schedule and any free
/// connection sends the next one. Latency runs from the scheduled time, so time spent queued
/// behind a slow answer counts (no coordinated omission). The pacer spins on the load
/// generator's own CPU for microsecond-accurate release, rather than the timer's 1 ms ticks.
fn open_loop(
    runtime: &Runtime,
    server: &Server,
    target: &Target,
    connections: usize,
    rate: f64,
    options: &Options,
) -> Result<Row, String> {
    runtime.block_on(async {
        let start = Instant::now();
        let from = start + options.warmup;
        let to = from + options.duration;
        let watcher = tokio::spawn(watch(server.pid(), from, to));
        let (release, due) = mpsc::unbounded_channel::<Instant>();
        let due = Arc::new(Mutex::new(due));
        let mut tasks = Vec::with_capacity(connections);
        for _ in 0..connections {
            let request = Arc::clone(&target.bytes);
            let due = Arc::clone(&due);
            let addr = server.addr;
            tasks.push(tokio::spawn(async move {
                let mut recorded = Recorded::default();
                let mut connection = Connection::open(addr).await?;
                // Give up on what is still queued 2 s after the end (an overloaded server).
                let give_up = to + Duration::from_secs(2);
                loop {
                    let Some(scheduled) = due.lock().await.recv().await else {
                        return Ok::<_, io::Error>(recorded);
                    };
                    if Instant::now() > give_up {
                        recorded.errors += 1;
                        continue;
                    }
                    connection
                        .measure(&request, scheduled, from, &mut recorded)
                        .await?;
                }
            }));
        }
        let interval = Duration::from_secs_f64(1.0 / rate);
        let mut next = start;
        while next < to {
            let now = Instant::now();
            while next <= now && next < to {
                let _ = release.send(next);
                next += interval;
            }
            tokio::task::yield_now().await;
        }
        drop(release);
        gather(target, options.duration, tasks, watcher).await
    })
}

// ---------------------------------------------------------------------------------------------
// The run and its report

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

struct Report<'a> {
    options: &'a Options,
    machine: String,
    placement: Placement,
    rows: &'a [Row],
    table: Option<&'a Row>,
    paced: &'a [Row],
    saturation: f64,
    starts: &'a [Duration],
    idle_rss: [u64; 3],
    peak_rss: u64,
    baseline_idle_rss: u64,
    sizes: &'a BTreeMap<String, usize>,
}

fn ms(d: Duration) -> String {
    format!("{:.3}", d.as_secs_f64() * 1e3)
}

fn mib(kib: u64) -> String {
    format!("{:.1}", kib as f64 / 1024.0)
}

fn machine() -> String {
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

fn report(r: &Report<'_>) -> String {
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
