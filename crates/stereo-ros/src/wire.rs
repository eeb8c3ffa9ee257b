//! The two serialisations of ROS messages: ROS 2's CDR (XCDR1, with its 4-byte encapsulation
//! header and alignment of each primitive to its size) and ROS 1's (little-endian, packed).
//! One reader and one writer for both, so that each message is described once. Every length
//! read is checked against the bytes left before anything is allocated.

use std::fmt;

/// Which serialisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// ROS 2: CDR, little-endian when written here; either endianness read.
    Cdr,
    /// ROS 1: packed little-endian.
    Ros1,
}

impl Kind {
    /// The MCAP message encoding's name (`cdr`, `ros1`).
    pub fn name(self) -> &'static str {
        match self {
            Kind::Cdr => "cdr",
            Kind::Ros1 => "ros1",
        }
    }
}

/// A message that does not read as its type: what was being read and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Malformed(pub String);

impl fmt::Display for Malformed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Malformed {}

/// Reads one message's fields in order.
#[derive(Debug)]
pub struct Reader<'a> {
    data: &'a [u8],
    at: usize,
    kind: Kind,
    /// Where CDR's alignment counts from (after the encapsulation header).
    origin: usize,
    big: bool,
}

impl<'a> Reader<'a> {
    /// A reader of `data` serialised as `kind` (a CDR message's header read and checked).
    pub fn new(data: &'a [u8], kind: Kind) -> Result<Reader<'a>, Malformed> {
        let mut reader = Reader {
            data,
            at: 0,
            kind,
            origin: 0,
            big: false,
        };
        if kind == Kind::Cdr {
            let header = data.get(..4).ok_or_else(|| {
                Malformed(format!(
                    "{} bytes: too short for CDR's 4-byte header",
                    data.len()
                ))
            })?;
            reader.big = match header[..2] {
                [0, 0] => true,
                [0, 1] => false,
                _ => {
                    return Err(Malformed(format!(
                        "the CDR header {:02x} {:02x} is neither plain CDR big- nor little-endian \
                         (00 00, 00 01)",
                        header[0], header[1]
                    )));
                }
            };
            reader.at = 4;
            reader.origin = 4;
        }
        Ok(reader)
    }

    fn align(&mut self, size: usize) {
        if self.kind == Kind::Cdr {
            let offset = self.at - self.origin;
            self.at += (size - offset % size) % size;
        }
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], Malformed> {
        let end = self.at.checked_add(n).filter(|&end| end <= self.data.len());
        match end {
            Some(end) => {
                let bytes = &self.data[self.at..end];
                self.at = end;
                Ok(bytes)
            }
            None => Err(Malformed(format!(
                "the message ends at byte {} of {what}, which needs {n} more",
                self.data.len(),
            ))),
        }
    }

    fn fixed<const N: usize>(&mut self, what: &str) -> Result<[u8; N], Malformed> {
        self.align(N);
        let mut bytes: [u8; N] = self.take(N, what)?.try_into().unwrap_or([0; N]);
        if self.big {
            bytes.reverse();
        }
        Ok(bytes)
    }

    pub fn u8(&mut self, what: &str) -> Result<u8, Malformed> {
        Ok(self.take(1, what)?[0])
    }

    pub fn bool(&mut self, what: &str) -> Result<bool, Malformed> {
        Ok(self.u8(what)? != 0)
    }

    pub fn u32(&mut self, what: &str) -> Result<u32, Malformed> {
        Ok(u32::from_le_bytes(self.fixed(what)?))
    }

    pub fn i32(&mut self, what: &str) -> Result<i32, Malformed> {
        Ok(i32::from_le_bytes(self.fixed(what)?))
    }

    pub fn f32(&mut self, what: &str) -> Result<f32, Malformed> {
        Ok(f32::from_le_bytes(self.fixed(what)?))
    }

    pub fn f64(&mut self, what: &str) -> Result<f64, Malformed> {
        Ok(f64::from_le_bytes(self.fixed(what)?))
    }

    /// A sequence's length, checked against the bytes left at `size` bytes an element.
    fn length(&mut self, size: usize, what: &str) -> Result<usize, Malformed> {
        let n = self.u32(what)? as usize;
        if n.saturating_mul(size) > self.data.len() - self.at {
            return Err(Malformed(format!(
                "{what} says {n} elements, more than the {} bytes left",
                self.data.len() - self.at
            )));
        }
        Ok(n)
    }

    pub fn string(&mut self, what: &str) -> Result<String, Malformed> {
        let n = self.length(1, what)?;
        let mut bytes = self.take(n, what)?;
        // CDR counts the terminating NUL; ROS 1 does not have one.
        if self.kind == Kind::Cdr {
            bytes = bytes.strip_suffix(&[0]).unwrap_or(bytes);
        }
        String::from_utf8(bytes.to_vec())
            .map_err(|_| Malformed(format!("{what} is not UTF-8 text")))
    }

    /// A `uint8[]`, borrowed.
    pub fn bytes(&mut self, what: &str) -> Result<&'a [u8], Malformed> {
        let n = self.length(1, what)?;
        self.take(n, what)
    }

    /// A `float64[]`.
    pub fn f64s(&mut self, what: &str) -> Result<Vec<f64>, Malformed> {
        let n = self.length(8, what)?;
        (0..n).map(|_| self.f64(what)).collect()
    }

    /// A `float64[N]`.
    pub fn f64_array<const N: usize>(&mut self, what: &str) -> Result<[f64; N], Malformed> {
        let mut out = [0.0; N];
        for value in &mut out {
            *value = self.f64(what)?;
        }
        Ok(out)
    }

    /// The count of a sequence of structures, checked against the bytes left at least
    /// `smallest` bytes an element.
    pub fn count(&mut self, smallest: usize, what: &str) -> Result<usize, Malformed> {
        self.length(smallest, what)
    }

    /// The serialisation read.
    pub fn kind(&self) -> Kind {
        self.kind
    }
}

/// Writes one message's fields in order.
pub struct Writer {
    buf: Vec<u8>,
    kind: Kind,
}

impl Writer {
    /// A message in `kind` (CDR little-endian, its header written), with room for `capacity`
    /// bytes.
    pub fn new(kind: Kind, capacity: usize) -> Writer {
        let mut buf = Vec::with_capacity(capacity + 64);
        if kind == Kind::Cdr {
            buf.extend_from_slice(&[0, 1, 0, 0]);
        }
        Writer { buf, kind }
    }

    fn align(&mut self, size: usize) {
        if self.kind == Kind::Cdr {
            let offset = self.buf.len() - 4;
            let pad = (size - offset % size) % size;
            self.buf.resize(self.buf.len() + pad, 0);
        }
    }

    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    pub fn bool(&mut self, v: bool) {
        self.buf.push(u8::from(v));
    }

    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f32(&mut self, v: f32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A length or count, saturating at `u32::MAX` (nothing written here is that long).
    pub fn count(&mut self, n: usize) {
        self.u32(u32::try_from(n).unwrap_or(u32::MAX));
    }

    pub fn string(&mut self, s: &str) {
        match self.kind {
            Kind::Cdr => {
                self.count(s.len() + 1);
                self.buf.extend_from_slice(s.as_bytes());
                self.buf.push(0);
            }
            Kind::Ros1 => {
                self.count(s.len());
                self.buf.extend_from_slice(s.as_bytes());
            }
        }
    }

    pub fn bytes(&mut self, b: &[u8]) {
        self.count(b.len());
        self.buf.extend_from_slice(b);
    }

    pub fn f64s(&mut self, values: &[f64]) {
        self.count(values.len());
        self.f64_array(values);
    }

    /// A fixed-size `float64[N]` (no count).
    pub fn f64_array(&mut self, values: &[f64]) {
        for &v in values {
            self.f64(v);
        }
    }

    /// The serialisation written.
    pub fn kind(&self) -> Kind {
        self.kind
    }

    /// The message's bytes.
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// CDR aligns each primitive to its size from after the header, and reads back what it
    /// wrote; ROS 1 packs.
    #[test]
    fn cdr_aligns_and_ros1_packs() {
        // CDR: header 4, u8 1, pad 3, u32 4, f64 8, length 4, "ab" and its NUL 3.
        for (kind, len) in [(Kind::Cdr, 27), (Kind::Ros1, 20)] {
            let mut w = Writer::new(kind, 0);
            w.u8(7);
            w.u32(0xdead_beef);
            w.f64(1.5);
            w.string(if kind == Kind::Cdr { "ab" } else { "abc" });
            let bytes = w.finish();
            assert_eq!(bytes.len(), len, "{kind:?}");
            let mut r = Reader::new(&bytes, kind).unwrap();
            assert_eq!(r.u8("a").unwrap(), 7);
            assert_eq!(r.u32("b").unwrap(), 0xdead_beef);
            assert_eq!(r.f64("c").unwrap(), 1.5);
            assert!(r.string("d").unwrap().starts_with("ab"));
        }
    }

    /// A length past the message's end is named before anything is allocated.
    #[test]
    fn a_length_past_the_end_is_named() {
        let mut w = Writer::new(Kind::Cdr, 0);
        w.u32(4_000_000_000);
        let bytes = w.finish();
        let err = Reader::new(&bytes, Kind::Cdr)
            .unwrap()
            .bytes("data")
            .unwrap_err();
        assert!(err.0.contains("data says 4000000000 elements"), "{err}");
        assert!(Reader::new(&[0, 1], Kind::Cdr).is_err());
        assert!(
            Reader::new(&[9, 9, 0, 0], Kind::Cdr)
                .unwrap_err()
                .0
                .contains("neither")
        );
    }

    /// A big-endian CDR message reads as well.
    #[test]
    fn big_endian_cdr_reads() {
        let bytes = [0, 0, 0, 0, 0, 0, 1, 2];
        assert_eq!(
            Reader::new(&bytes, Kind::Cdr).unwrap().u32("x").unwrap(),
            0x0102
        );
    }
}
