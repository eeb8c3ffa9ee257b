//! ROS 2 messages written to an MCAP file as `ros2 bag record` writes them (profile `ros2`,
//! CDR messages, `ros2msg` schemas), which Foxglove, `ros2 bag play`, `rosbags` and
//! `mcap-ros2-support` read. Chunks are zstd-compressed and closed often, so that a run that
//! stops leaves every chunk before the last readable.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use mcap::records::MessageHeader;

use crate::bag::BagError;
use crate::msg::{self, Type};

/// An MCAP file being written.
pub struct McapOut {
    writer: mcap::Writer<BufWriter<File>>,
    schemas: HashMap<&'static str, u16>,
    channels: HashMap<String, u16>,
    sequence: u32,
    path: String,
}

impl McapOut {
    /// A new file at `path` (replacing one there).
    pub fn create(path: &Path) -> Result<McapOut, BagError> {
        let shown = path.display().to_string();
        let file =
            File::create(path).map_err(|e| BagError(format!("cannot write {shown}: {e}")))?;
        let options = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("stereo-distance ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Zstd))
            .chunk_size(Some(4 << 20));
        let writer = options
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(|e| BagError(format!("cannot write {shown}: {e}")))?;
        Ok(McapOut {
            writer,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            sequence: 0,
            path: shown,
        })
    }

    fn fault(&self, e: impl std::fmt::Display) -> BagError {
        BagError(format!("cannot write {}: {e}", self.path))
    }

    /// The channel of `topic` carrying `t`, added on first use.
    fn channel(&mut self, topic: &str, t: Type) -> Result<u16, BagError> {
        if let Some(&id) = self.channels.get(topic) {
            return Ok(id);
        }
        let name = t.ros1_name();
        let schema = match self.schemas.get(name) {
            Some(&id) => id,
            None => {
                let id = self
                    .writer
                    .add_schema(&t.ros2_name(), "ros2msg", msg::schema(t).as_bytes())
                    .map_err(|e| self.fault(e))?;
                self.schemas.insert(name, id);
                id
            }
        };
        let mut metadata = BTreeMap::new();
        metadata.insert("offered_qos_profiles".to_owned(), String::new());
        let id = self
            .writer
            .add_channel(schema, topic, "cdr", &metadata)
            .map_err(|e| self.fault(e))?;
        self.channels.insert(topic.to_owned(), id);
        Ok(id)
    }

    /// A CDR message of type `t` on `topic`, logged at `time_ns`.
    pub fn write(
        &mut self,
        topic: &str,
        t: Type,
        time_ns: u64,
        cdr: &[u8],
    ) -> Result<(), BagError> {
        let channel_id = self.channel(topic, t)?;
        self.sequence = self.sequence.wrapping_add(1);
        let header = MessageHeader {
            channel_id,
            sequence: self.sequence,
            log_time: time_ns,
            publish_time: time_ns,
        };
        self.writer
            .write_to_known_channel(&header, cdr)
            .map_err(|e| self.fault(e))
    }

    /// Closes the current chunk, so that what was written reads even if the run stops.
    pub fn flush(&mut self) -> Result<(), BagError> {
        self.writer.flush().map_err(|e| self.fault(e))
    }

    /// The file's summary and end written.
    pub fn finish(mut self) -> Result<(), BagError> {
        self.writer.finish().map_err(|e| self.fault(e))?;
        Ok(())
    }
}
