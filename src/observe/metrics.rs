//! Prometheus metrics: request counts and latency histograms by method, route and status, the
//! number of requests in flight, and the image requests' memory budget and compute slots in
//! use, kept in a registry owned by each application instance and fed by
//! [`crate::server::edge`] (and, for the image gauges, read when `/metrics` is asked).

use axum::http::Method;
use prometheus::{
    Encoder, HistogramOpts, HistogramVec, IntCounterVec, IntGauge, Opts, Registry, TextEncoder,
};

/// Latency buckets in seconds: from 50 µs (a warm /distance) to 10 s (past any timeout).
const LATENCY_BUCKETS: &[f64] = &[
    0.000_05, 0.000_1, 0.000_25, 0.000_5, 0.001, 0.002_5, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5,
    1.0, 2.5, 5.0, 10.0,
];

/// The service's metrics and the registry that renders them.
#[derive(Clone)]
pub struct Metrics {
    registry: Registry,
    requests: IntCounterVec,
    latency: HistogramVec,
    in_flight: IntGauge,
    heavy: HeavyGauges,
}

/// The image requests' shared resources, as gauges.
#[derive(Clone)]
struct HeavyGauges {
    reserved: IntGauge,
    budget: IntGauge,
    working: IntGauge,
}

impl std::fmt::Debug for Metrics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Metrics").finish_non_exhaustive()
    }
}

impl Default for Metrics {
    fn default() -> Self {
        Self::new()
    }
}

impl Metrics {
    /// A fresh registry with the service's metrics, all at zero.
    pub fn new() -> Self {
        // The names, labels and buckets are constants checked by the unit test below, so
        // building and registering them cannot fail at run time.
        const CHECKED: &str = "static metric definitions are valid";
        let labels = &["method", "route", "status"];
        let registry = Registry::new();
        let requests = IntCounterVec::new(
            Opts::new("http_requests_total", "HTTP requests answered"),
            labels,
        )
        .expect(CHECKED);
        let latency = HistogramVec::new(
            HistogramOpts::new(
                "http_request_duration_seconds",
                "Time from request received to response headers ready",
            )
            .buckets(LATENCY_BUCKETS.to_vec()),
            labels,
        )
        .expect(CHECKED);
        let in_flight =
            IntGauge::new("http_requests_in_flight", "HTTP requests being served").expect(CHECKED);
        registry
            .register(Box::new(requests.clone()))
            .expect(CHECKED);
        registry.register(Box::new(latency.clone())).expect(CHECKED);
        registry
            .register(Box::new(in_flight.clone()))
            .expect(CHECKED);
        let gauge = |name: &str, help: &str| {
            let gauge = IntGauge::new(name, help).expect(CHECKED);
            registry.register(Box::new(gauge.clone())).expect(CHECKED);
            gauge
        };
        let heavy = HeavyGauges {
            reserved: gauge(
                "heavy_memory_reserved_bytes",
                "Memory the image requests hold in the budget: bodies, work, unsent answers",
            ),
            budget: gauge(
                "heavy_memory_budget_bytes",
                "The image requests' memory budget",
            ),
            working: gauge(
                "heavy_requests_working",
                "Image requests holding a compute slot (working, not uploading)",
            ),
        };
        Self {
            registry,
            requests,
            latency,
            in_flight,
            heavy,
        }
    }

    /// Sets the image requests' gauges: bytes reserved of the `budget`, and requests working.
    pub fn set_heavy(&self, reserved: usize, budget: usize, working: usize) {
        let int = |n: usize| i64::try_from(n).unwrap_or(i64::MAX);
        self.heavy.reserved.set(int(reserved));
        self.heavy.budget.set(int(budget));
        self.heavy.working.set(int(working));
    }

    /// Every metric in the Prometheus text exposition format (version 0.0.4).
    pub fn render(&self) -> Result<String, String> {
        let mut buffer = Vec::new();
        TextEncoder::new()
            .encode(&self.registry.gather(), &mut buffer)
            .map_err(|error| error.to_string())?;
        String::from_utf8(buffer).map_err(|error| error.to_string())
    }

    /// Counts one answered request and its latency.
    pub fn observe(&self, method: &str, route: &str, status: &str, seconds: f64) {
        let labels = [method, route, status];
        self.requests.with_label_values(&labels).inc();
        self.latency.with_label_values(&labels).observe(seconds);
    }

    /// The gauge of requests being served.
    pub fn in_flight(&self) -> &IntGauge {
        &self.in_flight
    }
}

/// The content type of [`Metrics::render`]'s output.
pub const TEXT_FORMAT: &str = "text/plain; version=0.0.4; charset=utf-8";

/// Keeps the in-flight gauge right even when a request is cancelled mid-way.
pub struct InFlight(IntGauge);

impl InFlight {
    /// Counts a request in until the guard is dropped.
    pub fn enter(gauge: &IntGauge) -> Self {
        gauge.inc();
        Self(gauge.clone())
    }
}

impl Drop for InFlight {
    fn drop(&mut self) {
        self.0.dec();
    }
}

/// A method label from a bounded set, so that odd methods cannot blow up the label space.
pub fn method_label(method: &Method) -> &'static str {
    match *method {
        Method::GET => "GET",
        Method::POST => "POST",
        Method::HEAD => "HEAD",
        Method::OPTIONS => "OPTIONS",
        Method::PUT => "PUT",
        Method::DELETE => "DELETE",
        Method::PATCH => "PATCH",
        _ => "OTHER",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definitions register, and an observation shows up in the text format.
    #[test]
    fn renders_observations() {
        let metrics = Metrics::new();
        metrics.observe("GET", "/distance", "200", 0.000_2);
        let text = metrics.render().unwrap();
        assert!(
            text.contains(
                "http_requests_total{method=\"GET\",route=\"/distance\",status=\"200\"} 1"
            )
        );
        assert!(text.contains(
            "http_request_duration_seconds_bucket{method=\"GET\",route=\"/distance\",\
             status=\"200\",le=\"0.00025\"} 1"
        ));
        assert!(text.contains("http_requests_in_flight 0"));
        metrics.set_heavy(3 << 20, 1 << 30, 2);
        let text = metrics.render().unwrap();
        assert!(
            text.contains("heavy_memory_reserved_bytes 3145728"),
            "{text}"
        );
        assert!(text.contains("heavy_memory_budget_bytes 1073741824"));
        assert!(text.contains("heavy_requests_working 2"));
    }
}
