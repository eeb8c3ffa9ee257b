//! Stereo distance service, over HTTP and JSON: checkerboard pairs into a calibration (or a
//! calibration file into the rig), raw pairs into rectified ones, pairs into disparities,
//! depths and matches, and a correspondence into a distance with its expected error.
//!
//! Two kinds of work, kept apart from the router down:
//! - **light**: JSON answers that take microseconds of CPU and kilobytes of memory (`/distance`,
//!   `/table`, `/chart-data`, `/rig`, …, the page at `/`);
//! - **heavy**: image requests that take megabytes in, milliseconds to seconds of CPU and tens
//!   of MB of memory each (`/depth-map`, `/match`, `/calibrate`, `/rectify`), and the live
//!   streams of `/depth-stream` (a WebSocket), a frame at a time.
//!
//! Each is a route group with its own body limit, timeout and concurrency limit (the heavy
//! group's taken when a request's work starts, not while its body arrives); the heavy group
//! also shares a memory budget, which holds each answer until it is sent. Every body must
//! arrive at a minimum rate, every answer be read within a write timeout. The probes are a
//! third router that no limit touches.
//!
//! Layout. The engine is the workspace's `stereo-core` crate (`crates/stereo-core`): physics,
//! cameras, calibration, the matcher and `pipeline`, its use cases as plain functions, with no
//! HTTP, serde or async in its dependencies; its `lib.rs` maps it. This crate translates:
//! requests into the engine's types, one engine call, its answers and faults into JSON, files
//! and problem+json. It sits below the engine, each layer using only those above it
//! (`tests/layout.rs` holds the code to it, and to the routes' budget):
//! - [`config`]: flags and environment variables (clap) for both groups, defaults, start-up
//!   checks.
//! - [`budget`]: what the heavy requests in flight share: the memory budget (bodies, work and
//!   answers not yet sent, with the matcher's pools and the allocator's free memory giving way
//!   to it) and the compute slots taken when work starts.
//! - [`observe`]: logs, request ids and the access log; Prometheus metrics.
//! - [`api`]: the HTTP layer, read one way: [`api::error`] ← [`api::extract`] ←
//!   [`api::wire`] ← [`api::validate`] ← [`api::images`] ← [`api::routes`].
//!   - [`api::wire`]: every request and answer as the JSON and the OpenAPI document see them,
//!     one module a route (`wire::depth_map`, …) beside what they share, with their
//!     translation from the engine's types (`DepthMapSummary::of`, `MatchResponse::of`).
//!   - [`api::validate`]: the caller's members into the engine's checking constructors.
//!   - [`api::images`]: what every image route shares: the form and its `ImagePair`
//!     extractor, the rig or calibration from its parts, the engine's rectify plan asked and
//!     its refusals named by part, the rectification maps' cache, file answers,
//!     `Server-Timing` and `Stereo-Warnings`, the limits and the blocking work
//!     ([`api::HeavyState`] is theirs).
//!   - [`api::routes`]: the handlers. Each translates: its wire types to the engine's, one
//!     call ([`stereo_core::pipeline`] for the image routes, [`stereo_core::physics`] for the
//!     light ones), the engine's faults to problem+json. None computes geometry, depths or
//!     statistics, and none imports another.
//! - [`web`]: the calculator page at `/`, a client of the API, its assets embedded
//!   (`src/web/`).
//! - [`server`]: the route groups wrapped in their guards, the edge layers, the accept loop
//!   and graceful shutdown, the health-check probe.
//! - [`batch`]: the `depth-map` command: a recording's folder of pairs, or a ROS bag (through
//!   the workspace's `stereo-ros` crate), to depth maps or ROS 2 messages, through
//!   the engine's pipeline in process (`batch::engine`: the calibration resolved once a frame
//!   size) or over HTTP to a running service, resumable, with a
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
