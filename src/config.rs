//! Server settings: where to listen and the limits that protect it, read from the environment
//! with defaults in code.

use std::{fmt, net::IpAddr};

/// Default request body limit: 64 KiB, far more than any request of this API needs.
pub const DEFAULT_BODY_LIMIT: usize = 64 * 1024;
/// Default cap on `/table` rows (`steps`).
pub const DEFAULT_MAX_TABLE_ROWS: usize = 10_000;
/// Default cap on `/chart-data` points per series.
pub const DEFAULT_MAX_CHART_POINTS: usize = 10_000;

/// Everything the server needs to start.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Config {
    /// Address to bind (`HOST`, default 127.0.0.1).
    pub host: IpAddr,
    /// Port to bind (`PORT`, default 8080; 0 picks a free one).
    pub port: u16,
    /// The limits the API enforces.
    pub limits: Limits,
}

/// Caps on what one request may ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest accepted request body, in bytes.
    pub body_bytes: usize,
    /// Most rows one `/table` answer may have.
    pub table_rows: usize,
    /// Most points one `/chart-data` series may have.
    pub chart_points: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            body_bytes: DEFAULT_BODY_LIMIT,
            table_rows: DEFAULT_MAX_TABLE_ROWS,
            chart_points: DEFAULT_MAX_CHART_POINTS,
        }
    }
}

impl Default for Config {
    fn default() -> Self {
        Self {
            host: IpAddr::from([127, 0, 0, 1]),
            port: 8080,
            limits: Limits::default(),
        }
    }
}

/// A setting that could not be used, with the variable it came from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigError {
    pub variable: &'static str,
    pub value: String,
    pub expected: &'static str,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}={:?} is not valid: expected {}",
            self.variable, self.value, self.expected
        )
    }
}

impl std::error::Error for ConfigError {}

impl Config {
    /// Reads `HOST` and `PORT`; unset variables keep their defaults.
    pub fn from_env() -> Result<Self, ConfigError> {
        Self::from_lookup(|name| std::env::var(name).ok())
    }

    /// Like [`Config::from_env`], with the variables looked up by `lookup`.
    pub fn from_lookup(lookup: impl Fn(&str) -> Option<String>) -> Result<Self, ConfigError> {
        let mut config = Config::default();
        if let Some(value) = lookup("HOST") {
            config.host = value.parse().map_err(|_| ConfigError {
                variable: "HOST",
                value,
                expected: "an IP address such as 127.0.0.1 or 0.0.0.0",
            })?;
        }
        if let Some(value) = lookup("PORT") {
            config.port = value.parse().map_err(|_| ConfigError {
                variable: "PORT",
                value,
                expected: "a port number from 0 to 65535",
            })?;
        }
        Ok(config)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unset variables give the documented defaults.
    #[test]
    fn defaults() {
        let config = Config::from_lookup(|_| None).unwrap();
        assert_eq!(config.host.to_string(), "127.0.0.1");
        assert_eq!(config.port, 8080);
        assert_eq!(config.limits.body_bytes, 65_536);
    }

    /// HOST and PORT are read, and a bad value names its variable.
    #[test]
    fn reads_and_rejects() {
        let config = Config::from_lookup(|name| match name {
            "HOST" => Some("0.0.0.0".into()),
            "PORT" => Some("9000".into()),
            _ => None,
        })
        .unwrap();
        assert_eq!(
            (config.host.to_string().as_str(), config.port),
            ("0.0.0.0", 9000)
        );
        let err =
            Config::from_lookup(|name| (name == "PORT").then(|| "eighty".into())).unwrap_err();
        assert_eq!(err.variable, "PORT");
        assert!(err.to_string().contains("eighty"));
    }
}
