//! The processes of a run: the bench-only baseline server, the service binaries, their placement
//! on CPUs, start-up, RSS and CPU time.

use std::{
    fs,
    net::{SocketAddr, TcpListener as StdListener},
    path::Path,
    process::{Child, Command, Stdio},
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
use tokio::runtime::Runtime;

use super::client::fetch;

// The baseline server (bench only; never part of the shipped binary)

/// `serve-baseline PORT BODY_FILE`: answers every `/distance` request, GET or POST, with the
/// bytes of BODY_FILE as `application/json`, after reading the request body, on the same tokio
/// runtime and TCP_NODELAY setting as the service.
pub fn serve_baseline(args: &[String]) -> Result<(), String> {
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

pub async fn fixed(State(body): State<Bytes>, _request: Bytes) -> impl IntoResponse {
    (
        [(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/json"),
        )],
        body,
    )
}

// Processes: pinning, start-up, RSS and CPU time

/// How processes are placed on CPUs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Placement {
    /// Servers on CPU 0, load generator on CPU 1.
    Pinned,
    /// No `taskset` or fewer than 2 CPUs: left to the scheduler.
    Shared,
}

impl Placement {
    pub fn detect() -> Self {
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
    pub fn pin_self(self) -> Result<(), String> {
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
    pub fn server(self, program: &str) -> Command {
        match self {
            Placement::Pinned => {
                let mut command = Command::new("taskset");
                command.args(["-c", "0", program]);
                command
            }
            Placement::Shared => Command::new(program),
        }
    }

    pub fn describe(self) -> &'static str {
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
pub struct Server {
    pub child: Child,
    pub addr: SocketAddr,
}

impl Server {
    /// Starts `command` listening on `addr` and waits for the first answer to `probe`; returns
    /// the server and the time from spawn to that answer.
    pub fn start(
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

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Resident set size now, in KiB.
    pub fn rss_kib(&self) -> Option<u64> {
        status_field(self.pid(), "VmRSS:")
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub fn status_field(pid: u32, field: &str) -> Option<u64> {
    let status = fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find_map(|line| line.strip_prefix(field))
        .and_then(|rest| rest.trim().trim_end_matches("kB").trim().parse().ok())
}

/// CPU time used so far by every thread of `pid` ("self" for this process), from schedstat.
pub fn cpu_time(pid: &str) -> Duration {
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

pub fn free_port() -> Result<SocketAddr, String> {
    let listener = StdListener::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    listener.local_addr().map_err(|e| e.to_string())
}

pub fn start_service(
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

pub fn start_baseline(
    placement: Placement,
    body_file: &Path,
    probe: &[u8],
) -> Result<Server, String> {
    let addr = free_port()?;
    let me = std::env::current_exe().map_err(|e| e.to_string())?;
    let mut command = placement.server(&me.to_string_lossy());
    command
        .arg("serve-baseline")
        .arg(addr.port().to_string())
        .arg(body_file);
    Server::start(command, addr, probe).map(|(server, _)| server)
}
