//! The largest body a route accepts ([`BodyLimit`]), the server option that sets it, and what
//! a 413 says when a body is past it: the limit, the option that raises it, and how to send
//! less.

use stereo_core::numbers::short;

/// The largest body a route accepts, in bytes, and the option that sets it. It is the one
/// body-limit mechanism: each route group's state provides it (`FromRef`), and every extractor
/// that reads a body reads it within this limit, so the 413 names the limit that applied, the
/// option that raises it, and how to send less.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BodyLimit {
    pub bytes: usize,
    pub set_by: LimitOption,
}

/// The server option that sets a body limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LimitOption {
    /// `--body-limit`: the light group's JSON and text bodies.
    Body,
    /// `--batch-body-limit`: `POST /distance`, which takes batches.
    BatchBody,
    /// `--heavy-body-limit`: the image routes' forms.
    HeavyBody,
}

impl LimitOption {
    /// The option's flag and environment variable.
    pub fn names(self) -> (&'static str, &'static str) {
        match self {
            LimitOption::Body => ("--body-limit", "BODY_LIMIT"),
            LimitOption::BatchBody => ("--batch-body-limit", "BATCH_BODY_LIMIT"),
            LimitOption::HeavyBody => ("--heavy-body-limit", "HEAVY_BODY_LIMIT"),
        }
    }

    /// How a client sends less than the limit, where there is a way.
    pub fn advice(self) -> Option<&'static str> {
        match self {
            LimitOption::Body => None,
            LimitOption::BatchBody => Some("send the batch in smaller batches"),
            LimitOption::HeavyBody => Some(
                "send the images as JPEG (quality 90 is about a tenth of a PNG's size) or \
                 smaller",
            ),
        }
    }
}

impl BodyLimit {
    /// What a 413 says of a body past this limit: its detail, and the `body` member's message.
    /// Both name the limit and the option that raises it; the message also says how to send
    /// less, where there is a way.
    pub fn refusal(self) -> (String, String) {
        let (flag, env) = self.set_by.names();
        let bytes = self.bytes;
        let human = if bytes < 1024 * 1024 {
            format!("{} KiB", short(bytes as f64 / 1024.0))
        } else {
            format!("{} MiB", short(bytes as f64 / (1024.0 * 1024.0)))
        };
        let detail = format!(
            "the request body is larger than this server's limit of {human} ({bytes} bytes: \
             {flag}, {env})"
        );
        let instead = self
            .set_by
            .advice()
            .map_or_else(String::new, |advice| format!("{advice}, or "));
        let message = format!(
            "must be at most {human} ({bytes} bytes): {instead}start the server with a larger \
             {flag}"
        );
        (detail, message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The options a 413 names are the server's own: each flag is an argument of its command
    /// line, read from that environment variable.
    #[test]
    fn a_limits_option_is_the_servers() {
        let command = <crate::config::Cli as clap::CommandFactory>::command();
        for option in [
            LimitOption::Body,
            LimitOption::BatchBody,
            LimitOption::HeavyBody,
        ] {
            let (flag, env) = option.names();
            let arg = command
                .get_arguments()
                .find(|a| a.get_long() == flag.strip_prefix("--"))
                .unwrap_or_else(|| panic!("{flag} is an option"));
            assert_eq!(arg.get_env().and_then(|e| e.to_str()), Some(env), "{flag}");
        }
    }

    /// A 413 names the limit in people's units and in bytes, the option and its variable, and
    /// for the image forms how to send less.
    #[test]
    fn a_refusal_names_the_limit_the_option_and_what_to_send() {
        let (detail, message) = BodyLimit {
            bytes: 65536,
            set_by: LimitOption::Body,
        }
        .refusal();
        assert_eq!(
            detail,
            "the request body is larger than this server's limit of 64 KiB (65536 bytes: \
             --body-limit, BODY_LIMIT)"
        );
        assert_eq!(
            message,
            "must be at most 64 KiB (65536 bytes): start the server with a larger --body-limit"
        );
        let (_, message) = BodyLimit {
            bytes: 32 << 20,
            set_by: LimitOption::HeavyBody,
        }
        .refusal();
        assert!(
            message.starts_with("must be at most 32 MiB (33554432 bytes): send the images as JPEG"),
            "{message}"
        );
    }
}
