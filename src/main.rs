//! Entry point: read the configuration, set up logging, serve until SIGINT or SIGTERM.

use std::process::ExitCode;

use stereo_distance::{Application, Config};
use tracing_subscriber::EnvFilter;

#[tokio::main]
async fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info")),
        )
        .init();
    let config = match Config::from_env() {
        Ok(config) => config,
        Err(error) => {
            eprintln!("error: {error}");
            return ExitCode::FAILURE;
        }
    };
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
        Ok(addr) => tracing::info!("serving on http://{addr} (API docs at http://{addr}/docs)"),
        Err(error) => tracing::warn!(%error, "serving, but the bound address is unknown"),
    }
    match application.run_until_stopped().await {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: server failed: {error}");
            ExitCode::FAILURE
        }
    }
}
