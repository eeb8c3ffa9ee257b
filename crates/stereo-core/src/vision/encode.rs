//! Writing disparity and depth maps in the formats their users' tools read: Middlebury's PFM,
//! NumPy's NPY and NPZ, KITTI's and ROS's 16-bit PNG, a colour preview PNG and a binary PLY
//! point cloud.

use std::io::{Cursor, Write};

use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};

/// Middlebury's PFM of a one-channel float image: `Pf`, the size, scale −1 (little-endian), then
/// the rows from the bottom up. Invalid (NaN) pixels are written as +inf, as Middlebury's
/// ground truth marks unknown disparities.
pub fn pfm(width: usize, height: usize, data: &[f32]) -> Vec<u8> {
    let header = format!("Pf\n{width} {height}\n-1\n");
    let mut out = Vec::with_capacity(header.len() + data.len() * 4);
    out.extend_from_slice(header.as_bytes());
    for row in data.chunks_exact(width.max(1)).rev() {
        for &v in row {
            let v = if v.is_nan() { f32::INFINITY } else { v };
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// NumPy's NPY (version 1.0) of a `height × width` float32 array, C order; `numpy.load` reads
/// it. Invalid pixels stay NaN.
pub fn npy(width: usize, height: usize, data: &[f32]) -> Vec<u8> {
    let mut out = npy_header("<f4", width, height, data.len() * 4);
    for &v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// NumPy's NPY of a `height × width` boolean array (`|b1`, one byte a value), C order.
pub fn npy_bool(width: usize, height: usize, data: &[bool]) -> Vec<u8> {
    let mut out = npy_header("|b1", width, height, data.len());
    out.extend(data.iter().map(|&b| u8::from(b)));
    out
}

/// NumPy's NPY of a string, a 0-d array of `<U` (UTF-32, `str(np.load(f))` reads it back).
pub fn npy_text(text: &str) -> Vec<u8> {
    let chars: Vec<char> = text.chars().collect();
    let descr = format!("<U{}", chars.len().max(1));
    let mut out = npy_header_of(&descr, "()", chars.len().max(1) * 4);
    for c in &chars {
        out.extend_from_slice(&u32::from(*c).to_le_bytes());
    }
    if chars.is_empty() {
        out.extend_from_slice(&[0; 4]);
    }
    out
}

/// NumPy's NPY of a one-dimensional array of `f64`.
pub fn npy_f64(values: &[f64]) -> Vec<u8> {
    let mut out = npy_header_of("<f8", &format!("({},)", values.len()), values.len() * 8);
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// An NPY header for a `height × width` array of `descr`, with room for `bytes` of data.
fn npy_header(descr: &str, width: usize, height: usize, bytes: usize) -> Vec<u8> {
    npy_header_of(descr, &format!("({height}, {width})"), bytes)
}

/// An NPY header for an array of `descr` and `shape` (a Python tuple), with room for `bytes`.
fn npy_header_of(descr: &str, shape: &str, bytes: usize) -> Vec<u8> {
    let dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    // Magic (6) + version (2) + length (2) + dict + padding + '\n', a multiple of 64.
    let unpadded = 10 + dict.len() + 1;
    let padding = unpadded.next_multiple_of(64) - unpadded;
    let header_len = dict.len() + padding + 1;
    let mut out = Vec::with_capacity(10 + header_len + bytes);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header_len as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.extend(std::iter::repeat_n(b' ', padding));
    out.push(b'\n');
    out
}

/// NumPy's NPZ: named NPY files in a zip archive, stored (not deflated: float maps hardly
/// compress, and this answer is made for one request), each entry's sizes in its local header
/// (the page reads them there). `numpy.load(p)["depth"]` reads an entry; a name gets `.npy`
/// appended, as `numpy.savez` does. Written by the `zip` crate; an error is only possible for
/// an entry of 4 GiB or more, which no image here reaches.
pub fn npz(entries: &[(&str, Vec<u8>)]) -> zip::result::ZipResult<Vec<u8>> {
    let size = entries
        .iter()
        .map(|(n, b)| 100 + 2 * n.len() + b.len())
        .sum();
    let mut zip = zip::ZipWriter::new(Cursor::new(Vec::with_capacity(size)));
    let stored =
        zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for (name, bytes) in entries {
        zip.start_file(format!("{name}.npy"), stored)?;
        zip.write_all(bytes)?;
    }
    Ok(zip.finish()?.into_inner())
}

/// A 16-bit grey PNG (the encoder takes native-endian samples and stores them big-endian, as
/// PNG does).
pub fn png16(width: usize, height: usize, data: &[u16]) -> Vec<u8> {
    let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_ne_bytes()).collect();
    png(width, height, &bytes, ExtendedColorType::L16)
}

/// An 8-bit grey PNG.
pub fn png_grey(width: usize, height: usize, grey: &[u8]) -> Vec<u8> {
    png(width, height, grey, ExtendedColorType::L8)
}

/// An 8-bit RGB PNG.
pub fn png_rgb(width: usize, height: usize, rgb: &[u8]) -> Vec<u8> {
    png(width, height, rgb, ExtendedColorType::Rgb8)
}

fn png(width: usize, height: usize, bytes: &[u8], colour: ExtendedColorType) -> Vec<u8> {
    let mut out = Vec::new();
    // Fast compression: these answers are made for one request, and deflate's best effort
    // would cost more time than the bytes it saves on a local network.
    PngEncoder::new_with_quality(
        Cursor::new(&mut out),
        CompressionType::Fast,
        FilterType::Adaptive,
    )
    .write_image(bytes, width as u32, height as u32, colour)
    .expect("a PNG of a valid size encodes into memory");
    out
}

/// KITTI's disparity PNG values: `round(d · 256)`, 0 where invalid (and where d ≤ 0 or too
/// large for 16 bits, which the format cannot hold).
pub fn kitti_disparity(data: &[f32]) -> Vec<u16> {
    data.iter()
        .map(|&d| {
            let v = (d * 256.0).round();
            if v.is_nan() || v < 1.0 || v > f32::from(u16::MAX) {
                0
            } else {
                v as u16
            }
        })
        .collect()
}

/// Depth in millimetres for a 16-bit PNG (ROS `16UC1`, RealSense): 0 where invalid or beyond
/// 65.535 m.
pub fn millimetres(depth_mm: &[f32]) -> Vec<u16> {
    depth_mm
        .iter()
        .map(|&z| {
            let v = z.round();
            if v.is_nan() || v < 1.0 || v > f32::from(u16::MAX) {
                0
            } else {
                v as u16
            }
        })
        .collect()
}

/// Google's Turbo colour map (Mikhailov 2019, its published polynomial fit), `t` in [0, 1]
/// from blue to red.
pub fn turbo(t: f32) -> [u8; 3] {
    let x = t.clamp(0.0, 1.0) as f64;
    let v4 = [1.0, x, x * x, x * x * x];
    let v2 = [v4[2] * v4[2], v4[3] * v4[2]];
    let channel = |c4: [f64; 4], c2: [f64; 2]| {
        let v = c4.iter().zip(v4).map(|(c, v)| c * v).sum::<f64>() + c2[0] * v2[0] + c2[1] * v2[1];
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    };
    [
        channel(
            [0.13572138, 4.61539260, -42.66032258, 132.13108234],
            [-152.94239396, 59.28637943],
        ),
        channel(
            [0.09140261, 2.19418839, 4.84296658, -14.18503333],
            [4.27729857, 2.82956604],
        ),
        channel(
            [0.10667330, 12.64194608, -60.58204836, 110.36276771],
            [-89.90310912, 27.34824973],
        ),
    ]
}

/// One point of a cloud, in the left camera's frame, with its colour and the standard
/// deviation of its depth (σ_Z, the same unit as `xyz`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColouredPoint {
    pub xyz: [f32; 3],
    pub rgb: [u8; 3],
    pub depth_std: f32,
}

/// The bytes of one vertex in [`ply`]: x y z, red green blue, depth_std.
pub const PLY_VERTEX_BYTES: usize = 19;

/// A binary little-endian PLY of coloured points, each with its σ_Z as the float property
/// `depth_std` (Open3D, CloudCompare, MeshLab read it; Open3D's tensor API and plyfile give
/// `depth_std` too, and readers that do not know it skip it), with a `comment` line for each
/// of `comments` (one line each; a line break in one ends it).
pub fn ply(points: &[ColouredPoint], comments: &[String]) -> Vec<u8> {
    let notes: String = comments
        .iter()
        .map(|c| format!("comment {}\n", c.lines().next().unwrap_or_default()))
        .collect();
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment stereo-distance depth map, left camera frame\n\
         comment depth_std: the standard deviation of each point's depth, in its unit\n{notes}\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         property float depth_std\nend_header\n",
        points.len()
    );
    let mut out = Vec::with_capacity(header.len() + points.len() * PLY_VERTEX_BYTES);
    out.extend_from_slice(header.as_bytes());
    for p in points {
        for v in p.xyz {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&p.rgb);
        out.extend_from_slice(&p.depth_std.to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The NPY header is padded to 64 bytes and ends in a newline; the data follow it.
    #[test]
    fn npy_header_is_aligned() {
        let out = npy(3, 2, &[0.0, 1.0, 2.0, 3.0, 4.0, f32::NAN]);
        let header_len = u16::from_le_bytes([out[8], out[9]]) as usize;
        assert_eq!((10 + header_len) % 64, 0);
        assert_eq!(out[10 + header_len - 1], b'\n');
        assert_eq!(out.len(), 10 + header_len + 24);
        assert_eq!(
            &out[10 + header_len + 4..10 + header_len + 8],
            &1f32.to_le_bytes()
        );
    }

    /// A boolean NPY: the same aligned header with `|b1`, one byte a value.
    #[test]
    fn bool_npy_is_one_byte_a_value() {
        let out = npy_bool(2, 2, &[true, false, false, true]);
        let header_len = u16::from_le_bytes([out[8], out[9]]) as usize;
        assert_eq!((10 + header_len) % 64, 0);
        let header = std::str::from_utf8(&out[10..10 + header_len]).unwrap();
        assert!(header.contains("'descr': '|b1'") && header.contains("'shape': (2, 2)"));
        assert_eq!(&out[10 + header_len..], &[1, 0, 0, 1]);
    }

    /// A string is a 0-d `<U` array of its UTF-32 code points, an empty one a single NUL;
    /// floats a 1-d `<f8` array; both headers aligned like every other.
    #[test]
    fn text_and_f64_npy() {
        for (text, n) in [("latlon", 6), ("σ", 1), ("", 1)] {
            let out = npy_text(text);
            let header_len = u16::from_le_bytes([out[8], out[9]]) as usize;
            assert_eq!((10 + header_len) % 64, 0);
            let header = std::str::from_utf8(&out[10..10 + header_len]).unwrap();
            assert!(header.contains(&format!("'descr': '<U{n}'")) && header.contains("(),"));
            let data = &out[10 + header_len..];
            assert_eq!(data.len(), 4 * n);
            let back: String = data
                .chunks(4)
                .map(|c| char::from_u32(u32::from_le_bytes(c.try_into().unwrap())).unwrap())
                .filter(|&c| c != '\0')
                .collect();
            assert_eq!(back, text);
        }
        let out = npy_f64(&[1.5, -2.0]);
        let header_len = u16::from_le_bytes([out[8], out[9]]) as usize;
        let header = std::str::from_utf8(&out[10..10 + header_len]).unwrap();
        assert!(header.contains("'descr': '<f8'") && header.contains("'shape': (2,)"));
        assert_eq!(&out[10 + header_len + 8..], &(-2.0f64).to_le_bytes());
    }

    /// The NPZ is a stored zip: each local header names the entry `….npy`, carries its
    /// CRC-32 and size and is followed by the bytes; the central directory, found from the
    /// end record, points back at each local header.
    #[test]
    fn npz_is_a_stored_zip_of_npy_files() {
        let a = npy(2, 1, &[1.0, 2.0]);
        let b = npy(1, 1, &[f32::NAN]);
        let out = npz(&[("disparity", a.clone()), ("depth", b.clone())]).unwrap();
        let u16_at = |i: usize| usize::from(u16::from_le_bytes([out[i], out[i + 1]]));
        let u32_at = |i: usize| u32::from_le_bytes(out[i..i + 4].try_into().unwrap());
        let end = out.len() - 22;
        assert_eq!(u32_at(end), 0x0605_4b50);
        assert_eq!(u16_at(end + 10), 2);
        let mut at = u32_at(end + 16) as usize;
        for (name, bytes) in [("disparity.npy", &a), ("depth.npy", &b)] {
            assert_eq!(u32_at(at), 0x0201_4b50);
            let name_len = u16_at(at + 28);
            assert_eq!(&out[at + 46..at + 46 + name_len], name.as_bytes());
            let local = u32_at(at + 42) as usize;
            assert_eq!(u32_at(local), 0x0403_4b50);
            assert_eq!(u16_at(local + 8), 0, "stored");
            assert_eq!(u32_at(local + 14), crc32fast::hash(bytes));
            assert_eq!(u32_at(local + 18) as usize, bytes.len());
            let data = local + 30 + u16_at(local + 26);
            assert_eq!(&out[data..data + bytes.len()], &bytes[..]);
            at += 46 + name_len;
        }
        assert_eq!(at, end);
    }

    /// What `npz` writes, a zip reader reads back: the names, in order, and the bytes.
    #[test]
    fn npz_round_trips() {
        let entries = [
            ("disparity", npy(2, 1, &[1.0, 2.0])),
            ("depth", npy(1, 1, &[7.5])),
        ];
        let out = npz(&entries).unwrap();
        let mut archive = zip::ZipArchive::new(Cursor::new(out)).unwrap();
        assert_eq!(archive.len(), 2);
        for (i, (name, bytes)) in entries.iter().enumerate() {
            let mut file = archive.by_index(i).unwrap();
            assert_eq!(file.name().unwrap(), format!("{name}.npy"));
            let mut read = Vec::new();
            std::io::Read::read_to_end(&mut file, &mut read).unwrap();
            assert_eq!(&read, bytes);
        }
    }

    /// PFM rows run bottom to top and NaN becomes +inf.
    #[test]
    fn pfm_is_bottom_up() {
        let out = pfm(2, 2, &[1.0, 2.0, 3.0, f32::NAN]);
        let body = &out[b"Pf\n2 2\n-1\n".len()..];
        let values: Vec<f32> = body
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(values, vec![3.0, f32::INFINITY, 1.0, 2.0]);
    }

    /// A 16-bit PNG decodes to the values written.
    #[test]
    fn png16_round_trips() {
        let values = [0u16, 1, 256, 384, 65535, 4097];
        let png = png16(3, 2, &values);
        let back = image::load_from_memory(&png)
            .unwrap()
            .into_luma16()
            .into_raw();
        assert_eq!(back, values);
    }

    /// KITTI and millimetre encodings keep 0 for invalid and out-of-range values.
    #[test]
    fn sixteen_bit_encodings() {
        assert_eq!(
            kitti_disparity(&[1.5, f32::NAN, 0.0, 300.0]),
            vec![384, 0, 0, 0]
        );
        assert_eq!(millimetres(&[1234.4, f32::NAN, 70_000.0]), vec![1234, 0, 0]);
    }

    /// Turbo runs from blue through green to red.
    #[test]
    fn turbo_ends() {
        let [r0, _, b0] = turbo(0.15);
        let [r1, _, b1] = turbo(0.9);
        assert!(
            b0 > 2 * r0 && r1 > 2 * b1,
            "{:?} {:?}",
            turbo(0.15),
            turbo(0.9)
        );
        let [_, g, _] = turbo(0.5);
        assert!(g > 200);
    }
}
