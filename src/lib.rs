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
//! - [`config`]: settings from the environment, with defaults in code.
//! - [`startup`]: the middleware stack, [`startup::Application`] (binds, may use port 0) and
//!   graceful shutdown.
//!
//! `main.rs` only reads the configuration, sets up logging and runs the application.

pub mod api;
pub mod config;
pub mod physics;
pub mod startup;

pub use config::Config;
pub use startup::{Application, app};
