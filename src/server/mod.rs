//! Serving: the layer above [`crate::api`], which it wraps and runs. Read one way, each using
//! the API and those before it:
//! - [`watch`]: the request body watcher (how much has arrived and whether all of it: the
//!   minimum body rate's 408, and a slow client's 408 against a slow server's 503);
//! - [`answer`]: an image answer on its way out, holding its memory in the budget until sent;
//! - [`auth`]: the optional bearer tokens, required of the API routes and `/metrics`;
//! - [`io`]: the connection's socket with a write timeout, for clients that stop reading;
//! - [`edge`]: the two hand-written layers, `Edge` on every request (request id, in-flight
//!   gauge, metrics, access log; tower-http's `CatchPanic` inside it for panic → 500) and
//!   `Guard` on each route group (shedding, memory admission, the body rate, timeout);
//! - [`startup`]: the route groups wrapped in their guards, the edge stack and CORS,
//!   [`startup::Application`] (binds, may use port 0), the accept loop, graceful shutdown;
//! - [`healthcheck`]: the `healthcheck` subcommand's probe, for images without curl.

pub mod answer;
pub mod auth;
pub mod edge;
pub mod healthcheck;
pub mod io;
pub mod startup;
pub mod watch;
