//! What the light group's handlers see: the limits of its JSON requests.

use axum::extract::FromRef;

use crate::api::extract::BodyLimit;
use crate::config::Limits;

/// What the light group's handlers see.
#[derive(Debug, Clone, Copy, Default)]
pub struct AppState {
    pub limits: Limits,
}

impl FromRef<AppState> for BodyLimit {
    fn from_ref(state: &AppState) -> Self {
        BodyLimit(state.limits.body_bytes)
    }
}
