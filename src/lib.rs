//! Stereo distance service: turns a stereo correspondence into a distance with its expected
//! error, and a calibration file into the rig, over HTTP and JSON; and, next, rectified image
//! pairs into correspondences and depth.
//!
//! Two kinds of work, kept apart from the router down:
//! - **light**: JSON answers that take microseconds of CPU and kilobytes of memory (`/distance`,
//!   `/table`, `/chart-data`, `/rig`, …, the page at `/`);
//! - **heavy**: image requests that take megabytes in, milliseconds to seconds of CPU and tens
//!   of MB of memory each.
//!
//! Each is a route group with its own body limit, timeout and concurrency limit; the heavy group
//! also shares a memory budget. The probes are a third router that no limit touches.
//!
//! Layout:
//! - Pure code, no HTTP or serde in any signature:
//!   - [`physics`]: the triangulation model: focal conversions, `Z = B·f_px / |d + doffs|`,
//!     depth error, 3D point and range, sweeps for tables and charts.
//!   - [`calibration`]: Middlebury, KITTI, ROS and OpenCV calibration files read into a rig.
//!   - [`numbers`]: numbers and text echoed into messages, short and exact.
//!   - [`vision`]: image matching (from a rectified pair to disparities); the heavy group's
//!     engine.
//! - [`api`]: the HTTP layer, read one way: [`api::error`] ← [`api::extract`] ←
//!   [`api::wire`] ← [`api::validate`] ← [`api::routes`] (one module per resource, each with
//!   its types and `router()`, merged into the light and heavy groups and the probes).
//! - [`web`]: the calculator page at `/`, a client of the API, its assets embedded
//!   (`src/web/`).
//! - Serving:
//!   - [`config`]: flags and environment variables (clap) for both groups, defaults, start-up
//!     checks.
//!   - [`startup`]: the route groups wrapped in their limits, [`startup::Application`] (binds,
//!     may use port 0), the accept loop, graceful shutdown.
//!   - [`edge`]: the two hand-written layers: `Edge` on every request (request id, metrics,
//!     access log; tower-http's `CatchPanic` inside it for panic → 500), `Guard` on each route
//!     group (shedding, timeout, memory admission).
//!   - [`budget`]: the memory budget shared by the heavy requests in flight.
//!   - [`protect`]: the body watcher behind 408 vs 503, `Retry-After`, CORS.
//!   - [`telemetry`], [`metrics`]: logs, request ids and the access log; Prometheus metrics.
//!   - [`healthcheck`]: the `healthcheck` subcommand's probe, for images without curl.
//! - Outside this crate, in the workspace: `crates/conformance` (dev only), what the service
//!   promises for any input, checked in process: the oracle of the fuzz target and of
//!   `tests/hostile_input.rs`.
//!
//! `main.rs` only parses the command line and runs the server or the probe.

pub mod api;
pub mod budget;
pub mod calibration;
pub mod config;
pub mod numbers;
pub mod observe;
pub mod physics;
pub mod server;
pub mod vision;
pub mod web;

pub use config::Config;
pub use server::startup::{Application, app};
