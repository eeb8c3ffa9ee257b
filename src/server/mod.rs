//! Serving: the layer above [`crate::api`], which it wraps and runs. Read one way, each using
//! the API and those before it:
//! - [`watch`]: the request body watcher (a slow client's 408 against a slow server's 503);
//! - [`edge`]: the two hand-written layers, `Edge` on every request (request id, in-flight
//!   gauge, metrics, access log; tower-http's `CatchPanic` inside it for panic → 500) and
//!   `Guard` on each route group (shedding, timeout, memory admission);
//! - [`startup`]: the route groups wrapped in their guards, the edge stack and CORS,
//!   [`startup::Application`] (binds, may use port 0), the accept loop, graceful shutdown;
//! - [`healthcheck`]: the `healthcheck` subcommand's probe, for images without curl.

pub mod edge;
pub mod healthcheck;
pub mod startup;
pub mod watch;
