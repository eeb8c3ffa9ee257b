//! A connection's socket with a write timeout: a write that the peer leaves blocked (it stopped
//! reading, so the kernel's buffers are full) for longer than the timeout fails, which ends the
//! connection and frees the answer it was sending. The socket is then reset rather than closed
//! politely, so that the kernel drops the unsent bytes too.

use std::future::Future;
use std::io;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;
use tokio::time::Sleep;

/// A TCP stream whose writes fail after `timeout` without progress.
pub struct WriteTimeout {
    stream: TcpStream,
    timeout: Duration,
    /// Running while a write is blocked; none while writes make progress.
    blocked: Option<Pin<Box<Sleep>>>,
}

impl WriteTimeout {
    pub fn new(stream: TcpStream, timeout: Duration) -> Self {
        Self {
            stream,
            timeout,
            blocked: None,
        }
    }

    /// Polls a write with `write`, timing how long it stays blocked.
    fn write_with<T>(
        &mut self,
        cx: &mut Context<'_>,
        write: impl FnOnce(Pin<&mut TcpStream>, &mut Context<'_>) -> Poll<io::Result<T>>,
    ) -> Poll<io::Result<T>> {
        match write(Pin::new(&mut self.stream), cx) {
            Poll::Pending => {
                let timeout = self.timeout;
                let timer = self
                    .blocked
                    .get_or_insert_with(|| Box::pin(tokio::time::sleep(timeout)));
                if timer.as_mut().poll(cx).is_pending() {
                    return Poll::Pending;
                }
                // Reset on close: the unsent answer is dropped by the kernel as well.
                let _ = self.stream.set_zero_linger();
                Poll::Ready(Err(io::Error::new(
                    io::ErrorKind::TimedOut,
                    format!(
                        "the client read nothing for {} ms (the write timeout)",
                        timeout.as_millis()
                    ),
                )))
            }
            ready => {
                self.blocked = None;
                ready
            }
        }
    }
}

impl AsyncRead for WriteTimeout {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_read(cx, buf)
    }
}

impl AsyncWrite for WriteTimeout {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        self.write_with(cx, |stream, cx| stream.poll_write(cx, buf))
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        self.write_with(cx, |stream, cx| stream.poll_write_vectored(cx, bufs))
    }

    fn is_write_vectored(&self) -> bool {
        self.stream.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        self.write_with(cx, AsyncWrite::poll_flush)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        self.write_with(cx, AsyncWrite::poll_shutdown)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::AsyncWriteExt;
    use tokio::net::TcpListener;

    /// A peer that reads nothing blocks the writer once the kernel's buffers are full; the
    /// write then fails with `TimedOut`, after the timeout and not before.
    #[tokio::test]
    async fn a_write_blocked_past_the_timeout_fails() {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let peer = TcpStream::connect(listener.local_addr().unwrap())
            .await
            .unwrap();
        let (stream, _) = listener.accept().await.unwrap();
        let timeout = Duration::from_millis(300);
        let mut writer = WriteTimeout::new(stream, timeout);
        let chunk = vec![7u8; 1 << 16];
        let mut written = 0usize;
        let (error, waited) = loop {
            let started = tokio::time::Instant::now();
            match writer.write(&chunk).await {
                Ok(n) => written += n,
                Err(error) => break (error, started.elapsed()),
            }
            assert!(written < 1 << 30, "the writes never blocked");
        };
        assert_eq!(error.kind(), io::ErrorKind::TimedOut);
        assert!(waited >= timeout, "failed after {waited:?}");
        assert!(written > 0, "the kernel took some before blocking");
        drop(peer);
    }
}
