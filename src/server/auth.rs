//! Optional bearer tokens (RFC 6750). Given tokens (`--api-tokens-file`, `API_TOKENS`), the
//! service takes a request to an API route or to `/metrics` only with `Authorization: Bearer`
//! and one of them; the probes, the page and its files, `/docs` and `/openapi.json` stay open.
//! A browser cannot set `Authorization` on a WebSocket, so the upgrade of `/depth-stream` may
//! carry its token as a `Sec-WebSocket-Protocol` entry instead, `bearer.` and the token in
//! base64url (as Kubernetes' API server takes it), offered beside the stream's own protocol
//! `depth-stream`, which the server selects. Several tokens are accepted at once, so that a new one can be handed out before the old
//! one is withdrawn; the file is read again when it changes (a Kubernetes Secret rotated in
//! place), and a file that no longer reads keeps the tokens it had.
//!
//! Tokens are held only as SHA-256 digests. A presented token is hashed and compared with
//! every digest, each comparison over all 32 bytes, so the time taken says neither how much
//! of a token matched nor which token did; no token is logged, and `Debug` shows a count.

use std::path::{Path, PathBuf};
use std::sync::{Arc, RwLock, Weak};
use std::time::Duration;

use axum::extract::{Request, State};
use axum::http::header;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};

use crate::api::error::ApiError;
use crate::api::wire::openapi::OPEN_PROBES;
use crate::config::tokens::{read_tokens_file, tokens_of_file};

type Digested = [u8; 32];

fn digest(token: &[u8]) -> Digested {
    Sha256::digest(token).into()
}

/// The tokens the service accepts.
pub struct Tokens {
    /// From `API_TOKENS`.
    fixed: Vec<Digested>,
    /// The file's, read again when it changes.
    file: Option<PathBuf>,
    from_file: RwLock<(Vec<Digested>, Vec<u8>)>,
}

/// The accepted tokens, shared by the routes and the file's watcher.
#[derive(Clone)]
pub struct Auth(Arc<Tokens>);

impl Auth {
    /// The tokens of `fixed` and of the file at `file`; `None` when neither is given (the
    /// service then trusts its network). A file that cannot be read leaves only `fixed`, and
    /// with none of them every request is refused (`Err` says why, to log).
    pub fn new(fixed: &[String], file: Option<&Path>) -> (Option<Auth>, Option<String>) {
        if fixed.is_empty() && file.is_none() {
            return (None, None);
        }
        let (from_file, fault) = match file {
            Some(path) => match read(path) {
                Ok(read) => (read, None),
                Err(e) => ((Vec::new(), Vec::new()), Some(e)),
            },
            None => ((Vec::new(), Vec::new()), None),
        };
        let tokens = Tokens {
            fixed: digests(fixed),
            file: file.map(Path::to_path_buf),
            from_file: RwLock::new(from_file),
        };
        (Some(Auth(Arc::new(tokens))), fault)
    }

    /// Whether `presented` is one of the tokens: compared with each in constant time, all
    /// of them always.
    pub fn admits(&self, presented: &str) -> bool {
        let given = digest(presented.as_bytes());
        let same = |known: &Digested| {
            known
                .iter()
                .zip(given.iter())
                .fold(0u8, |acc, (a, b)| acc | (a ^ b))
                == 0
        };
        let mut found = false;
        for known in &self.0.fixed {
            found |= same(known);
        }
        if let Ok(read) = self.0.from_file.read() {
            for known in &read.0 {
                found |= same(known);
            }
        }
        found
    }

    /// Reads the tokens file again if its bytes changed: `Ok(Some(n))` with the count of its
    /// new tokens, `Ok(None)` when unchanged; a file that no longer reads keeps the old ones.
    pub fn reload(&self) -> Result<Option<usize>, String> {
        let Some(path) = &self.0.file else {
            return Ok(None);
        };
        let bytes =
            std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        if self.0.from_file.read().is_ok_and(|r| r.1 == bytes) {
            return Ok(None);
        }
        let digests = digests(&tokens_of_file(&bytes, path)?);
        let count = digests.len();
        if let Ok(mut held) = self.0.from_file.write() {
            *held = (digests, bytes);
        }
        Ok(Some(count))
    }

    /// Reads the file again `every` so often, logging what changed (a count, never a
    /// token), until the service drops its tokens.
    pub fn watch(&self, every: Duration) -> impl std::future::Future<Output = ()> + Send + 'static {
        let weak: Weak<Tokens> = Arc::downgrade(&self.0);
        async move {
            loop {
                tokio::time::sleep(every).await;
                let Some(tokens) = weak.upgrade() else { break };
                match Auth(tokens).reload() {
                    Ok(Some(count)) => tracing::info!(tokens = count, "API tokens file read again"),
                    Ok(None) => {}
                    Err(error) => {
                        tracing::warn!(%error, "the API tokens file did not read: the tokens before stay")
                    }
                }
            }
        }
    }
}

/// The file's digests and bytes.
fn read(path: &Path) -> Result<(Vec<Digested>, Vec<u8>), String> {
    let (tokens, bytes) = read_tokens_file(path)?;
    Ok((digests(&tokens), bytes))
}

fn digests(tokens: &[String]) -> Vec<Digested> {
    tokens.iter().map(|t| digest(t.as_bytes())).collect()
}

/// The middleware: a request without a token is 401 with `WWW-Authenticate: Bearer`, one
/// with a token not accepted 401 with `error="invalid_token"`; the probes pass.
pub async fn require(State(auth): State<Auth>, request: Request, next: Next) -> Response {
    if OPEN_PROBES.contains(&request.uri().path()) {
        return next.run(request).await;
    }
    let headers = request.headers();
    let presented = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| {
            let (scheme, token) = v.trim().split_once(' ')?;
            scheme
                .eq_ignore_ascii_case("bearer")
                .then(|| token.trim().to_owned())
        })
        .or_else(|| protocol_token(headers.get_all(header::SEC_WEBSOCKET_PROTOCOL)));
    match presented {
        Some(token) if auth.admits(&token) => next.run(request).await,
        Some(_) => ApiError::Unauthorized { refused: true }.into_response(),
        None => ApiError::Unauthorized { refused: false }.into_response(),
    }
}

/// The prefix of a token carried in `Sec-WebSocket-Protocol`.
pub const PROTOCOL_PREFIX: &str = "bearer.";

/// The token of a `Sec-WebSocket-Protocol` entry `bearer.<base64url>` (unpadded, as a
/// protocol name cannot hold `=`), among the comma-separated protocols the client offers. An
/// entry that does not decode to UTF-8 is presented as itself, and so refused.
fn protocol_token(values: header::GetAll<'_, header::HeaderValue>) -> Option<String> {
    use base64::Engine as _;
    use base64::engine::general_purpose::URL_SAFE_NO_PAD;
    values
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .find_map(|entry| entry.trim().strip_prefix(PROTOCOL_PREFIX))
        .map(|encoded| {
            URL_SAFE_NO_PAD
                .decode(encoded.trim_end_matches('='))
                .ok()
                .and_then(|bytes| String::from_utf8(bytes).ok())
                .unwrap_or_else(|| encoded.to_owned())
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A token in a `Sec-WebSocket-Protocol` entry is read from base64url among the other
    /// protocols offered, in one header or several; without the entry there is none.
    #[test]
    fn a_websocket_protocol_entry_carries_a_token() {
        use base64::Engine as _;
        let encoded = base64::engine::general_purpose::URL_SAFE_NO_PAD.encode(B);
        let mut headers = header::HeaderMap::new();
        let offered = format!("depth-stream, bearer.{encoded}");
        headers.insert(header::SEC_WEBSOCKET_PROTOCOL, offered.parse().unwrap());
        let read = protocol_token(headers.get_all(header::SEC_WEBSOCKET_PROTOCOL));
        assert_eq!(read.as_deref(), Some(B));
        let mut two = header::HeaderMap::new();
        two.append(
            header::SEC_WEBSOCKET_PROTOCOL,
            "depth-stream".parse().unwrap(),
        );
        two.append(
            header::SEC_WEBSOCKET_PROTOCOL,
            format!("bearer.{encoded}").parse().unwrap(),
        );
        let read = protocol_token(two.get_all(header::SEC_WEBSOCKET_PROTOCOL));
        assert_eq!(read.as_deref(), Some(B));
        let mut none = header::HeaderMap::new();
        none.insert(
            header::SEC_WEBSOCKET_PROTOCOL,
            "depth-stream".parse().unwrap(),
        );
        assert_eq!(
            protocol_token(none.get_all(header::SEC_WEBSOCKET_PROTOCOL)),
            None
        );
    }

    const A: &str = "alpha-token-0123456789";
    const B: &str = "bravo/token+0123456789==";

    /// Each token given is accepted and nothing else is: not a prefix, not a longer one, not
    /// the empty string; a file rotated in place is read again, and one that stops reading
    /// keeps its tokens.
    #[test]
    fn only_given_tokens_are_admitted_and_the_file_rotates() {
        let dir = std::env::temp_dir().join(format!("auth-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("tokens");
        std::fs::write(&file, format!("{B}\n")).unwrap();
        let (auth, fault) = Auth::new(&[A.to_owned()], Some(&file));
        let auth = auth.unwrap();
        assert_eq!(fault, None);
        assert!(auth.admits(A) && auth.admits(B));
        for wrong in ["", &A[..A.len() - 1], &format!("{A}x"), "bearer"] {
            assert!(!auth.admits(wrong), "{wrong}");
        }
        assert_eq!(auth.reload(), Ok(None));
        let c = "charlie-token-0123456789";
        std::fs::write(&file, format!("{c}\n")).unwrap();
        assert_eq!(auth.reload(), Ok(Some(1)));
        assert!(auth.admits(c) && !auth.admits(B) && auth.admits(A));
        std::fs::write(&file, "tiny\n").unwrap();
        assert!(auth.reload().is_err());
        assert!(auth.admits(c));
        let (none, _) = Auth::new(&[], None);
        assert!(none.is_none());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
