//! The `healthcheck` subcommand: a tiny HTTP/1.1 client that asks the running server for
//! `/healthz`, for container HEALTHCHECKs on an image that has no curl.

use std::{
    io::{Read, Write},
    net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr, TcpStream},
    time::Duration,
};

/// Where to probe a server configured to listen on `host:port`: an unspecified address
/// (0.0.0.0 or ::) is probed on the matching loopback address.
pub fn target(host: IpAddr, port: u16) -> SocketAddr {
    let ip = match host {
        IpAddr::V4(ip) if ip.is_unspecified() => IpAddr::V4(Ipv4Addr::LOCALHOST),
        IpAddr::V6(ip) if ip.is_unspecified() => IpAddr::V6(Ipv6Addr::LOCALHOST),
        ip => ip,
    };
    SocketAddr::new(ip, port)
}

/// GETs `/healthz` from `address`; `Ok` when the answer is 200, otherwise what went wrong.
pub fn probe(address: SocketAddr, timeout: Duration) -> Result<(), String> {
    let fail = |what: &str, error: std::io::Error| format!("{what} {address}: {error}");
    let mut stream =
        TcpStream::connect_timeout(&address, timeout).map_err(|e| fail("cannot connect to", e))?;
    stream
        .set_read_timeout(Some(timeout))
        .and_then(|()| stream.set_write_timeout(Some(timeout)))
        .map_err(|e| fail("cannot set timeouts for", e))?;
    stream
        .write_all(b"GET /healthz HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n")
        .map_err(|e| fail("cannot send to", e))?;
    let mut head = [0u8; 64];
    let mut filled = 0;
    while filled < 12 {
        match stream.read(&mut head[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(error) => return Err(fail("no answer from", error)),
        }
    }
    let status_line = String::from_utf8_lossy(&head[..filled]);
    let status_line = status_line.lines().next().unwrap_or_default();
    if status_line.starts_with("HTTP/1.1 200") {
        Ok(())
    } else {
        Err(format!(
            "{address}/healthz answered {status_line:?}, not 200"
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An unspecified listen address is probed on loopback; a specific one as it is.
    #[test]
    fn probes_loopback_for_unspecified_hosts() {
        assert_eq!(
            target("0.0.0.0".parse().unwrap(), 8080).to_string(),
            "127.0.0.1:8080"
        );
        assert_eq!(target("::".parse().unwrap(), 80).to_string(), "[::1]:80");
        assert_eq!(
            target("10.0.0.7".parse().unwrap(), 9).to_string(),
            "10.0.0.7:9"
        );
    }

    /// Nothing listening is a failure that names the address.
    #[test]
    fn refused_connection_fails() {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let address = listener.local_addr().unwrap();
        drop(listener);
        let error = probe(address, Duration::from_secs(1)).unwrap_err();
        assert!(error.contains(&address.to_string()), "{error}");
    }
}
