//! Stereo distance service: turns a stereo correspondence into a distance with its expected
//! error, over HTTP and JSON.
//!
//! Layout:
//! - [`physics`]: the pure triangulation model (no HTTP, no serde): focal conversions,
//!   `Z = B·f_px / |d + doffs|`, depth error, 3D point, sweeps for tables and charts.
//! - [`api`]: the HTTP layer, kept thin: route → extract ([`api::extract`]) → validate
//!   ([`api::validate`]) → physics → response ([`api::types`]); one error type
//!   ([`api::error::ApiError`]) rendered as `application/problem+json`; the OpenAPI document
//!   derived from the same types.
//!   [`api::ops`] holds the probes and `/metrics`.
//! - [`config`]: flags and environment variables (clap), defaults in code, start-up checks.
//! - [`telemetry`]: logging setup, `x-request-id`, the access log line.
//! - [`metrics`]: Prometheus request counts, latency histograms and in-flight gauge.
//! - [`edge`]: the two hand-written layers every request passes through (request id, metrics,
//!   access log, panic → 500; load shedding, request timeout, body limit).
//! - [`protect`]: the pieces `edge` uses for timeouts and shedding, and CORS.
//! - [`startup`]: the middleware stack, [`startup::Application`] (binds, may use port 0), the
//!   accept loop with its header read timeout, and graceful shutdown with readiness drain.
//! - [`healthcheck`]: the `healthcheck` subcommand's probe, for images without curl.
//! - [`web`]: the calculator page at `/`, a client of the API, its assets embedded in the binary
//!   (`src/web/`).
//! - [`conformance`]: what the service promises for any input, checked in process; the oracle
//!   of the fuzz target (`fuzz/`) and of the random-input test.
//!
//! `main.rs` only parses the command line and runs the server or the probe.

pub mod api;
pub mod config;
pub mod conformance;
pub mod edge;
pub mod healthcheck;
pub mod metrics;
pub mod physics;
pub mod protect;
pub mod startup;
pub mod telemetry;
pub mod web;

pub use config::Config;
pub use startup::{Application, app};
