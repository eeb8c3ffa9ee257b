//! What is seen of the service while it runs, used by every layer (the API stamps its problems
//! with the request id; the edge counts and logs each request): [`telemetry`] (the tracing
//! subscriber, request ids, the access log line) and [`metrics`] (the Prometheus registry).
//! It uses nothing of the API or the server.

pub mod metrics;
pub mod telemetry;
