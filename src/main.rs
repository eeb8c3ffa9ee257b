//! Entry point: parse the command line, then either serve until SIGINT/SIGTERM, run the
//! `healthcheck` probe, or the `depth-map` command over a recording.

use std::process::ExitCode;

use stereo_distance::{
    Application,
    config::{Cli, Command},
    observe::telemetry,
    server::healthcheck,
};

fn main() -> ExitCode {
    let cli = match Cli::try_parse_args(std::env::args_os()) {
        Ok(cli) => cli,
        Err(error) => error.exit(),
    };
    let config = cli.config;
    match cli.command.unwrap_or(Command::Serve) {
        Command::Healthcheck { timeout } => {
            match healthcheck::probe(healthcheck::target(config.host, config.port), timeout) {
                Ok(()) => ExitCode::SUCCESS,
                Err(error) => {
                    eprintln!("unhealthy: {error}");
                    ExitCode::FAILURE
                }
            }
        }
        Command::DepthMap(args) => stereo_distance::batch::run(config, *args),
        Command::Serve => {
            if let Err(error) = telemetry::init(config.log_format, &config.log_level) {
                eprintln!("error: cannot set up logging: {error}");
                return ExitCode::FAILURE;
            }
            let runtime = match tokio::runtime::Runtime::new() {
                Ok(runtime) => runtime,
                Err(error) => {
                    eprintln!("error: cannot start the async runtime: {error}");
                    return ExitCode::FAILURE;
                }
            };
            runtime.block_on(serve(config))
        }
    }
}

async fn serve(config: stereo_distance::Config) -> ExitCode {
    let application = match Application::build(config.clone()).await {
        Ok(application) => application,
        Err(error) => {
            eprintln!(
                "error: cannot listen on {}:{}: {error}",
                config.host, config.port
            );
            return ExitCode::FAILURE;
        }
    };
    match application.local_addr() {
        Ok(addr) => tracing::info!(
            concurrency_limit = config.concurrency_limit,
            request_timeout_ms = config.request_timeout.as_millis() as u64,
            body_limit = config.limits.body_bytes,
            cors_origins = config.cors_allowed_origins.len(),
            "serving on http://{addr} (API docs at http://{addr}/docs)"
        ),
        Err(error) => tracing::warn!(%error, "serving, but the bound address is unknown"),
    }
    match application.run_until_stopped().await {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            tracing::error!(%error, "server failed");
            ExitCode::FAILURE
        }
    }
}
