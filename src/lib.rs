//! Stereo distance service, over HTTP and JSON: checkerboard pairs into a calibration (or a
//! calibration file into the rig), raw pairs into rectified ones, pairs into disparities,
//! depths and matches, and a correspondence into a distance with its expected error.
//!
//! Two kinds of work, kept apart from the router down:
//! - **light**: JSON answers that take microseconds of CPU and kilobytes of memory (`/distance`,
//!   `/table`, `/chart-data`, `/rig`, …, the page at `/`);
//! - **heavy**: image requests that take megabytes in, milliseconds to seconds of CPU and tens
//!   of MB of memory each (`/depth-map`, `/match`, `/calibrate`, `/rectify`).
//!
//! Each is a route group with its own body limit, timeout and concurrency limit (the heavy
//! group's taken when a request's work starts, not while its body arrives); the heavy group
//! also shares a memory budget, which holds each answer until it is sent. Every body must
//! arrive at a minimum rate, every answer be read within a write timeout. The probes are a
//! third router that no limit touches.
//!
//! Layout. The engine is the workspace's `stereo-core` crate (`crates/stereo-core`): physics,
//! cameras, calibration, the matcher, with no HTTP, serde or async in its dependencies; its
//! `lib.rs` maps it. This crate sits below it, each layer using only those above it
//! (`tests/layout.rs` holds the code to it):
//! - [`config`]: flags and environment variables (clap) for both groups, defaults, start-up
//!   checks.
//! - [`budget`]: what the heavy requests in flight share: the memory budget (bodies, work and
//!   answers not yet sent, with the matcher's pools and the allocator's free memory giving way
//!   to it) and the compute slots taken when work starts.
//! - [`observe`]: logs, request ids and the access log; Prometheus metrics.
//! - [`api`]: the HTTP layer, read one way: [`api::error`] ← [`api::extract`] ←
//!   [`api::wire`] ← [`api::validate`] ← [`api::images`] ← [`api::routes`]. The routes map
//!   the pure constructors' faults onto field names and nothing more, and never import one
//!   another: what two routes share lives below them. [`api::images`] holds what every
//!   image route shares (the form and its `ImagePair` extractor, the rig from a part, raw
//!   pairs rectified and the row check, file answers and `Server-Timing`, the limits, the
//!   blocking work); [`api::wire`] the wire types they share (the rig, `RectifyMode`,
//!   `StageTimes`).
//! - [`web`]: the calculator page at `/`, a client of the API, its assets embedded
//!   (`src/web/`).
//! - [`server`]: the route groups wrapped in their guards, the edge layers, the accept loop
//!   and graceful shutdown, the health-check probe.
//! - [`batch`]: the `depth-map` command: a recording's folder of pairs to depth maps, through
//!   the engine's pipeline in process or over HTTP to a running service, resumable, with a
//!   progress bar; its settings checked before the first frame, a restarting service waited
//!   for, broken frames named and skipped, the service's warnings printed once.
//! - Outside this crate, in the workspace: `crates/conformance` (dev only), what the service
//!   promises for any input, checked in process: the oracle of the fuzz target and of
//!   `tests/hostile_input.rs`.
//!
//! `main.rs` only parses the command line and runs the server, the probe or the command.

pub mod api;
pub mod batch;
pub mod budget;
pub mod config;
pub mod observe;
pub mod server;
pub mod web;

pub use config::Config;
pub use server::startup::{Application, app};
