//! A recording's messages, one at a time and in the order they were recorded, from a ROS 2
//! MCAP file, a rosbag2 folder (its `metadata.yaml` beside one or more `.mcap` files) or a
//! ROS 1 `.bag` (v2.0; chunks stored plain or lz4). Nothing holds more than one record (a
//! ROS 1 chunk, an MCAP chunk's decompressed records) at a time, and no record longer than
//! the reader's limit is allocated.

use std::collections::{BTreeSet, HashMap, VecDeque};
use std::fmt;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use mcap::records::{Record, op};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

use crate::ros1;
use crate::wire::Kind;

/// Why a recording, or a part of it, could not be read: a sentence naming the file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagError(pub String);

impl fmt::Display for BagError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BagError {}

/// One recorded message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Message {
    pub topic: String,
    /// Its type as the recording names it (`sensor_msgs/msg/Image`, `sensor_msgs/Image`).
    pub type_name: String,
    pub kind: Kind,
    /// When it was recorded, in nanoseconds since the epoch.
    pub log_time_ns: u64,
    pub data: Vec<u8>,
}

/// What kind of recording a path is.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Source {
    /// MCAP files, read one after the other.
    Mcap(Vec<PathBuf>),
    Ros1(PathBuf),
}

/// A recording, opened.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bag {
    source: Source,
    path: PathBuf,
}

impl Bag {
    /// The recording at `path`: a `.mcap` file, a rosbag2 folder, or a ROS 1 `.bag` (told
    /// apart by their first bytes, not their names).
    pub fn open(path: &Path) -> Result<Bag, BagError> {
        let shown = path.display();
        if path.is_dir() {
            return rosbag2_folder(path).map(|files| Bag {
                source: Source::Mcap(files),
                path: path.to_owned(),
            });
        }
        let mut start = [0u8; 13];
        let read = File::open(path)
            .and_then(|mut f| {
                let mut n = 0;
                while n < start.len() {
                    let got = f.read(&mut start[n..])?;
                    if got == 0 {
                        break;
                    }
                    n += got;
                }
                Ok(n)
            })
            .map_err(|e| BagError(format!("cannot read the recording {shown}: {e}")))?;
        let source = if start[..read].starts_with(mcap::MAGIC) {
            Source::Mcap(vec![path.to_owned()])
        } else if start[..read].starts_with(ros1::MAGIC) {
            Source::Ros1(path.to_owned())
        } else if start[..read].starts_with(b"SQLite format 3") {
            return Err(BagError(format!(
                "{shown} is a rosbag2 SQLite file (.db3); this reads MCAP: convert it with \
                 `ros2 bag convert` to storage_id mcap"
            )));
        } else if start[..read].starts_with(b"#ROSBAG V1") {
            return Err(BagError(format!(
                "{shown} is a ROS 1 bag of format 1.2, which is not read: `rosbag fix` or \
                 `rosbag reindex` writes it as 2.0"
            )));
        } else {
            return Err(BagError(format!(
                "{shown} is neither an MCAP file, a rosbag2 folder nor a ROS 1 bag (its first \
                 bytes are none of theirs)"
            )));
        };
        Ok(Bag {
            source,
            path: path.to_owned(),
        })
    }

    /// The path it was opened at.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What kind of recording it is, in words.
    pub fn kind(&self) -> &'static str {
        match self.source {
            Source::Mcap(_) => "ROS 2 MCAP",
            Source::Ros1(_) => "ROS 1 bag",
        }
    }

    /// Its messages on `topics` (all, when `None`), in the order recorded, none longer than
    /// `limit` bytes.
    pub fn messages(&self, topics: Option<BTreeSet<String>>, limit: usize) -> Messages {
        let inner = match &self.source {
            Source::Mcap(files) => Inner::Mcap(Box::new(McapMessages {
                files: files.iter().cloned().collect(),
                current: None,
                channels: HashMap::new(),
                schemas: HashMap::new(),
                limit,
            })),
            Source::Ros1(path) => Inner::Ros1(ros1::Messages::new(path, limit)),
        };
        Messages {
            inner,
            topics,
            done: false,
            count: 0,
        }
    }
}

/// The recordings of a folder that is not itself one (it has no `metadata.yaml`): its `.mcap`
/// and `.bag` files and its rosbag2 folders, by name; `None` for a recording.
pub fn recordings(path: &Path) -> Result<Option<Vec<PathBuf>>, BagError> {
    if !path.is_dir() || path.join("metadata.yaml").is_file() {
        return Ok(None);
    }
    let mut found: Vec<PathBuf> = std::fs::read_dir(path)
        .map_err(|e| BagError(format!("cannot read the folder {}: {e}", path.display())))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.join("metadata.yaml").is_file()
                || p.extension().is_some_and(|e| e == "mcap" || e == "bag")
        })
        .collect();
    found.sort();
    Ok(Some(found))
}

/// The MCAP files of a rosbag2 folder, in the order its `metadata.yaml` lists them (else by
/// name).
fn rosbag2_folder(folder: &Path) -> Result<Vec<PathBuf>, BagError> {
    let shown = folder.display();
    let metadata = std::fs::read_to_string(folder.join("metadata.yaml")).ok();
    let listed: Vec<PathBuf> = metadata
        .iter()
        .flat_map(|text| text.lines())
        .filter_map(|line| {
            let item = line
                .trim()
                .strip_prefix("- ")?
                .trim()
                .trim_matches(['"', '\'']);
            item.ends_with(".mcap").then(|| folder.join(item))
        })
        .collect::<BTreeSet<_>>()
        .into_iter()
        .filter(|p| p.is_file())
        .collect();
    if !listed.is_empty() {
        return Ok(listed);
    }
    let mut found: Vec<PathBuf> = std::fs::read_dir(folder)
        .map_err(|e| BagError(format!("cannot read the folder {shown}: {e}")))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
        .collect();
    found.sort();
    if !found.is_empty() {
        return Ok(found);
    }
    let sqlite = metadata.is_some_and(|m| m.contains("sqlite3"));
    Err(BagError(if sqlite {
        format!(
            "{shown} is a rosbag2 folder stored in SQLite (.db3); this reads MCAP: convert it \
             with `ros2 bag convert` to storage_id mcap"
        )
    } else {
        format!("{shown} has no .mcap file: give a rosbag2 folder, an .mcap file or a ROS 1 .bag")
    }))
}

/// A recording's messages, in order; after the first error, none.
pub struct Messages {
    inner: Inner,
    topics: Option<BTreeSet<String>>,
    done: bool,
    count: usize,
}

enum Inner {
    Mcap(Box<McapMessages>),
    Ros1(ros1::Messages),
}

impl Messages {
    /// How many messages (on the topics asked for) were read.
    pub fn count(&self) -> usize {
        self.count
    }
}

impl Iterator for Messages {
    type Item = Result<Message, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let wanted = |topic: &str| self.topics.as_ref().is_none_or(|t| t.contains(topic));
        let next = match &mut self.inner {
            Inner::Mcap(m) => m.next(&wanted),
            Inner::Ros1(m) => m.next(&wanted),
        };
        match &next {
            None | Some(Err(_)) => self.done = true,
            Some(Ok(_)) => self.count += 1,
        }
        next.map(|r| {
            r.map_err(|e| {
                BagError(format!(
                    "{e}{}",
                    if self.count > 0 {
                        format!(" (after {} messages read)", self.count)
                    } else {
                        String::new()
                    }
                ))
            })
        })
    }
}

/// A channel of an MCAP file: its topic, type and encoding.
struct Channel {
    topic: String,
    schema: u16,
    encoding: String,
}

struct McapMessages {
    files: VecDeque<PathBuf>,
    current: Option<(PathBuf, BufReader<File>, LinearReader)>,
    channels: HashMap<u16, Channel>,
    schemas: HashMap<u16, String>,
    limit: usize,
}

impl McapMessages {
    fn next(&mut self, wanted: &dyn Fn(&str) -> bool) -> Option<Result<Message, BagError>> {
        loop {
            if self.current.is_none() {
                let path = self.files.pop_front()?;
                let file = match File::open(&path) {
                    Ok(file) => file,
                    Err(e) => {
                        return Some(Err(BagError(format!(
                            "cannot read {}: {e}",
                            path.display()
                        ))));
                    }
                };
                let options = LinearReaderOptions::default()
                    .with_record_length_limit(self.limit)
                    .with_validate_chunk_crcs(true);
                self.channels.clear();
                self.schemas.clear();
                self.current = Some((
                    path,
                    BufReader::with_capacity(1 << 20, file),
                    LinearReader::new_with_options(options),
                ));
            }
            let (path, file, reader) = self.current.as_mut()?;
            let shown = path.display().to_string();
            let fault = |what: String| Some(Err(BagError(format!("{shown}: {what}"))));
            match reader.next_event() {
                None => {
                    self.current = None;
                }
                Some(Err(mcap::McapError::UnexpectedEof)) => {
                    return fault(
                        "the file ends in the middle of a record: it was cut off (a recording \
                         stopped without closing it, or a copy in part)"
                            .to_owned(),
                    );
                }
                Some(Err(e)) => return fault(format!("not a readable MCAP file: {e}")),
                Some(Ok(LinearReadEvent::ReadRequest(n))) => {
                    let buffer = reader.insert(n);
                    match file.read(buffer) {
                        Ok(read) => reader.notify_read(read),
                        Err(e) => return fault(format!("cannot read: {e}")),
                    }
                }
                Some(Ok(LinearReadEvent::Record { data, opcode })) => {
                    if !matches!(opcode, op::SCHEMA | op::CHANNEL | op::MESSAGE) {
                        continue;
                    }
                    let record = match mcap::parse_record(opcode, data) {
                        Ok(record) => record,
                        Err(e) => return fault(format!("a record does not read: {e}")),
                    };
                    match record {
                        Record::Schema { header, .. } => {
                            self.schemas.insert(header.id, header.name);
                        }
                        Record::Channel(c) => {
                            self.channels.insert(
                                c.id,
                                Channel {
                                    topic: c.topic,
                                    schema: c.schema_id,
                                    encoding: c.message_encoding,
                                },
                            );
                        }
                        Record::Message { header, data } => {
                            let Some(channel) = self.channels.get(&header.channel_id) else {
                                return fault(format!(
                                    "a message on channel {} comes before that channel's record",
                                    header.channel_id
                                ));
                            };
                            if !wanted(&channel.topic) {
                                continue;
                            }
                            let kind = match channel.encoding.as_str() {
                                "cdr" => Kind::Cdr,
                                "ros1" => Kind::Ros1,
                                other => {
                                    return fault(format!(
                                        "the topic {} is encoded as `{other}`; ROS messages are \
                                         read in cdr or ros1",
                                        channel.topic
                                    ));
                                }
                            };
                            return Some(Ok(Message {
                                topic: channel.topic.clone(),
                                type_name: self
                                    .schemas
                                    .get(&channel.schema)
                                    .cloned()
                                    .unwrap_or_default(),
                                kind,
                                log_time_ns: header.log_time,
                                data: data.into_owned(),
                            }));
                        }
                        _ => {}
                    }
                }
            }
        }
    }
}
