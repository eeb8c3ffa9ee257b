//! Building and running the server: the middleware stack, the HTTP/1.1 accept loop with its
//! header read timeout and its sockets' write timeout, and graceful shutdown (readiness off, optional delay, bounded drain
//! that loses no request a client has sent).

use crate::api::images::maps::{self, MapCache};
use std::{future::Future, io, net::SocketAddr, pin::pin, sync::Arc, time::Duration};

use axum::Router;
use futures_util::FutureExt;
use hyper::server::conn::http1;
use hyper_util::{
    rt::{TokioIo, TokioTimer},
    service::TowerToHyperService,
};
use tokio::{
    net::{TcpListener, TcpStream},
    sync::{Notify, watch},
};
use tower::ServiceBuilder;
use tower_http::{catch_panic::CatchPanicLayer, compression::CompressionLayer};

use crate::{
    api::{
        self, AppState, HeavyState, Routers,
        body_limit::{BodyLimit, LimitOption},
        routes::{
            self,
            ops::{OpsState, Readiness},
        },
    },
    budget::MemoryBudget,
    config::Config,
    observe::telemetry::X_REQUEST_ID,
    web,
};
use axum::http::{HeaderValue, Method, header};
use tower_http::cors::{AllowOrigin, CorsLayer};

use super::auth::{self, Auth};
use super::edge::{self, EdgeLayer, GuardLayer};
use super::io::WriteTimeout;
use super::watch::MinRate;
use crate::budget::Slots;

/// The complete application router for `config`, every layer included. `ops` carries the
/// readiness flag and the metrics registry, shared with whoever runs the server.
pub fn app(config: &Config, ops: OpsState) -> Router {
    app_with(config, ops, Router::new())
}

/// [`app`], with `extra_heavy` mounted in the heavy group, under its limits and memory budget
/// and outside the OpenAPI document: the one seam for tests, reached only through
/// [`Application::build_with`].
///
/// Each route group is wrapped in its own [`crate::server::edge::Guard`]: the light group (the JSON
/// answers, the page, the docs) in the light limits, the heavy group (the image requests) in
/// the heavy limits and the memory budget. The probes are a router of their own, outside both.
/// Then every route, probes included, is wrapped in [`crate::server::edge::Edge`] (request id,
/// in-flight gauge, panic → 500, metrics, access log) → CORS (when configured) → compression,
/// applied in one `Router::layer` call.
fn app_with(config: &Config, ops: OpsState, extra_heavy: Router<HeavyState>) -> Router {
    let (limits, heavy) = (config.limits, config.heavy);
    // What the matcher's buffer pool keeps between requests is held outside the budget's
    // reservations: an eighth of the budget at most, and, with what the allocator keeps free,
    // no more than the reservations leave free.
    let budget = MemoryBudget::with_spare(heavy.memory_budget, &crate::budget::Leftovers);
    // glibc's thresholds as a warm server has them (a no-op under another allocator).
    stereo_core::vision::huge_pages::tune_for_budget(heavy.memory_budget);
    let heavy_state = HeavyState {
        body_limit: BodyLimit {
            bytes: heavy.body_bytes,
            set_by: LimitOption::HeavyBody,
        },
        maps: std::sync::Arc::new(MapCache::new(Some(budget.clone()), maps::MAX_ENTRIES)),
        slots: Slots::new(heavy.concurrency_limit),
        image_limits: api::images::limits::decode_limits(heavy.max_image_pixels),
        streams: api::images::stream::Streams {
            budget: budget.clone(),
            open: Slots::new(heavy.max_streams),
            idle_timeout: heavy.stream_idle_timeout,
            write_timeout: config.write_timeout,
            max_frame_bytes: heavy.stream_frame_bytes,
            pools: Default::default(),
        },
    };
    let ops = OpsState {
        heavy: Some((budget.clone(), heavy_state.slots.clone())),
        ..ops
    };
    let body_rate = MinRate {
        bytes_per_second: config.min_body_rate as u64,
        grace: config.body_rate_grace,
    };
    let Routers {
        light,
        docs,
        heavy: images,
        probes,
    } = api::routers(AppState { limits }, heavy_state.clone(), ops.clone());
    let images = images.merge(extra_heavy.with_state(heavy_state));
    // With tokens, the API routes and /metrics require one (the probes are let through by
    // the middleware itself); the page, its files and the docs stay open.
    let (auth, fault) = Auth::new(
        config.api_tokens.as_ref().map_or(&[][..], |t| &t.0),
        config.api_tokens_file.as_deref(),
    );
    if let Some(fault) = fault {
        tracing::error!(%fault, "no API token could be read: every API request will be refused");
    }
    let (light, images, probes) = match &auth {
        Some(auth) => {
            if config.api_tokens_file.is_some()
                && let Ok(runtime) = tokio::runtime::Handle::try_current()
            {
                runtime.spawn(auth.watch(config.api_tokens_reload));
            }
            let require = || axum::middleware::from_fn_with_state(auth.clone(), auth::require);
            (
                light.route_layer(require()),
                images.route_layer(require()),
                probes.route_layer(require()),
            )
        }
        None => (light, images, probes),
    };
    let light = light
        .merge(docs)
        .merge(web::router())
        .layer(GuardLayer::new(
            config.concurrency_limit,
            config.request_timeout,
            body_rate,
        ));
    // The form extractor's own cap (2 MB by default) raised to the group's body limit; the
    // guard's admission and the form reader enforce that limit. The group's concurrency limit
    // is `heavy_state.slots`, taken by the handlers when their work starts.
    let images = images
        .layer(axum::extract::DefaultBodyLimit::max(heavy.body_bytes))
        .layer(GuardLayer::with_memory(
            heavy.request_timeout,
            body_rate,
            budget,
            heavy.body_bytes,
        ));
    let edge = ServiceBuilder::new()
        .layer(EdgeLayer::new(ops.metrics, config.access_log))
        .layer(CatchPanicLayer::custom(edge::panic_answer))
        .option_layer(cors(&config.cors_allowed_origins))
        .layer(CompressionLayer::new());
    light
        .merge(images)
        .merge(probes)
        .fallback(routes::not_found)
        .method_not_allowed_fallback(routes::method_not_allowed)
        .layer(edge)
}

/// How connections are served and how the server stops.
#[derive(Debug, Clone, Copy)]
struct Serving {
    header_read_timeout: Duration,
    write_timeout: Duration,
    shutdown_delay: Duration,
    shutdown_timeout: Duration,
}

/// A bound, not yet serving, server.
pub struct Application {
    listener: TcpListener,
    router: Router,
    readiness: Readiness,
    serving: Serving,
}

impl Application {
    /// Binds `config.host:config.port` (port 0 picks a free port) and builds the router.
    pub async fn build(config: Config) -> io::Result<Self> {
        Self::build_with(config, Router::new()).await
    }

    /// [`Application::build`], with `extra_heavy` mounted in the heavy group, under its limits
    /// and memory budget and outside the OpenAPI document: the one seam for tests.
    pub async fn build_with(config: Config, extra_heavy: Router<HeavyState>) -> io::Result<Self> {
        let listener = TcpListener::bind((config.host, config.port)).await?;
        let ops = OpsState::default();
        Ok(Self {
            listener,
            readiness: ops.readiness.clone(),
            router: app_with(&config, ops, extra_heavy),
            serving: Serving {
                header_read_timeout: config.header_read_timeout,
                write_timeout: config.write_timeout,
                shutdown_delay: config.shutdown_delay,
                shutdown_timeout: config.shutdown_timeout,
            },
        })
    }

    /// The address actually bound.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// Serves until `shutdown` completes, then stops gracefully: `/readyz` answers 503 at once;
    /// connections are still accepted for the shutdown delay (so a load balancer can notice);
    /// then the listener closes and in-flight requests get up to the shutdown timeout to finish.
    pub async fn run_until(
        self,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> io::Result<()> {
        let Self {
            listener,
            router,
            readiness,
            serving,
        } = self;
        let mut http = http1::Builder::new();
        http.timer(TokioTimer::new())
            .header_read_timeout(serving.header_read_timeout);
        let (stopping, _) = watch::channel(false);
        let server = Server {
            listener,
            router,
            http,
            write_timeout: serving.write_timeout,
            stopping,
        };

        readiness.set(true);
        server.accept_until(shutdown).await;
        readiness.set(false);
        if !serving.shutdown_delay.is_zero() {
            tracing::info!(
                delay_ms = serving.shutdown_delay.as_millis() as u64,
                "shutting down: readiness off, still serving during the delay"
            );
            server
                .accept_until(tokio::time::sleep(serving.shutdown_delay))
                .await;
        }
        let accepted = server.accept_pending();
        let Server {
            listener, stopping, ..
        } = server;
        drop(listener);
        tracing::info!(
            accepted_from_queue = accepted,
            "listener closed: draining in-flight requests"
        );
        stopping.send_replace(true);
        match tokio::time::timeout(serving.shutdown_timeout, stopping.closed()).await {
            Ok(()) => tracing::info!("drained: every in-flight request finished"),
            Err(_) => tracing::warn!(
                timeout_ms = serving.shutdown_timeout.as_millis() as u64,
                "drain timed out: the remaining connections are cut off"
            ),
        }
        Ok(())
    }

    /// Serves until SIGINT (Ctrl-C) or SIGTERM.
    pub async fn run_until_stopped(self) -> io::Result<()> {
        self.run_until(shutdown_signal()).await
    }
}

/// Connections the kernel may queue before they are accepted (tokio's listen backlog).
const ACCEPT_QUEUE: usize = 1024;

/// The listening half of a running server.
struct Server {
    listener: TcpListener,
    router: Router,
    http: http1::Builder,
    /// How long a write may stay blocked by a client that reads nothing.
    write_timeout: Duration,
    /// Turns true when the server stops; every connection task holds a receiver, so
    /// `closed()` on it completes when the last connection is done.
    stopping: watch::Sender<bool>,
}

impl Server {
    /// Accepts and serves connections until `stop` completes.
    async fn accept_until(&self, stop: impl Future<Output = ()>) {
        let mut stop = pin!(stop);
        loop {
            tokio::select! {
                biased;
                () = &mut stop => return,
                accepted = self.listener.accept() => match accepted {
                    Ok((stream, _)) => self.serve(stream),
                    Err(error) => {
                        // Out of file descriptors and the like: back off instead of spinning.
                        tracing::warn!(%error, "accept failed");
                        tokio::time::sleep(Duration::from_millis(50)).await;
                    }
                },
            }
        }
    }

    /// Accepts the connections already waiting in the kernel's queue, which closing the
    /// listener would reset although their clients may have sent a request; returns how many.
    fn accept_pending(&self) -> usize {
        let mut accepted = 0;
        while accepted < ACCEPT_QUEUE {
            match self.listener.accept().now_or_never() {
                Some(Ok((stream, _))) => {
                    self.serve(stream);
                    accepted += 1;
                }
                _ => break,
            }
        }
        accepted
    }

    /// Serves one connection on its own task. When the server stops, a connection that has
    /// begun a request finishes it and closes, and an idle keep-alive connection closes; a
    /// new connection that has not yet sent its first request is given that request first
    /// (within the header read timeout), since its client has no reason to expect a close.
    fn serve(&self, stream: TcpStream) {
        if let Err(error) = stream.set_nodelay(true) {
            tracing::debug!(%error, "cannot set TCP_NODELAY");
        }
        let begun = Arc::new(Notify::new());
        let signal = begun.clone();
        let router = ServiceBuilder::new()
            .map_request(move |request: hyper::Request<hyper::body::Incoming>| {
                signal.notify_one();
                request
            })
            .service(self.router.clone());
        // With upgrades: a depth stream's WebSocket takes the connection over (its socket
        // keeps the write timeout).
        let connection = self
            .http
            .serve_connection(
                TokioIo::new(WriteTimeout::new(stream, self.write_timeout)),
                TowerToHyperService::new(router),
            )
            .with_upgrades();
        let mut stopping = self.stopping.subscribe();
        tokio::spawn(async move {
            let mut connection = pin!(connection);
            let result = tokio::select! {
                result = connection.as_mut() => result,
                () = async {
                    // The guard `wait_for` returns is dropped here: it must not cross an await.
                    let _ = stopping.wait_for(|&stop| stop).await;
                } => {
                    // A request has begun on this connection (a permit is stored), or wait for
                    // the first one.
                    let result = tokio::select! {
                        result = connection.as_mut() => Some(result),
                        () = begun.notified() => None,
                    };
                    match result {
                        Some(result) => result,
                        None => {
                            connection.as_mut().graceful_shutdown();
                            connection.await
                        }
                    }
                }
            };
            if let Err(error) = result {
                tracing::debug!(%error, "connection closed with an error");
            }
            drop(stopping);
        });
    }
}

/// Completes on Ctrl-C, or on SIGTERM where there is one.
pub async fn shutdown_signal() {
    let ctrl_c = async {
        if tokio::signal::ctrl_c().await.is_err() {
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut signal) => {
                signal.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {},
        () = terminate => {},
    }
    tracing::info!("shutdown signal received");
}

/// CORS for `origins` (`*` alone allows any), or `None` when the list is empty: then no CORS
/// headers are sent and browsers keep the same-origin policy.
pub fn cors(origins: &[String]) -> Option<CorsLayer> {
    if origins.is_empty() {
        return None;
    }
    let allow_origin = if origins.iter().any(|o| o == "*") {
        AllowOrigin::any()
    } else {
        AllowOrigin::list(
            origins
                .iter()
                .filter_map(|origin| HeaderValue::from_str(origin).ok()),
        )
    };
    Some(
        CorsLayer::new()
            .allow_origin(allow_origin)
            .allow_methods([Method::GET, Method::POST])
            .allow_headers([
                header::CONTENT_TYPE,
                header::ACCEPT,
                header::AUTHORIZATION,
                X_REQUEST_ID.clone(),
            ])
            .expose_headers([
                X_REQUEST_ID.clone(),
                header::RETRY_AFTER,
                header::WWW_AUTHENTICATE,
                axum::http::HeaderName::from_static(crate::api::images::output::WARNINGS_HEADER),
            ])
            .max_age(Duration::from_secs(3600)),
    )
}
