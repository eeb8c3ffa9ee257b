//! `GET /depth-stream`: a WebSocket that turns a stereo camera's frames into depth maps as
//! they come. The first message holds the settings (answered with them as resolved, or with
//! a problem and a close); then each binary frame is answered in order with its id, stage
//! times, summary and the files asked for, a bad frame with an error while the stream goes
//! on. The newest frame waits and older ones are dropped; answers a client has not read are
//! dropped, and a client that reads nothing is closed after the write timeout. The messages
//! are described in `openapi/asyncapi.yaml`; the work between socket and engine is
//! [`crate::api::images::stream`]'s.

mod session;

pub use crate::api::wire::depth_stream as types;

use axum::extract::State;
use axum::extract::ws::WebSocketUpgrade;
use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use axum::response::Response;
use axum::routing::get;
use utoipa_axum::router::OpenApiRouter;

use crate::api::error::ApiError;
use crate::api::images::HeavyState;

/// The stream's WebSocket subprotocol, selected when the client offers it.
pub const PROTOCOL: &str = "depth-stream";

/// `GET /depth-stream`, documented by the AsyncAPI file rather than the OpenAPI one.
pub fn router() -> OpenApiRouter<HeavyState> {
    OpenApiRouter::new().route("/depth-stream", get(open))
}

/// Opens a stream: one of `--max-streams` taken and its frame limit reserved in the heavy
/// budget (503 with `Retry-After` when either is used up), then the socket upgraded with
/// that frame limit. A request without the upgrade gets 426.
pub async fn open(
    State(state): State<HeavyState>,
    upgrade: Result<WebSocketUpgrade, WebSocketUpgradeRejection>,
) -> Result<Response, ApiError> {
    let upgrade = upgrade.map_err(|r| ApiError::UpgradeRequired(r.body_text()))?;
    let streams = &state.streams;
    let slot = streams.open.take().ok_or(ApiError::TooManyStreams {
        limit: streams.open.limit(),
    })?;
    let held = streams
        .budget
        .reserve(streams.max_frame_bytes)
        .map_err(ApiError::Memory)?;
    let max = streams.max_frame_bytes;
    // A browser offers `depth-stream` beside its token's entry (`bearer.…`, read by the
    // auth middleware), and closes a socket whose server selects none of its protocols.
    Ok(upgrade
        .protocols([PROTOCOL])
        .max_message_size(max)
        .max_frame_size(max)
        .on_upgrade(move |socket| session::run(socket, state, (slot, held))))
}
