//! Settings: the command line and environment (clap, every flag with an `env` twin), the
//! defaults in code and the checks that refuse a bad value before the server starts.
//!
//! Every default is a constant below with the reason it was chosen; `--help` shows them all.

use std::{net::IpAddr, path::PathBuf, time::Duration};

use clap::{Args, Parser, Subcommand, ValueEnum};

use values::{count, delay, duration, size, timeout};

pub mod depth_map;
pub mod environment;
pub mod help;
pub mod tokens;
pub mod values;

pub use depth_map::DepthMapArgs;
pub use tokens::ApiTokens;

/// Default request body limit: 64 KiB. The largest legitimate body (a rig plus a range) is under
/// 1 KiB; 64 KiB leaves room for growth while bounding what a client can make us buffer.
pub const DEFAULT_BODY_LIMIT: usize = 64 * 1024;
/// Default cap on `/table` rows (`steps`): 10 000 rows is ~1.5 MB of JSON, a few ms of work.
pub const DEFAULT_MAX_TABLE_ROWS: usize = 10_000;
/// Default cap on `/chart-data` points per series: as for the table.
pub const DEFAULT_MAX_CHART_POINTS: usize = 10_000;
/// Default cap on the correspondences in one batch `POST /distance`: 10 000 is a dense frame's
/// worth of matches from a feature tracker, answered in a few ms as ~2 MB of JSON.
pub const DEFAULT_MAX_BATCH_POINTS: usize = 10_000;
/// Default body limit of `POST /distance`, the one route that takes batches: 2 MiB. A full batch
/// of 10 000 points is ~0.5 MB compact and under 1 MB pretty-printed; the single-shot routes keep
/// the smaller [`DEFAULT_BODY_LIMIT`].
pub const DEFAULT_BATCH_BODY_LIMIT: usize = 2 * 1024 * 1024;
/// Default request timeout: 5 s. The slowest request (a 10 000-row table) takes milliseconds, so
/// anything near this is a stalled client body or an overloaded host, not work worth waiting for.
pub const DEFAULT_REQUEST_TIMEOUT: Duration = Duration::from_secs(5);
/// Default header read timeout: 10 s. A real client sends its headers in one packet; this cuts
/// off slow-header (slowloris) clients. hyper also applies it to idle keep-alive connections.
pub const DEFAULT_HEADER_READ_TIMEOUT: Duration = Duration::from_secs(10);
/// Default concurrency limit: 512 requests in flight. Each costs microseconds of CPU and at most
/// one body (64 KiB; a full batch is the exception, see [`DEFAULT_BATCH_BODY_LIMIT`]), so 512
/// saturates two cores many times over while bounding memory; requests beyond it are shed at
/// once with 503 rather than queued.
pub const DEFAULT_CONCURRENCY_LIMIT: usize = 512;
/// Default time to keep serving with readiness off after SIGTERM: 0 s for local use; set it to a
/// few seconds behind a load balancer so that it stops routing here first.
pub const DEFAULT_SHUTDOWN_DELAY: Duration = Duration::ZERO;
/// Default bound on draining in-flight requests after the listener closes: 10 s, twice the
/// request timeout and well inside Kubernetes' default 30 s grace period.
pub const DEFAULT_SHUTDOWN_TIMEOUT: Duration = Duration::from_secs(10);
/// Default minimum request body rate: 1 KiB/s on average, from the request's start, once the
/// grace period has passed. A phone on a poor uplink (GPRS's worst, 20 kbit/s) sends more than
/// twice that; a client that trickles its body to hold the server's memory (a byte every two
/// seconds) is cut off with 408 at the end of the grace period. Kestrel's default is 240 B/s,
/// Apache's `mod_reqtimeout` 500 B/s.
pub const DEFAULT_MIN_BODY_RATE: usize = 1024;
/// Default grace period of the minimum body rate: 5 s (Kestrel's), for the connection's first
/// round trips and a slow start over a poor link.
pub const DEFAULT_BODY_RATE_GRACE: Duration = Duration::from_secs(5);
/// Default write timeout: 30 s. A client reading its answer makes progress every few
/// milliseconds, even over a poor downlink; one that reads nothing for 30 s has stopped, and
/// holds the answer's memory for nothing.
pub const DEFAULT_WRITE_TIMEOUT: Duration = Duration::from_secs(30);
/// Default period of reading the tokens file again: 10 s. A Kubernetes Secret mounted as a
/// file changes in place within about a minute, so this adds little to a rotation, for one
/// small read.
pub const DEFAULT_API_TOKENS_RELOAD: Duration = Duration::from_secs(10);
/// Default log filter.
pub const DEFAULT_LOG_LEVEL: &str = "info";

/// Default body limit of the heavy (image) routes: 32 MiB, a rectified pair of 12-megapixel
/// PNGs or a pair of 4K frames with room to spare, while bounding what one upload can make the
/// server buffer.
pub const DEFAULT_HEAVY_BODY_LIMIT: usize = 32 * 1024 * 1024;
/// Default request timeout of the heavy routes: 30 s, for an upload over a slow link plus
/// seconds of matching; past it the work is abandoned.
pub const DEFAULT_HEAVY_REQUEST_TIMEOUT: Duration = Duration::from_secs(30);
/// Default memory budget shared by the heavy requests in flight: 1 GiB, a few large requests at
/// once (a 1280 × 720 pair with 128 disparities needs a few hundred MiB) within a pod of 2 GiB.
pub const DEFAULT_HEAVY_MEMORY_BUDGET: usize = 1024 * 1024 * 1024;

/// Default cap on an image's pixels: 34 megapixels. It admits an 8K UHD frame (7680 × 4320,
/// 33.2 MP), a 24 MP camera's photograph (6000 × 4000) and a phone's 12 MP one (4032 × 3024);
/// what a request may do with them is governed by the memory budget, which every request
/// reserves from first.
pub const DEFAULT_MAX_IMAGE_PIXELS: usize = 34_000_000;

/// Default cap on the streams open at once (`/depth-stream`): 8. Each holds its frame limit
/// and its filter's state in the heavy budget for its life, and takes a compute slot for each
/// frame it matches, so a few streams already share the cores; more wait at the client.
pub const DEFAULT_MAX_STREAMS: usize = 8;
/// Default time a stream may send nothing before it is closed: 60 s, past any pause of a
/// camera being moved, short enough that a client gone without closing frees its memory.
pub const DEFAULT_STREAM_IDLE_TIMEOUT: Duration = Duration::from_secs(60);
/// Default largest frame message of a stream: 16 MiB, a side-by-side 4K frame as JPEG or a
/// 1080p one as PNG with room to spare. Each open stream holds this much of the heavy budget,
/// the most a message being read may take.
pub const DEFAULT_STREAM_FRAME_LIMIT: usize = 16 * 1024 * 1024;

/// Default concurrency limit of the heavy routes: twice the number of CPUs, and at least 4. A
/// request takes its slot when its work starts, once its body has arrived, so an upload does
/// not hold one. The requests working share the matcher's threads (one a core), so more of them than cores
/// each go slower rather than thrash; what keeps them within memory is the heavy budget, which
/// every request reserves from first. A client feeding two or three cameras is then not refused
/// while the budget holds their pairs.
pub fn default_heavy_concurrency() -> usize {
    std::thread::available_parallelism()
        .map_or(1, usize::from)
        .saturating_mul(2)
        .max(4)
}

/// The command line of the `stereo-distance` binary.
#[derive(Debug, Parser)]
#[command(
    name = "stereo-distance",
    version,
    about = "HTTP JSON service that turns a stereo rig and what it sees into distances with their \
             error: calibration and its check, rectification, depth maps, a live camera's frames streamed over a \
             WebSocket, matches, and recordings' folders",
    long_about = "HTTP JSON service that turns a stereo rig and what it sees into distances with \
                  their error: chessboard or ChArUco pairs to a calibration (σ per parameter, \
                  OpenCV and ROS files, or started from an earlier one), whether an old \
                  calibration still holds from ordinary frames (/calibration/check), raw frames \
                  rectified, depth maps with each pixel's σ and a clicked point's match, a live stereo camera's frames streamed over a \
                  WebSocket (/depth-stream, with a temporal filter) and board views found \
                  one at a time (/board), and the distance with its error bar; `depth-map` \
                  turns a recording's folder of pairs into depth maps.\n\nEvery option can also be set through the environment variable shown \
                  with it; a flag wins over its variable. Durations take units: 500ms, 5s, 1m.",
    after_help = "Fixed caps, not options: an image is at most 8192 pixels a side; a match \
                  searches at most 512 disparities (max_disparity − min_disparity); /calibrate \
                  takes at most 60 views in one request."
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
    #[command(flatten)]
    pub config: Config,
}

/// What the binary does; serving is the default.
#[derive(Debug, Clone, PartialEq, Subcommand)]
pub enum Command {
    /// Serve the API (the default when no command is given).
    Serve,
    /// Ask the server at HOST:PORT for /healthz and exit 0 when it answers 200 (for container
    /// HEALTHCHECKs: the runtime image has no curl). An unspecified HOST such as 0.0.0.0 is
    /// probed on loopback.
    Healthcheck {
        /// How long to wait for the answer.
        #[arg(long, default_value = "2s", value_parser = duration)]
        timeout: Duration,
    },
    /// Every pair of a recording (folders of images, or a ROS 2 or ROS 1 bag) to depth maps,
    /// as /depth-map makes them, or to an MCAP file of ROS 2 messages: in this process
    /// (under the server's limits, set by its options before or after `depth-map`; its help
    /// shows those a run uses, `serve --help` all of them), or sent to a running service
    /// with --server. Pairs already written are skipped, so a stopped run resumes; a file
    /// without a partner or that cannot be read is named and the rest go on. A progress bar
    /// shows on a terminal.
    DepthMap(Box<DepthMapArgs>),
}

/// Log line format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum LogFormat {
    /// Human-readable lines, for a terminal.
    #[default]
    Pretty,
    /// One JSON object per line, for a log collector.
    Json,
}

/// Which requests get an access log line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum AccessLog {
    /// Every request: one line each, which at full load costs more CPU than the request.
    All,
    /// Requests answered 4xx or 5xx (the default): what a caller or an operator needs to
    /// look into. Successful requests are counted in `/metrics`.
    #[default]
    Errors,
    /// None.
    Off,
}

/// Everything the server needs to start.
#[derive(Debug, Clone, PartialEq, Eq, Args)]
pub struct Config {
    /// Address to listen on; 0.0.0.0 for every interface (as in the container image).
    #[arg(global = true, long, env = "HOST", default_value = "127.0.0.1")]
    pub host: IpAddr,

    /// Port to listen on; 0 picks a free one.
    #[arg(global = true, long, env = "PORT", default_value_t = 8080)]
    pub port: u16,

    /// Log format: pretty (for a terminal) or json (one object per line).
    #[arg(global = true, long, env = "LOG_FORMAT", value_enum, default_value_t = LogFormat::Pretty)]
    pub log_format: LogFormat,

    /// Which requests get an access log line (target `access`): all, errors (4xx and 5xx) or
    /// off. Every request is counted in /metrics either way.
    #[arg(global = true, long, env = "ACCESS_LOG", value_enum, default_value_t = AccessLog::Errors)]
    pub access_log: AccessLog,

    /// Log filter in tracing's EnvFilter syntax, e.g. `info` or `stereo_distance=debug,info`.
    #[arg(global = true, long, env = "RUST_LOG", default_value = DEFAULT_LOG_LEVEL, value_parser = log_filter)]
    pub log_level: String,

    /// Origins allowed to call the API from a browser (CORS), comma-separated, such as
    /// `https://app.example.com`. Empty (the default) allows none; `*` allows any.
    #[arg(global = true, long, env = "CORS_ALLOWED_ORIGINS", value_delimiter = ',', value_parser = origin)]
    pub cors_allowed_origins: Vec<String>,

    /// Longest time one request may take, body upload included; past it the answer is 408 (body
    /// still arriving) or 503 (server too slow).
    #[arg(global = true, long, env = "REQUEST_TIMEOUT", default_value = "5s", value_parser = timeout)]
    pub request_timeout: Duration,

    /// Longest time a client may take to send its request headers (and to stay idle on a
    /// keep-alive connection) before the connection is closed.
    #[arg(global = true, long, env = "HEADER_READ_TIMEOUT", default_value = "10s", value_parser = timeout)]
    pub header_read_timeout: Duration,

    /// Slowest accepted request body, in bytes a second (or with a unit: 512, 1KiB, 64KiB): a
    /// body that, once --body-rate-grace has passed, has come slower than this on average since
    /// its request started is cut off with 408 and its connection closed. 0 switches it off.
    #[arg(global = true, long, env = "MIN_BODY_RATE", value_name = "SIZE", default_value = "1KiB",
          value_parser = size::<0, 1_073_741_824>)]
    pub min_body_rate: usize,

    /// How long a request body may take before --min-body-rate applies.
    #[arg(global = true, long, env = "BODY_RATE_GRACE", default_value = "5s", value_parser = delay)]
    pub body_rate_grace: Duration,

    /// Longest time an answer may wait for a client that reads nothing (its socket full);
    /// then the connection is reset and the answer's memory freed.
    #[arg(global = true, long, env = "WRITE_TIMEOUT", default_value = "30s", value_parser = timeout)]
    pub write_timeout: Duration,

    /// Most API requests served at once; more are refused at once with 503 and Retry-After.
    #[arg(global = true, long, env = "CONCURRENCY_LIMIT", default_value_t = DEFAULT_CONCURRENCY_LIMIT,
          value_parser = count::<1, 1_000_000>)]
    pub concurrency_limit: usize,

    /// After SIGTERM/SIGINT, how long to keep serving with /readyz answering 503, so that a load
    /// balancer stops sending traffic before the listener closes.
    #[arg(global = true, long, env = "SHUTDOWN_DELAY", default_value = "0s", value_parser = delay)]
    pub shutdown_delay: Duration,

    /// After the listener closes, the longest wait for in-flight requests to finish.
    #[arg(global = true, long, env = "SHUTDOWN_TIMEOUT", default_value = "10s", value_parser = timeout)]
    pub shutdown_timeout: Duration,

    /// A file of bearer tokens, one or more (separated by new lines, commas or spaces; `#`
    /// starts a comment): when given, every API route and /metrics take a request only with
    /// `Authorization: Bearer <one of them>`, while /healthz, /readyz, the page, /docs and
    /// /openapi.json stay open. The file is read again when it changes (see
    /// --api-tokens-reload), so a token is rotated by adding the new one, moving the clients,
    /// then removing the old one.
    #[arg(global = true, long, env = "API_TOKENS_FILE", value_name = "FILE", value_parser = tokens_file)]
    pub api_tokens_file: Option<PathBuf>,

    /// How often the tokens file is read again (a Kubernetes Secret mounted as a file is
    /// updated in place within about a minute of its change).
    #[arg(global = true, long, env = "API_TOKENS_RELOAD", default_value = "10s", value_parser = timeout)]
    pub api_tokens_reload: Duration,

    /// Bearer tokens, as --api-tokens-file's (comma-separated), accepted besides the file's.
    /// Prefer the variable or the file: a command line is visible to every user of the host.
    #[arg(global = true, long, env = "API_TOKENS", value_name = "TOKENS", hide_env_values = true,
          value_parser = tokens)]
    pub api_tokens: Option<ApiTokens>,

    #[command(flatten)]
    pub limits: Limits,

    #[command(flatten)]
    pub heavy: HeavyLimits,
}

/// The limits of the heavy route group, the image requests: megabytes in, milliseconds to
/// seconds of CPU and tens of MB of memory each. The light group keeps the limits above.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Args)]
#[command(next_help_heading = "Image requests (the heavy route group)")]
pub struct HeavyLimits {
    /// Largest accepted body of an image request (both images and their parts), in bytes or
    /// with a unit (KiB, MiB, GiB); larger bodies get 413. At most the memory budget.
    #[arg(global = true, id = "heavy_body_limit", long = "heavy-body-limit", env = "HEAVY_BODY_LIMIT", value_name = "SIZE",
          default_value = "32MiB", value_parser = size::<1024, 4_294_967_296>)]
    pub body_bytes: usize,

    /// Longest time one image request may take, upload included; 408 or 503 past it.
    #[arg(global = true, id = "heavy_request_timeout", long = "heavy-request-timeout", env = "HEAVY_REQUEST_TIMEOUT", value_name = "DURATION",
          default_value = "30s", value_parser = timeout)]
    pub request_timeout: Duration,

    /// Most image requests working at once (default: twice the number of CPUs, at least 4); a
    /// request takes its slot when its work starts, not while its body is still arriving. One
    /// past the limit is refused at once with 503 and Retry-After.
    #[arg(global = true, id = "heavy_concurrency_limit", long = "heavy-concurrency-limit", env = "HEAVY_CONCURRENCY_LIMIT", value_name = "N",
          default_value_t = default_heavy_concurrency(), value_parser = count::<1, 4096>)]
    pub concurrency_limit: usize,

    /// Memory shared by the image requests in flight, in bytes or with a unit (KiB, MiB, GiB).
    /// Each reserves its body on arrival and its working memory before allocating it, and its
    /// answer stays counted until it is sent; one that does not fit is refused with 503 and
    /// Retry-After. The matcher's buffer pools keep up to
    /// an eighth of it each (96 MiB at most) between requests.
    #[arg(global = true, id = "heavy_memory_budget", long = "heavy-memory-budget", env = "HEAVY_MEMORY_BUDGET", value_name = "SIZE",
          default_value = "1GiB", value_parser = size::<1024, 1_099_511_627_776>)]
    pub memory_budget: usize,

    /// Most pixels (width × height) of one image; a larger one gets 413 naming it, judged from
    /// its header before any pixel is decoded. Every side is at most 8192 pixels besides.
    #[arg(global = true, id = "max_image_pixels", long = "max-image-pixels", env = "MAX_IMAGE_PIXELS", value_name = "PIXELS",
          default_value_t = DEFAULT_MAX_IMAGE_PIXELS, value_parser = count::<1, 67_108_864>)]
    pub max_image_pixels: usize,

    /// Most depth streams (`/depth-stream`, WebSocket) open at once; one more is refused with
    /// 503 and Retry-After before the upgrade.
    #[arg(global = true, long = "max-streams", env = "MAX_STREAMS", value_name = "N",
          default_value_t = DEFAULT_MAX_STREAMS, value_parser = count::<1, 4096>)]
    pub max_streams: usize,

    /// How long a depth stream may send nothing (no frame, no ping) before it is closed.
    #[arg(global = true, long = "stream-idle-timeout", env = "STREAM_IDLE_TIMEOUT", value_name = "DURATION",
          default_value = "60s", value_parser = timeout)]
    pub stream_idle_timeout: Duration,

    /// Largest frame message of a depth stream, in bytes or with a unit; a larger one closes
    /// the stream (1009). Each open stream holds this much of the memory budget.
    #[arg(global = true, long = "stream-frame-limit", env = "STREAM_FRAME_LIMIT", value_name = "SIZE",
          default_value = "16MiB", value_parser = size::<1024, 1_073_741_824>)]
    pub stream_frame_bytes: usize,
}

impl Default for HeavyLimits {
    fn default() -> Self {
        Self {
            body_bytes: DEFAULT_HEAVY_BODY_LIMIT,
            request_timeout: DEFAULT_HEAVY_REQUEST_TIMEOUT,
            concurrency_limit: default_heavy_concurrency(),
            memory_budget: DEFAULT_HEAVY_MEMORY_BUDGET,
            max_image_pixels: DEFAULT_MAX_IMAGE_PIXELS,
            max_streams: DEFAULT_MAX_STREAMS,
            stream_idle_timeout: DEFAULT_STREAM_IDLE_TIMEOUT,
            stream_frame_bytes: DEFAULT_STREAM_FRAME_LIMIT,
        }
    }
}

/// Caps on what one request may ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Args)]
pub struct Limits {
    /// Largest accepted request body, in bytes; larger bodies get 413.
    #[arg(global = true, long = "body-limit", env = "BODY_LIMIT", value_name = "SIZE", default_value = "64KiB",
          value_parser = size::<256, 67_108_864>)]
    pub body_bytes: usize,

    /// Most rows one /table answer may have (`steps`).
    #[arg(global = true, long = "max-table-rows", env = "MAX_TABLE_ROWS", value_name = "ROWS",
          default_value_t = DEFAULT_MAX_TABLE_ROWS, value_parser = count::<1, 1_000_000>)]
    pub table_rows: usize,

    /// Most points one /chart-data series may have (`points`).
    #[arg(global = true, long = "max-chart-points", env = "MAX_CHART_POINTS", value_name = "POINTS",
          default_value_t = DEFAULT_MAX_CHART_POINTS, value_parser = count::<1, 1_000_000>)]
    pub chart_points: usize,

    /// Most correspondences one batch POST /distance may hold (`points`).
    #[arg(global = true, long = "max-batch-points", env = "MAX_BATCH_POINTS", value_name = "POINTS",
          default_value_t = DEFAULT_MAX_BATCH_POINTS, value_parser = count::<1, 1_000_000>)]
    pub batch_points: usize,

    /// Largest accepted body for POST /distance, which takes batches, in bytes; 413 beyond.
    #[arg(global = true, long = "batch-body-limit", env = "BATCH_BODY_LIMIT", value_name = "SIZE",
          default_value = "2MiB", value_parser = size::<256, 268_435_456>)]
    pub batch_body_bytes: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            body_bytes: DEFAULT_BODY_LIMIT,
            table_rows: DEFAULT_MAX_TABLE_ROWS,
            chart_points: DEFAULT_MAX_CHART_POINTS,
            batch_points: DEFAULT_MAX_BATCH_POINTS,
            batch_body_bytes: DEFAULT_BATCH_BODY_LIMIT,
        }
    }
}

impl Default for Config {
    fn default() -> Self {
        Self {
            host: IpAddr::from([127, 0, 0, 1]),
            port: 8080,
            log_format: LogFormat::Pretty,
            access_log: AccessLog::Errors,
            log_level: DEFAULT_LOG_LEVEL.to_owned(),
            cors_allowed_origins: Vec::new(),
            request_timeout: DEFAULT_REQUEST_TIMEOUT,
            header_read_timeout: DEFAULT_HEADER_READ_TIMEOUT,
            min_body_rate: DEFAULT_MIN_BODY_RATE,
            body_rate_grace: DEFAULT_BODY_RATE_GRACE,
            write_timeout: DEFAULT_WRITE_TIMEOUT,
            concurrency_limit: DEFAULT_CONCURRENCY_LIMIT,
            shutdown_delay: DEFAULT_SHUTDOWN_DELAY,
            shutdown_timeout: DEFAULT_SHUTDOWN_TIMEOUT,
            api_tokens_file: None,
            api_tokens_reload: DEFAULT_API_TOKENS_RELOAD,
            api_tokens: None,
            limits: Limits::default(),
            heavy: HeavyLimits::default(),
        }
    }
}

/// The tokens of `API_TOKENS`.
fn tokens(text: &str) -> Result<ApiTokens, String> {
    tokens::parse_tokens(text).map(ApiTokens)
}

/// One token as a header carries it: visible ASCII, no spaces.
pub(crate) fn one_token(text: &str) -> Result<String, String> {
    let text = text.trim();
    if text.is_empty() || !text.chars().all(|c| c.is_ascii_graphic()) {
        return Err("a token is one word of visible ASCII characters".to_owned());
    }
    Ok(text.to_owned())
}

/// A tokens file that reads and holds at least one token.
fn tokens_file(text: &str) -> Result<PathBuf, String> {
    let path = PathBuf::from(text);
    tokens::read_tokens_file(&path)?;
    Ok(path)
}

/// A log filter that tracing can use.
fn log_filter(text: &str) -> Result<String, String> {
    tracing_subscriber::EnvFilter::try_new(text)
        .map(|_| text.to_owned())
        .map_err(|error| format!("not a log filter such as `info` or `debug` ({error})"))
}

/// A browser origin, `scheme://host[:port]` with no path, or `*`.
fn origin(text: &str) -> Result<String, String> {
    let text = text.trim();
    if text.is_empty() || text == "*" {
        // An empty item (as in `CORS_ALLOWED_ORIGINS=`) means no origin; it is dropped later.
        return Ok(text.to_owned());
    }
    let expected = "expected an origin such as https://app.example.com or http://localhost:3000 \
                    (scheme, host and optional port; no path), or *";
    let uri: axum::http::Uri = text.parse().map_err(|_| expected.to_owned())?;
    let scheme_ok = matches!(uri.scheme_str(), Some("http" | "https"));
    let path_ok = matches!(uri.path(), "" | "/") && uri.query().is_none();
    match uri.authority() {
        Some(authority) if scheme_ok && path_ok && !authority.as_str().contains('@') => {
            Ok(format!("{}://{}", uri.scheme_str().unwrap_or("http"), authority).to_lowercase())
        }
        _ => Err(expected.to_owned()),
    }
}

impl Cli {
    /// Parses `args` (the program name first), looking up unset options in the environment.
    pub fn try_parse_args<I, T>(args: I) -> Result<Self, clap::Error>
    where
        I: IntoIterator<Item = T>,
        T: Into<std::ffi::OsString> + Clone,
    {
        let args: Vec<std::ffi::OsString> = args.into_iter().map(Into::into).collect();
        let depth_map = args.iter().skip(1).any(|a| a == "depth-map");
        let command = Self::command_for(depth_map);
        let parsed = command
            .clone()
            .try_get_matches_from(&args)
            .and_then(|matches| <Self as clap::FromArgMatches>::from_arg_matches(&matches));
        match parsed {
            Ok(cli) => cli.finish(),
            Err(error) => Err(environment::named(error, &args, &command)),
        }
    }

    /// Tidies what clap parsed and applies the checks that span more than one value.
    fn finish(mut self) -> Result<Self, clap::Error> {
        self.config.cors_allowed_origins.retain(|o| !o.is_empty());
        self.config.check()?;
        Ok(self)
    }
}

impl Config {
    /// Checks that span more than one option, reported like clap's own errors.
    fn check(&self) -> Result<(), clap::Error> {
        if self.heavy.body_bytes > self.heavy.memory_budget {
            return Err(clap::Error::raw(
                clap::error::ErrorKind::ValueValidation,
                format!(
                    "--heavy-body-limit (HEAVY_BODY_LIMIT, {} bytes) must not exceed \
                     --heavy-memory-budget (HEAVY_MEMORY_BUDGET, {} bytes): every image request \
                     reserves its body from the budget\n",
                    self.heavy.body_bytes, self.heavy.memory_budget
                ),
            ));
        }
        if self.heavy.stream_frame_bytes > self.heavy.memory_budget {
            return Err(clap::Error::raw(
                clap::error::ErrorKind::ValueValidation,
                format!(
                    "--stream-frame-limit (STREAM_FRAME_LIMIT, {} bytes) must not exceed                      --heavy-memory-budget (HEAVY_MEMORY_BUDGET, {} bytes): every stream                      reserves its frame limit from the budget\n",
                    self.heavy.stream_frame_bytes, self.heavy.memory_budget
                ),
            ));
        }
        let origins = &self.cors_allowed_origins;
        if origins.len() > 1 && origins.iter().any(|o| o == "*") {
            return Err(clap::Error::raw(
                clap::error::ErrorKind::ValueValidation,
                "--cors-allowed-origins (CORS_ALLOWED_ORIGINS): `*` allows every origin and \
                 cannot be combined with a list\n",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use clap::{CommandFactory, FromArgMatches};

    use super::*;

    /// Parses `args` with every environment lookup switched off, so the test sees only flags.
    fn parse(args: &[&str]) -> Result<Cli, clap::Error> {
        let command = Cli::command().mut_args(|arg| arg.env(None));
        let matches = command
            .try_get_matches_from(std::iter::once("stereo-distance").chain(args.iter().copied()))?;
        Cli::from_arg_matches(&matches)?.finish()
    }

    /// With no flags the parsed configuration is exactly `Config::default()`: the constants and
    /// the `--help` defaults agree.
    #[test]
    fn flag_defaults_match_code_defaults() {
        let cli = parse(&[]).unwrap();
        assert_eq!(cli.config, Config::default());
        assert_eq!(cli.command, None);
    }

    /// An empty origin list (as `CORS_ALLOWED_ORIGINS=` gives) allows no origin.
    #[test]
    fn empty_origin_list_is_none() {
        let cli = parse(&["--cors-allowed-origins", ""]).unwrap();
        assert!(cli.config.cors_allowed_origins.is_empty());
    }

    /// Flags are read, durations take units, origins are normalised.
    #[test]
    fn reads_flags() {
        let cli = parse(&[
            "--host",
            "0.0.0.0",
            "--port",
            "9000",
            "--log-format",
            "json",
            "--access-log",
            "all",
            "--request-timeout",
            "250ms",
            "--cors-allowed-origins",
            "https://App.example.com/,http://localhost:3000",
            "--body-limit",
            "1024",
            "--concurrency-limit",
            "3",
            "--min-body-rate",
            "4KiB",
            "--body-rate-grace",
            "2s",
            "--write-timeout",
            "45s",
        ])
        .unwrap();
        let config = cli.config;
        assert_eq!(config.min_body_rate, 4096);
        assert_eq!(config.body_rate_grace, Duration::from_secs(2));
        assert_eq!(config.write_timeout, Duration::from_secs(45));
        assert_eq!(config.host.to_string(), "0.0.0.0");
        assert_eq!(config.port, 9000);
        assert_eq!(config.log_format, LogFormat::Json);
        assert_eq!(config.access_log, AccessLog::All);
        assert_eq!(config.request_timeout, Duration::from_millis(250));
        assert_eq!(
            config.cors_allowed_origins,
            ["https://app.example.com", "http://localhost:3000"]
        );
        assert_eq!(config.limits.body_bytes, 1024);
        assert_eq!(config.concurrency_limit, 3);
    }

    /// Bad values are refused with a message naming the option and what it accepts.
    #[test]
    fn refuses_bad_values() {
        for (args, expected) in [
            (&["--port", "eighty"][..], "--port"),
            (&["--host", "localhost"][..], "--host"),
            (&["--concurrency-limit", "0"][..], "from 1 to 1000000"),
            (&["--body-limit", "10"][..], "from 256"),
            (&["--request-timeout", "5"][..], "duration"),
            (&["--request-timeout", "0s"][..], "from 1ms"),
            (&["--log-format", "xml"][..], "pretty"),
            (&["--log-level", "info,[["][..], "log filter"),
            (
                &["--cors-allowed-origins", "https://a.com/path"][..],
                "origin",
            ),
            (
                &["--cors-allowed-origins", "*,https://a.com"][..],
                "cannot be combined",
            ),
            (&["--heavy-body-limit", "32 MB"][..], "expected a size"),
            (&["--heavy-body-limit", "12"][..], "from 1024"),
            (
                &["--heavy-memory-budget", "99999999999GiB"][..],
                "expected a size",
            ),
            (&["--heavy-concurrency-limit", "0"][..], "from 1 to 4096"),
            (&["--min-body-rate", "fast"][..], "expected a size"),
            (&["--body-rate-grace", "10m"][..], "at most 5m"),
            (&["--write-timeout", "0s"][..], "from 1ms"),
            (
                &[
                    "--heavy-body-limit",
                    "64MiB",
                    "--heavy-memory-budget",
                    "32MiB",
                ][..],
                "must not exceed",
            ),
            (
                &[
                    "--stream-frame-limit",
                    "64MiB",
                    "--heavy-memory-budget",
                    "48MiB",
                ][..],
                "--stream-frame-limit (STREAM_FRAME_LIMIT, 67108864 bytes) must not exceed",
            ),
        ] {
            let error = parse(args).expect_err(&format!("{args:?} must be refused"));
            let text = error.to_string();
            assert!(text.contains(expected), "{args:?}: {text}");
        }
    }

    /// The heavy group's flags take sizes with units (their refusals are in
    /// `refuses_bad_values`).
    #[test]
    fn heavy_limits() {
        let cli = parse(&[
            "--heavy-body-limit",
            "8MiB",
            "--heavy-memory-budget",
            "512MiB",
            "--heavy-concurrency-limit",
            "3",
            "--heavy-request-timeout",
            "2s",
        ])
        .unwrap();
        assert_eq!(
            cli.config.heavy,
            HeavyLimits {
                body_bytes: 8 << 20,
                memory_budget: 512 << 20,
                concurrency_limit: 3,
                request_timeout: Duration::from_secs(2),
                max_image_pixels: DEFAULT_MAX_IMAGE_PIXELS,
                max_streams: DEFAULT_MAX_STREAMS,
                stream_idle_timeout: DEFAULT_STREAM_IDLE_TIMEOUT,
                stream_frame_bytes: DEFAULT_STREAM_FRAME_LIMIT,
            }
        );
        assert_eq!(size::<1, 4096>("2KiB"), Ok(2048));
        assert_eq!(size::<1, 4096>("100"), Ok(100));
    }

    /// `--help` tells what the code does: each default as the code computes it (the heavy
    /// concurrency from this machine's CPUs), the pixel cap as an option, and the fixed caps
    /// with the values the code enforces.
    #[test]
    fn help_matches_the_config() {
        let help = Cli::command().render_long_help().to_string();
        let flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
        let defaults = Config::default();
        for (flag, default) in [
            (
                "--heavy-concurrency-limit <N>",
                defaults.heavy.concurrency_limit.to_string(),
            ),
            (
                "--max-image-pixels <PIXELS>",
                DEFAULT_MAX_IMAGE_PIXELS.to_string(),
            ),
            (
                "--concurrency-limit <CONCURRENCY_LIMIT>",
                DEFAULT_CONCURRENCY_LIMIT.to_string(),
            ),
            (
                "--max-table-rows <ROWS>",
                DEFAULT_MAX_TABLE_ROWS.to_string(),
            ),
            ("--body-limit <SIZE>", "64KiB".to_owned()),
            ("--max-streams <N>", DEFAULT_MAX_STREAMS.to_string()),
            ("--stream-idle-timeout <DURATION>", "60s".to_owned()),
            ("--stream-frame-limit <SIZE>", "16MiB".to_owned()),
        ] {
            let at = flat
                .find(flag)
                .unwrap_or_else(|| panic!("{flag} in --help"));
            let next = flat[at + flag.len()..]
                .find(" --")
                .map_or(flat.len(), |n| at + flag.len() + n);
            let text = &flat[at..next];
            assert!(
                text.contains(&format!("[default: {default}]")),
                "{flag}'s default is {default}: {text}"
            );
        }
        assert_eq!(
            defaults.limits.body_bytes,
            size::<1, 1_000_000>("64KiB").unwrap()
        );
        let cpus = std::thread::available_parallelism().map_or(1, usize::from);
        assert_eq!(defaults.heavy.concurrency_limit, (2 * cpus).max(4));
        assert!(
            flat.contains("default: twice the number of CPUs, at least 4"),
            "{flat}"
        );
        for cap in [
            format!(
                "at most {} pixels a side",
                stereo_core::vision::decode::MAX_SIDE
            ),
            format!(
                "at most {} disparities",
                stereo_core::vision::MAX_DISPARITIES
            ),
            format!(
                "at most {} views",
                stereo_core::calibration::boards::MAX_VIEWS
            ),
        ] {
            assert!(flat.contains(&cap), "--help states the cap: {cap}");
        }
    }

    /// `healthcheck` is a subcommand with its own timeout.
    #[test]
    fn healthcheck_subcommand() {
        let cli = parse(&["--port", "9001", "healthcheck", "--timeout", "1s"]).unwrap();
        assert_eq!(
            cli.command,
            Some(Command::Healthcheck {
                timeout: Duration::from_secs(1)
            })
        );
        assert_eq!(cli.config.port, 9001);
    }

    /// `depth-map` takes two folders or one, and refuses an output /depth-map does not make.
    #[test]
    fn the_depth_map_command_reads_its_folders() {
        let cli = parse(&[
            "depth-map",
            "--left",
            "l",
            "--right",
            "r",
            "--out",
            "o",
            "--preset",
            "fast",
            "--max-disparity-std",
            "0.5",
        ])
        .unwrap();
        let Some(Command::DepthMap(args)) = cli.command else {
            panic!("the depth-map command");
        };
        assert_eq!(
            (
                args.left,
                args.right,
                args.preset.as_deref(),
                args.max_disparity_std
            ),
            (Some("l".into()), Some("r".into()), Some("fast"), Some(0.5))
        );
        assert!(parse(&["depth-map", "--out", "o"]).is_err());
        assert!(parse(&["depth-map", "--left", "l", "--out", "o"]).is_err());
        assert!(
            parse(&[
                "depth-map",
                "--frames",
                "f",
                "--out",
                "o",
                "--output",
                "x.gif"
            ])
            .is_err()
        );
        assert!(
            parse(&[
                "depth-map",
                "--frames",
                "f",
                "--left",
                "l",
                "--right",
                "r",
                "--out",
                "o"
            ])
            .is_err()
        );
    }
}
