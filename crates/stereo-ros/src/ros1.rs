//! ROS 1 bags (format 2.0), read a record at a time: the connection records name each
//! connection's topic and type, message records carry the data, and chunks (stored plain or
//! lz4-compressed) hold both. Index records are passed over, so a bag whose recording stopped
//! before its index was written reads up to where it stops.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use crate::bag::{BagError, Message};
use crate::wire::Kind;

/// The first bytes of a ROS 1 bag of format 2.0.
pub const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

const OP_MESSAGE: u8 = 0x02;
const OP_CHUNK: u8 = 0x05;
const OP_CONNECTION: u8 = 0x07;

/// A record's header fields (`name=value`), longest allowed.
const HEADER_LIMIT: usize = 16 << 20;

/// A connection: its topic and type.
#[derive(Clone)]
struct Connection {
    topic: String,
    type_name: String,
}

/// Where records come from: the file, or a chunk's records after it was read.
pub struct Messages {
    path: PathBuf,
    file: Option<BufReader<File>>,
    started: bool,
    chunk: Option<(Vec<u8>, usize)>,
    connections: HashMap<u32, Connection>,
    limit: usize,
}

/// A record: its header fields and its data.
struct RawRecord {
    fields: HashMap<String, Vec<u8>>,
    data: Vec<u8>,
}

impl RawRecord {
    fn op(&self) -> Option<u8> {
        self.fields.get("op").and_then(|v| v.first().copied())
    }

    fn u32(&self, name: &str) -> Result<u32, String> {
        let v = self
            .fields
            .get(name)
            .ok_or(format!("a record has no {name} field"))?;
        let bytes: [u8; 4] = v
            .get(..4)
            .and_then(|b| b.try_into().ok())
            .ok_or(format!("the {name} field is not 4 bytes"))?;
        Ok(u32::from_le_bytes(bytes))
    }

    fn text(&self, name: &str) -> Result<String, String> {
        let v = self
            .fields
            .get(name)
            .ok_or(format!("a record has no {name} field"))?;
        String::from_utf8(v.clone()).map_err(|_| format!("the {name} field is not text"))
    }
}

/// The `name=value` fields of a record's header, or a connection record's data.
fn fields(mut bytes: &[u8]) -> Result<HashMap<String, Vec<u8>>, String> {
    let mut out = HashMap::new();
    while !bytes.is_empty() {
        let len = bytes
            .get(..4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
            .ok_or("a header field's length is cut off")?;
        let field = bytes
            .get(4..4 + len)
            .ok_or("a header field runs past its header")?;
        let eq = field
            .iter()
            .position(|&b| b == b'=')
            .ok_or("a header field has no `=`")?;
        out.insert(
            String::from_utf8_lossy(&field[..eq]).into_owned(),
            field[eq + 1..].to_vec(),
        );
        bytes = &bytes[4 + len..];
    }
    Ok(out)
}

/// Reads a little-endian length, and that many bytes (at most `limit`), from `from`;
/// `Ok(None)` at a clean end before the length.
fn sized(from: &mut impl Read, limit: usize, what: &str) -> Result<Option<Vec<u8>>, String> {
    let mut len = [0u8; 4];
    let mut got = 0;
    while got < 4 {
        match from.read(&mut len[got..]) {
            Ok(0) if got == 0 => return Ok(None),
            Ok(0) => return Err(cut()),
            Ok(n) => got += n,
            Err(e) => return Err(format!("cannot read: {e}")),
        }
    }
    let len = u32::from_le_bytes(len) as usize;
    if len > limit {
        return Err(format!(
            "a record's {what} says {len} bytes, more than the {limit} allowed"
        ));
    }
    let mut bytes = Vec::new();
    from.take(len as u64)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot read: {e}"))?;
    if bytes.len() < len {
        return Err(cut());
    }
    Ok(Some(bytes))
}

fn cut() -> String {
    "the file ends in the middle of a record: it was cut off (a recording stopped without \
     closing it, or a copy in part)"
        .to_owned()
}

fn record(from: &mut impl Read, limit: usize) -> Result<Option<RawRecord>, String> {
    let Some(header) = sized(from, HEADER_LIMIT, "header")? else {
        return Ok(None);
    };
    let data = sized(from, limit, "data")?.ok_or_else(cut)?;
    Ok(Some(RawRecord {
        fields: fields(&header)?,
        data,
    }))
}

impl Messages {
    /// The messages of the bag at `path`, no record longer than `limit` bytes.
    pub fn new(path: &Path, limit: usize) -> Messages {
        Messages {
            path: path.to_owned(),
            file: None,
            started: false,
            chunk: None,
            connections: HashMap::new(),
            limit,
        }
    }

    /// The next record, from the current chunk, else from the file.
    fn next_record(&mut self) -> Result<Option<RawRecord>, String> {
        if let Some((bytes, at)) = &mut self.chunk {
            let mut rest = &bytes[*at..];
            let before = rest.len();
            match record(&mut rest, self.limit)? {
                Some(r) => {
                    *at += before - rest.len();
                    return Ok(Some(r));
                }
                None => self.chunk = None,
            }
        }
        if !self.started {
            self.started = true;
            let file = File::open(&self.path).map_err(|e| format!("cannot read: {e}"))?;
            let mut file = BufReader::with_capacity(1 << 20, file);
            let mut magic = [0u8; 13];
            file.read_exact(&mut magic)
                .map_err(|_| "too short for a ROS 1 bag".to_owned())?;
            if magic != MAGIC {
                return Err("not a ROS 1 bag of format 2.0".to_owned());
            }
            self.file = Some(file);
        }
        match &mut self.file {
            Some(file) => record(file, self.limit),
            None => Ok(None),
        }
    }

    pub fn next(&mut self, wanted: &dyn Fn(&str) -> bool) -> Option<Result<Message, BagError>> {
        let shown = self.path.display().to_string();
        let fault = |what: String| Some(Err(BagError(format!("{shown}: {what}"))));
        loop {
            let record = match self.next_record() {
                Ok(Some(record)) => record,
                Ok(None) => return None,
                Err(e) => {
                    self.file = None;
                    self.chunk = None;
                    return fault(e);
                }
            };
            match record.op() {
                Some(OP_CONNECTION) => {
                    let connection = (|| {
                        let id = record.u32("conn")?;
                        let topic = record.text("topic")?;
                        let inner = fields(&record.data)?;
                        let type_name = inner
                            .get("type")
                            .map(|t| String::from_utf8_lossy(t).into_owned())
                            .unwrap_or_default();
                        Ok::<_, String>((id, Connection { topic, type_name }))
                    })();
                    match connection {
                        Ok((id, c)) => {
                            self.connections.insert(id, c);
                        }
                        Err(e) => return fault(e),
                    }
                }
                Some(OP_CHUNK) => {
                    let compression = record.text("compression").unwrap_or_default();
                    let size = match record.u32("size") {
                        Ok(size) => size as usize,
                        Err(e) => return fault(e),
                    };
                    if size > self.limit {
                        return fault(format!(
                            "a chunk says {size} bytes, more than the {} allowed",
                            self.limit
                        ));
                    }
                    let bytes = match compression.as_str() {
                        "none" => record.data,
                        "lz4" => {
                            let mut out = Vec::with_capacity(size);
                            let read = lz4::Decoder::new(record.data.as_slice())
                                .and_then(|d| d.take(size as u64).read_to_end(&mut out));
                            if let Err(e) = read {
                                return fault(format!("an lz4 chunk does not decompress: {e}"));
                            }
                            out
                        }
                        other => {
                            return fault(format!(
                                "its chunks are compressed with {other}, which is not read \
                                 (plain and lz4 are): `rosbag decompress` it, or `rosbag \
                                 compress --lz4`"
                            ));
                        }
                    };
                    self.chunk = Some((bytes, 0));
                }
                Some(OP_MESSAGE) => {
                    let id = match record.u32("conn") {
                        Ok(id) => id,
                        Err(e) => return fault(e),
                    };
                    let Some(connection) = self.connections.get(&id) else {
                        return fault(format!(
                            "a message on connection {id} comes before that connection's record"
                        ));
                    };
                    if !wanted(&connection.topic) {
                        continue;
                    }
                    let time = record.fields.get("time").and_then(|t| t.get(..8));
                    let Some(time) = time else {
                        return fault("a message record has no 8-byte time".to_owned());
                    };
                    let sec = u32::from_le_bytes([time[0], time[1], time[2], time[3]]);
                    let nsec = u32::from_le_bytes([time[4], time[5], time[6], time[7]]);
                    return Some(Ok(Message {
                        topic: connection.topic.clone(),
                        type_name: connection.type_name.clone(),
                        kind: Kind::Ros1,
                        log_time_ns: u64::from(sec) * 1_000_000_000 + u64::from(nsec),
                        data: record.data,
                    }));
                }
                _ => {}
            }
        }
    }
}

/// Writes a ROS 1 bag (format 2.0, no chunks, no index: what readers that read linearly take,
/// and `rosbag reindex` completes).
pub struct Writer<W: std::io::Write> {
    out: W,
    connections: Vec<(String, String)>,
}

impl<W: std::io::Write> Writer<W> {
    /// A bag into `out`, its magic and an empty bag header written.
    pub fn new(mut out: W) -> std::io::Result<Writer<W>> {
        out.write_all(MAGIC)?;
        let mut header = Vec::new();
        field(&mut header, "op", &[0x03]);
        field(&mut header, "index_pos", &0u64.to_le_bytes());
        field(&mut header, "conn_count", &0u32.to_le_bytes());
        field(&mut header, "chunk_count", &0u32.to_le_bytes());
        let padding = 4096usize.saturating_sub(header.len() + 8);
        write_record(&mut out, &header, &vec![b' '; padding])?;
        Ok(Writer {
            out,
            connections: Vec::new(),
        })
    }

    /// The connection of `topic` with messages of `type_name` (its definition and md5sum as
    /// given), written on first use; its id.
    pub fn connection(
        &mut self,
        topic: &str,
        type_name: &str,
        md5sum: &str,
        definition: &str,
    ) -> std::io::Result<u32> {
        if let Some(id) = self.connections.iter().position(|(t, _)| t == topic) {
            return Ok(id as u32);
        }
        let id = self.connections.len() as u32;
        let mut header = Vec::new();
        field(&mut header, "op", &[OP_CONNECTION]);
        field(&mut header, "conn", &id.to_le_bytes());
        field(&mut header, "topic", topic.as_bytes());
        let mut data = Vec::new();
        field(&mut data, "topic", topic.as_bytes());
        field(&mut data, "type", type_name.as_bytes());
        field(&mut data, "md5sum", md5sum.as_bytes());
        field(&mut data, "message_definition", definition.as_bytes());
        write_record(&mut self.out, &header, &data)?;
        self.connections
            .push((topic.to_owned(), type_name.to_owned()));
        Ok(id)
    }

    /// A message on connection `id`, recorded at `time_ns`.
    pub fn message(&mut self, id: u32, time_ns: u64, data: &[u8]) -> std::io::Result<()> {
        let mut header = Vec::new();
        field(&mut header, "op", &[OP_MESSAGE]);
        field(&mut header, "conn", &id.to_le_bytes());
        let sec = (time_ns / 1_000_000_000) as u32;
        let nsec = (time_ns % 1_000_000_000) as u32;
        let mut time = sec.to_le_bytes().to_vec();
        time.extend_from_slice(&nsec.to_le_bytes());
        field(&mut header, "time", &time);
        write_record(&mut self.out, &header, data)
    }

    /// The bag's bytes, flushed.
    pub fn finish(mut self) -> std::io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

fn field(out: &mut Vec<u8>, name: &str, value: &[u8]) {
    out.extend_from_slice(&((name.len() + 1 + value.len()) as u32).to_le_bytes());
    out.extend_from_slice(name.as_bytes());
    out.push(b'=');
    out.extend_from_slice(value);
}

fn write_record(out: &mut impl std::io::Write, header: &[u8], data: &[u8]) -> std::io::Result<()> {
    out.write_all(&(header.len() as u32).to_le_bytes())?;
    out.write_all(header)?;
    out.write_all(&(data.len() as u32).to_le_bytes())?;
    out.write_all(data)
}
