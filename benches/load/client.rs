//! The load generator: a minimal HTTP/1.1 client (one request at a time per keep-alive
//! connection), and the closed and open loops that measure a server with it.

use std::{
    collections::BTreeMap,
    fmt::Write as _,
    io::{self, Read, Write},
    net::{SocketAddr, TcpStream as StdStream},
    sync::Arc,
    time::{Duration, Instant},
};

use tokio::{
    io::{AsyncReadExt, AsyncWriteExt},
    net::TcpStream,
    runtime::Runtime,
    sync::{Mutex, mpsc},
};

use super::{
    options::Options,
    process::{Server, cpu_time, status_field},
};

/// A request written out once, sent as is every time.
#[derive(Debug, Clone)]
pub struct Target {
    pub name: String,
    pub bytes: Arc<[u8]>,
}

impl Target {
    pub fn new(name: &str, method: &str, path: &str, body: Option<&str>) -> Self {
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
pub struct Head {
    pub len: usize,
    pub status: u16,
    pub content_length: usize,
}

pub fn parse_head(buf: &[u8]) -> io::Result<Option<Head>> {
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
pub fn fetch(addr: SocketAddr, request: &[u8]) -> io::Result<(u16, Vec<u8>)> {
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
pub struct Connection {
    pub addr: SocketAddr,
    pub stream: TcpStream,
    pub buf: Vec<u8>,
}

impl Connection {
    pub async fn open(addr: SocketAddr) -> io::Result<Self> {
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
    pub async fn measure(
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
    pub async fn exchange(&mut self, request: &[u8]) -> io::Result<u16> {
        self.exchange_body(request).await.map(|(status, _)| status)
    }

    /// Sends `request` and reads the whole response; returns its status and body.
    pub async fn exchange_body(&mut self, request: &[u8]) -> io::Result<(u16, &[u8])> {
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

    pub async fn fill(&mut self) -> io::Result<()> {
        if self.buf.capacity() - self.buf.len() < 16 * 1024 {
            self.buf.reserve(64 * 1024);
        }
        match self.stream.read_buf(&mut self.buf).await? {
            0 => Err(io::ErrorKind::UnexpectedEof.into()),
            _ => Ok(()),
        }
    }
}

// Measuring

/// What one connection saw in the measured window.
#[derive(Debug, Default)]
pub struct Recorded {
    pub latencies_ns: Vec<u64>,
    pub statuses: BTreeMap<u16, u64>,
    pub errors: u64,
}

impl Recorded {
    pub fn merge(&mut self, other: Recorded) {
        self.latencies_ns.extend(other.latencies_ns);
        for (status, n) in other.statuses {
            *self.statuses.entry(status).or_default() += n;
        }
        self.errors += other.errors;
    }

    pub fn record(&mut self, latency: Duration, status: u16) {
        self.latencies_ns.push(latency.as_nanos() as u64);
        *self.statuses.entry(status).or_default() += 1;
    }
}

/// Server-side readings over the measured window.
#[derive(Debug, Default, Clone, Copy)]
pub struct Readings {
    pub server_cpu: f64,
    pub client_cpu: f64,
    pub peak_rss_kib: u64,
}

/// One measured row.
#[derive(Debug, Clone)]
pub struct Row {
    pub target: String,
    pub connections: usize,
    pub requests_per_sec: f64,
    pub p50: Duration,
    pub p99: Duration,
    pub p999: Duration,
    pub max: Duration,
    pub non_200: u64,
    pub errors: u64,
    pub readings: Readings,
}

impl Row {
    pub fn new(
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
pub async fn watch(pid: u32, from: Instant, to: Instant) -> Readings {
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
pub async fn gather(
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

/// A run's timeline: it starts now, measures from the end of the warm-up `from` to `to`, and
/// `watcher` reads the server's and the client's CPU over that window.
struct Window {
    start: Instant,
    from: Instant,
    to: Instant,
    watcher: tokio::task::JoinHandle<Readings>,
}

impl Window {
    /// Opens the window of one run (inside the runtime: it spawns the watcher).
    fn open(server: &Server, options: &Options) -> Self {
        let start = Instant::now();
        let from = start + options.warmup;
        let to = from + options.duration;
        let watcher = tokio::spawn(watch(server.pid(), from, to));
        Self {
            start,
            from,
            to,
            watcher,
        }
    }
}

/// Closed loop: `connections` connections each send the next request as soon as the last is
/// answered, for the warm-up and then the measured window.
pub fn closed_loop(
    runtime: &Runtime,
    server: &Server,
    target: &Target,
    connections: usize,
    options: &Options,
) -> Result<Row, String> {
    runtime.block_on(async {
        let Window {
            from, to, watcher, ..
        } = Window::open(server, options);
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
pub fn open_loop(
    runtime: &Runtime,
    server: &Server,
    target: &Target,
    connections: usize,
    rate: f64,
    options: &Options,
) -> Result<Row, String> {
    runtime.block_on(async {
        let Window {
            start,
            from,
            to,
            watcher,
        } = Window::open(server, options);
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
