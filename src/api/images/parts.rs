//! A multipart form's parts by name, as every image route reads them, with each part as
//! UTF-8 text naming the part when it is not.

use std::collections::BTreeMap;

use axum::body::Bytes;

use crate::api::error::FieldErrors;

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
    pub fn get(&self, name: &str) -> Option<&Bytes> {
        self.0.get(name)
    }

    /// The part as UTF-8 text, or an error naming it.
    pub fn text(&self, name: &str, problems: &mut FieldErrors) -> Option<String> {
        let bytes = self.get(name)?;
        match std::str::from_utf8(bytes) {
            Ok(text) => Some(text.to_owned()),
            Err(e) => {
                problems.add(
                    name,
                    format!("must be UTF-8 text; byte {} is not", e.valid_up_to()),
                );
                None
            }
        }
    }
}
