//! A multipart form's parts by name, as every image route reads them, with each part as
//! UTF-8 text naming the part when it is not.

use std::collections::BTreeMap;

use axum::body::Bytes;

use crate::api::error::FieldErrors;
use crate::api::wire::images::{RIG_PARTS, RigParts};

/// The parts of a multipart form, by name.
#[derive(Debug, Default)]
pub struct Parts(BTreeMap<String, Bytes>);

impl FromIterator<(String, Bytes)> for Parts {
    /// The parts by name; of two with one name, the last.
    fn from_iter<I: IntoIterator<Item = (String, Bytes)>>(iter: I) -> Self {
        Parts(iter.into_iter().collect())
    }
}

impl Parts {
    /// The parts that describe the rig ([`RigParts`]).
    pub fn rig_parts(&self) -> RigParts {
        let mut input = RigParts::default();
        for name in RIG_PARTS {
            if let Some(bytes) = self.get(name) {
                input.set(name, bytes.clone());
            }
        }
        input
    }

    pub fn get(&self, name: &str) -> Option<&Bytes> {
        self.0.get(name)
    }

    /// The part as UTF-8 text, or an error naming it.
    pub fn text(&self, name: &str, problems: &mut FieldErrors) -> Option<String> {
        crate::api::wire::images::utf8(name, self.get(name)?, problems)
    }
}
