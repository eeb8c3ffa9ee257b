//! Where a run's maps go: a folder, one file a pair written under a temporary name and
//! renamed when whole (so a stopped run resumes by skipping what is there), or an MCAP file
//! of ROS 2 messages ([`crate::api::images::ros`]), its chunks closed as the pairs come so
//! that a run that stops leaves what it wrote readable.

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
        file: Mutex<Option<Box<McapOut>>>,
        path: PathBuf,
        namespace: String,
    },
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

    /// A pair's ROS messages, stamped with `header`, each on its topic under the namespace.
    pub fn messages(&self, map: &DepthMap, header: &Header) -> Result<(), String> {
        let Sink::Mcap {
            file, namespace, ..
        } = self
        else {
            return Err("a folder takes files, not ROS messages".to_owned());
        };
        let messages = ros::messages(map, header, Kind::Cdr)?;
        let mut file = file.lock().unwrap_or_else(|e| e.into_inner());
        let Some(out) = file.as_mut() else {
            return Err("the MCAP file was closed".to_owned());
        };
        let time = u64::try_from(header.stamp_ns).unwrap_or(0);
        for ((topic, t), cdr) in ros::TOPICS.iter().zip(&messages) {
            let topic = format!("{}/{topic}", namespace.trim_end_matches('/'));
            out.write(&topic, *t, time, cdr).map_err(|e| e.0)?;
        }
        out.flush().map_err(|e| e.0)
    }

    /// The MCAP file's summary and end written (nothing for a folder).
    pub fn close(&self) -> Result<(), String> {
        if let Sink::Mcap { file, .. } = self {
            let taken = file.lock().unwrap_or_else(|e| e.into_inner()).take();
            if let Some(out) = taken {
                out.finish().map_err(|e| e.0)?;
            }
        }
        Ok(())
    }
}
