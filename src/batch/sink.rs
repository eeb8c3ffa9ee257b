//! Where a run's maps go: a folder, one file a pair written under a temporary name and
//! renamed when whole (so a stopped run resumes by skipping what is there), or an MCAP file
//! of ROS 2 messages ([`crate::api::images::ros`]), its chunks closed as the pairs come so
//! that a run that stops leaves what it wrote readable.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use stereo_core::pipeline::DepthMap;
use stereo_ros::Kind;
use stereo_ros::msg::Header;
use stereo_ros::out::McapOut;

use crate::api::images::ros;

/// Where the maps go.
pub enum Sink {
    Folder {
        out: PathBuf,
        extension: String,
    },
    Mcap {
        file: Mutex<Ordered>,
        path: PathBuf,
        namespace: String,
    },
}

/// An MCAP file written in the run's order: a pair's messages wait here until every pair
/// before it is written or failed (at most the pairs in flight).
pub struct Ordered {
    out: Option<Box<McapOut>>,
    next: usize,
    pending: BTreeMap<usize, Option<Encoded>>,
}

/// A pair's messages, stamped: their header and each topic's CDR bytes.
type Encoded = (Header, Vec<Vec<u8>>);

impl Ordered {
    /// The file at `path`, made.
    pub fn create(path: &Path) -> Result<Ordered, String> {
        Ok(Ordered {
            out: Some(Box::new(McapOut::create(path).map_err(|e| e.0)?)),
            next: 0,
            pending: BTreeMap::new(),
        })
    }
}

/// Whether `path` names an MCAP file (`.mcap`).
pub fn is_mcap(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
}

impl Sink {
    /// Where a pair's file goes, for a folder.
    pub fn target(&self, name: &str) -> Option<PathBuf> {
        match self {
            Sink::Folder { out, extension } => Some(out.join(format!("{name}.{extension}"))),
            Sink::Mcap { .. } => None,
        }
    }

    /// Where the maps go, for the summary.
    pub fn place(&self) -> &Path {
        match self {
            Sink::Folder { out, .. } => out,
            Sink::Mcap { path, .. } => path,
        }
    }

    /// A pair's file, under a temporary name renamed when whole.
    pub async fn file(&self, name: &str, bytes: &[u8]) -> Result<(), String> {
        let Sink::Folder { out, extension } = self else {
            return Err("an MCAP output takes ROS messages, not files".to_owned());
        };
        let target = out.join(format!("{name}.{extension}"));
        let partial = out.join(format!(".{name}.{extension}.partial"));
        let written = async {
            tokio::fs::write(&partial, bytes).await?;
            tokio::fs::rename(&partial, &target).await
        };
        written
            .await
            .map_err(|e| format!("cannot write {}: {e}", target.display()))
    }

    /// The pair `seq`'s ROS messages (its map, stamped with `header`; `None` for a pair that
    /// failed), each on its topic under the namespace, written once every pair before it is
    /// (nothing for a folder).
    pub fn messages(&self, seq: usize, map: Option<(&DepthMap, &Header)>) -> Result<(), String> {
        let Sink::Mcap {
            file, namespace, ..
        } = self
        else {
            return Ok(());
        };
        let encoded = match map {
            Some((map, header)) => Some((header.clone(), ros::messages(map, header, Kind::Cdr)?)),
            None => None,
        };
        let mut guard = file.lock().unwrap_or_else(|e| e.into_inner());
        let file = &mut *guard;
        file.pending.insert(seq, encoded);
        while let Some(ready) = file.pending.remove(&file.next) {
            file.next += 1;
            let (Some((header, messages)), Some(out)) = (ready, file.out.as_mut()) else {
                continue;
            };
            let time = u64::try_from(header.stamp_ns).unwrap_or(0);
            for (topic, cdr) in ros::Topic::ALL.into_iter().zip(&messages) {
                let name = format!("{}/{}", namespace.trim_end_matches('/'), topic.name());
                out.write(&name, topic.message_type(), time, cdr)
                    .map_err(|e| e.0)?;
            }
            out.flush().map_err(|e| e.0)?;
        }
        Ok(())
    }

    /// The MCAP file's summary and end written (nothing for a folder).
    pub fn close(&self) -> Result<(), String> {
        if let Sink::Mcap { file, .. } = self {
            let taken = file.lock().unwrap_or_else(|e| e.into_inner()).out.take();
            if let Some(out) = taken {
                out.finish().map_err(|e| e.0)?;
            }
        }
        Ok(())
    }
}
