//! An image request's answer on its way to the client, still counted in the memory budget: the
//! request's reservation is settled to the answer's size and dropped only with the answer's
//! body, and the body is handed to the connection in copied chunks of [`CHUNK`] bytes, so that
//! what the connection still holds once the body is done is a few chunks, never a slice that
//! keeps the whole answer alive outside the budget.

use std::pin::Pin;
use std::task::{Context, Poll};

use axum::body::{Body, Bytes};
use axum::response::Response;
use http_body::{Body as _, Frame, SizeHint};

use crate::budget::Reservation;

/// The largest piece of an answer handed to the connection at once. hyper queues at most
/// about 400 KiB of them before it waits for the socket.
pub const CHUNK: usize = 64 * 1024;

/// `response`, its body holding `reservation` (settled to the body's size when the request
/// holds it alone, that is when no abandoned work still runs with it) until the body is
/// dropped: sent to the end, or its connection closed.
pub fn held(response: Response, reservation: Reservation) -> Response {
    if let Some(bytes) = response.body().size_hint().exact() {
        reservation.settle_alone(usize::try_from(bytes).unwrap_or(usize::MAX));
    }
    response.map(|body| {
        Body::new(Held {
            inner: body,
            rest: Bytes::new(),
            _reservation: reservation,
        })
    })
}

/// A response body that holds its answer's reservation and yields the answer in copied chunks.
struct Held {
    inner: Body,
    /// What is left of the frame being handed out.
    rest: Bytes,
    _reservation: Reservation,
}

impl http_body::Body for Held {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, axum::Error>>> {
        if self.rest.is_empty() {
            match Pin::new(&mut self.inner).poll_frame(cx) {
                Poll::Ready(Some(Ok(frame))) => match frame.into_data() {
                    Ok(data) => self.rest = data,
                    Err(frame) => return Poll::Ready(Some(Ok(frame))),
                },
                other => return other,
            }
        }
        let n = self.rest.len().min(CHUNK);
        let chunk = Bytes::copy_from_slice(&self.rest[..n]);
        self.rest = if n == self.rest.len() {
            Bytes::new()
        } else {
            self.rest.slice(n..)
        };
        Poll::Ready(Some(Ok(Frame::data(chunk))))
    }

    fn is_end_stream(&self) -> bool {
        self.rest.is_empty() && self.inner.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        let mut hint = self.inner.size_hint();
        let rest = self.rest.len() as u64;
        hint.set_lower(hint.lower() + rest);
        if let Some(upper) = hint.upper() {
            hint.set_upper(upper + rest);
        }
        hint
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::budget::MemoryBudget;
    use http_body_util::BodyExt;

    /// The answer comes out whole, in chunks of at most [`CHUNK`] bytes, its size announced
    /// up front; the reservation is settled to the answer's size and given back only once the
    /// body is dropped.
    #[tokio::test]
    async fn the_answer_is_held_until_its_body_is_dropped() {
        let budget = MemoryBudget::new(1 << 20);
        let reservation = budget.reserve(900_000).unwrap();
        let answer: Vec<u8> = (0..200_000u32).map(|i| (i % 251) as u8).collect();
        let response = held(Response::new(Body::from(answer.clone())), reservation);
        assert_eq!(budget.used(), 200_000, "settled to the answer's size");
        let mut body = response.into_body();
        assert_eq!(body.size_hint().exact(), Some(200_000));
        let mut received = Vec::new();
        let mut chunks = 0;
        while let Some(frame) = body.frame().await {
            let data = frame.unwrap().into_data().unwrap();
            assert!(data.len() <= CHUNK);
            received.extend_from_slice(&data);
            chunks += 1;
        }
        assert_eq!(received, answer);
        assert_eq!(chunks, 4);
        assert_eq!(budget.used(), 200_000, "held while the body lives");
        drop(body);
        assert_eq!(budget.used(), 0);
    }

    /// While abandoned work still holds a clone, the reservation is not settled: that work's
    /// memory stays counted.
    #[test]
    fn a_shared_reservation_is_left_as_it_is() {
        let budget = MemoryBudget::new(1 << 20);
        let reservation = budget.reserve(500_000).unwrap();
        let work = reservation.clone();
        let response = held(Response::new(Body::from("late")), reservation);
        assert_eq!(budget.used(), 500_000);
        drop(response);
        assert_eq!(budget.used(), 500_000, "the work still holds it");
        drop(work);
        assert_eq!(budget.used(), 0);
    }
}
