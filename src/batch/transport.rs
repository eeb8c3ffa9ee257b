//! How a pair reaches a running service (`--server`): HTTP/1.1, one kept-alive connection a
//! job, the `/depth-map` form sent and its answer read.

use axum::body::Bytes;
use axum::http::{Request, header};
use http_body_util::{BodyExt, Full};

/// An answer: its status, its `Retry-After` when it has one, its warnings
/// (`Stereo-Warnings`) and its body.
#[derive(Debug, Clone)]
pub struct Answer {
    pub status: u16,
    pub retry_after: Option<std::time::Duration>,
    pub warnings: Vec<String>,
    pub body: Bytes,
}

/// A running service's address, and this job's connection to it once made (a clone makes
/// its own).
pub struct Server {
    authority: String,
    base: String,
    /// `Authorization`'s value, for a service that takes bearer tokens.
    authorization: Option<String>,
    connection: Option<hyper::client::conn::http1::SendRequest<Full<Bytes>>>,
}

impl Clone for Server {
    fn clone(&self) -> Self {
        Server {
            authority: self.authority.clone(),
            base: self.base.clone(),
            authorization: self.authorization.clone(),
            connection: None,
        }
    }
}

impl Server {
    /// The service at `url` (`http://host:port`, optionally with a path prefix); `https` and
    /// other schemes are refused with a sentence saying so.
    pub fn parse(url: &str) -> Result<Server, String> {
        let rest = url.strip_prefix("http://").ok_or_else(|| {
            format!("--server {url}: give an http:// address (https is not spoken here; use the cluster's own http Service)")
        })?;
        let (authority, path) = rest.split_once('/').unwrap_or((rest, ""));
        if authority.is_empty() {
            return Err(format!("--server {url}: no host"));
        }
        let authority = if authority.contains(':') && !authority.ends_with(']') {
            authority.to_owned()
        } else {
            format!("{authority}:80")
        };
        let base = path.trim_end_matches('/');
        Ok(Server {
            authority,
            base: if base.is_empty() {
                String::new()
            } else {
                format!("/{base}")
            },
            authorization: None,
            connection: None,
        })
    }

    /// The same service, sent `token` as a bearer token with every request.
    pub fn with_token(self, token: Option<String>) -> Server {
        Server {
            authorization: token.map(|t| format!("Bearer {}", t.trim())),
            ..self
        }
    }

    async fn connect(
        &self,
    ) -> Result<hyper::client::conn::http1::SendRequest<Full<Bytes>>, String> {
        let stream = tokio::net::TcpStream::connect(&self.authority)
            .await
            .map_err(|e| format!("cannot connect to {}: {e}", self.authority))?;
        let _ = stream.set_nodelay(true);
        let (sender, connection) =
            hyper::client::conn::http1::handshake(hyper_util::rt::TokioIo::new(stream))
                .await
                .map_err(|e| format!("no HTTP/1.1 at {}: {e}", self.authority))?;
        tokio::spawn(async move {
            let _ = connection.await;
        });
        Ok(sender)
    }
}

impl Server {
    /// POSTs `body` (of `content_type`) to `path_and_query`. An error is the transport's
    /// (no connection, a connection lost twice), not an answer's.
    pub async fn post(
        &mut self,
        path_and_query: &str,
        content_type: &str,
        body: Vec<u8>,
    ) -> Result<Answer, String> {
        let server = self;
        let body = Bytes::from(body);
        // A kept-alive connection the server closed meanwhile is made again, once.
        for attempt in 0..2 {
            let alive = match server.connection.as_mut() {
                Some(sender) => sender.ready().await.is_ok(),
                None => false,
            };
            if !alive {
                server.connection = Some(server.connect().await?);
            }
            let Some(sender) = server.connection.as_mut() else {
                return Err(format!("no connection to {}", server.authority));
            };
            let mut request = Request::post(format!("{}{path_and_query}", server.base))
                .header(header::HOST, server.authority.as_str())
                .header(header::CONTENT_TYPE, content_type);
            if let Some(authorization) = &server.authorization {
                request = request.header(header::AUTHORIZATION, authorization.as_str());
            }
            let request = request.body(Full::new(body.clone())).map_err(|_| {
                "the request was not built (is the token one line of text?)".to_owned()
            })?;
            match sender.send_request(request).await {
                Ok(response) => return Answer::read(response).await,
                Err(error) if attempt == 0 => {
                    tracing::debug!(%error, "the connection was lost; connecting again");
                    server.connection = None;
                }
                Err(error) => {
                    return Err(format!("{} did not answer: {error}", server.authority));
                }
            }
        }
        Err(format!("{} did not answer", server.authority))
    }
}

impl Answer {
    /// A response read to its end.
    async fn read<B>(response: axum::http::Response<B>) -> Result<Answer, String>
    where
        B: http_body::Body,
        B::Error: std::fmt::Display,
    {
        let (parts, body) = response.into_parts();
        let body = body
            .collect()
            .await
            .map_err(|e| format!("the answer was cut off: {e}"))?
            .to_bytes();
        let text = |name| parts.headers.get(name).and_then(|v| v.to_str().ok());
        Ok(Answer {
            status: parts.status.as_u16(),
            retry_after: text(header::RETRY_AFTER.as_str())
                .and_then(|v| super::retry::retry_after(v, std::time::SystemTime::now())),
            warnings: text(crate::api::images::output::WARNINGS_HEADER)
                .and_then(|v| serde_json::from_str(v).ok())
                .unwrap_or_default(),
            body,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An http address with or without a port and a prefix; https refused in words.
    #[test]
    fn server_addresses_are_read() {
        let s = Server::parse("http://depth.default.svc:8080").unwrap();
        assert_eq!(
            (s.authority.as_str(), s.base.as_str()),
            ("depth.default.svc:8080", "")
        );
        let s = Server::parse("http://example/api/").unwrap();
        assert_eq!(
            (s.authority.as_str(), s.base.as_str()),
            ("example:80", "/api")
        );
        let refused = |url: &str| Server::parse(url).err().unwrap_or_default();
        assert!(refused("https://example").contains("http://"));
        assert!(refused("http:///x").contains("no host"));
    }
}
