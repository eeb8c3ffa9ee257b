//! What the light group's handlers see: the limits of its JSON requests.

use axum::extract::FromRef;

use crate::api::body_limit::{BodyLimit, LimitOption};
use crate::config::Limits;

/// What the light group's handlers see.
#[derive(Debug, Clone, Copy, Default)]
pub struct AppState {
    pub limits: Limits,
}

impl FromRef<AppState> for BodyLimit {
    fn from_ref(state: &AppState) -> Self {
        BodyLimit {
            bytes: state.limits.body_bytes,
            set_by: LimitOption::Body,
        }
    }
}
