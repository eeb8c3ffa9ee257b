//! Decoding the uploaded images: PNG and JPEG, 8 or 16 bits, grey, grey-alpha, RGB or RGBA.
//! The header is read first and judged against the limits, and the decoder gets its own width,
//! height and allocation caps before it decodes, so a small file that claims 20 000 × 20 000
//! pixels is refused without allocating them.

use std::io::Cursor;

use image::metadata::Orientation;
use image::{
    DynamicImage, ImageDecoder, ImageError, ImageFormat, ImageReader, error::LimitErrorKind,
};

use super::Gray;

/// The widest or tallest image any route decodes, in pixels.
pub const MAX_SIDE: u32 = 8192;
/// The narrowest or shortest image worth matching, in pixels: the census window (9 × 7) and
/// the aggregation's paths need room, and nothing a camera delivers is smaller (the board
/// finder's own floor is the same).
pub const MIN_SIDE: u32 = 32;

/// What a decode may take.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DecodeLimits {
    /// The widest and tallest image accepted, in pixels.
    pub max_side: u32,
    /// The most pixels (width × height) accepted.
    pub max_pixels: u64,
}

impl DecodeLimits {
    /// Whether a `width × height` image is within the limits.
    pub fn admit(self, width: u32, height: u32) -> bool {
        width <= self.max_side
            && height <= self.max_side
            && u64::from(width) * u64::from(height) <= self.max_pixels
    }
}

/// The two formats read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Codec {
    Png,
    Jpeg,
    /// Pixels as a camera gives them (a ROS `Image`), read by [`super::pixels`].
    Raw,
}

/// Why a file could not be read as an image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DecodeError {
    /// Empty, or no image format's signature.
    NotAnImage,
    /// A known image format that is not read here (named).
    Unsupported(&'static str),
    /// Larger than the limits allow.
    TooLarge {
        width: u32,
        height: u32,
        limits: DecodeLimits,
    },
    /// The data ends before the image does (an interrupted copy).
    Truncated,
    /// The header or the data is damaged (the decoder's words).
    Corrupt(String),
}

impl std::fmt::Display for DecodeError {
    /// The fault in a few words (the service says more, with its limits and what to send).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DecodeError::NotAnImage => f.write_str("not an image: PNG or JPEG is read"),
            DecodeError::Unsupported(format) => write!(f, "a {format} file: PNG or JPEG is read"),
            DecodeError::TooLarge {
                width,
                height,
                limits,
            } => write!(
                f,
                "{width} × {height} pixels, past the limits ({} a side, {} pixels)",
                limits.max_side, limits.max_pixels
            ),
            DecodeError::Truncated => f.write_str("cut off: the file ends before its image does"),
            DecodeError::Corrupt(what) => write!(f, "could not be decoded: {what}"),
        }
    }
}

impl std::error::Error for DecodeError {}

/// A decoded image: its grey levels for matching and, when asked, its colours for a point cloud.
#[derive(Debug, Clone, PartialEq)]
pub struct Decoded {
    pub format: Codec,
    pub grey: Gray,
    /// RGB, 8 bits a channel, row-major; present when decoding was asked to keep colour.
    pub rgb: Option<Vec<u8>>,
    /// What was forgiven to read it (a JPEG without its end-of-image marker), in a sentence
    /// about the file.
    pub note: Option<String>,
}

/// The format of `bytes` from its signature, or why it is not one read here.
pub fn sniff(bytes: &[u8]) -> Result<Codec, DecodeError> {
    const OTHERS: [(&[u8], &str); 9] = [
        (b"GIF8", "GIF"),
        (b"BM", "BMP"),
        (b"II*\0", "TIFF"),
        (b"MM\0*", "TIFF"),
        (b"RIFF", "WebP"),
        (b"Pf\n", "PFM"),
        (b"PF\n", "PFM"),
        (b"\x93NUMPY", "NPY"),
        (b"\0\0\0\x0cjP  ", "JPEG 2000"),
    ];
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        return Ok(Codec::Png);
    }
    if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        return Ok(Codec::Jpeg);
    }
    if bytes.len() >= 12 && &bytes[4..8] == b"ftyp" {
        return Err(DecodeError::Unsupported("HEIF/AVIF"));
    }
    for (magic, name) in OTHERS {
        if bytes.starts_with(magic) {
            return Err(DecodeError::Unsupported(name));
        }
    }
    Err(DecodeError::NotAnImage)
}

/// The width and height of the image as it is shown, from the header alone: turned as its
/// EXIF orientation says (a phone's portrait JPEG, stored 4032 × 3024 with orientation 6, is
/// 3024 × 4032), as browsers show it.
pub fn dimensions(bytes: &[u8]) -> Result<(u32, u32), DecodeError> {
    let format = sniff(bytes)?;
    let mut decoder = reader(bytes, format)
        .into_decoder()
        .map_err(|e| corrupt(&e))?;
    let (width, height) = decoder.dimensions();
    let orientation = decoder.orientation().map_err(|e| corrupt(&e))?;
    Ok(if turns(orientation) {
        (height, width)
    } else {
        (width, height)
    })
}

/// Whether an orientation swaps the image's width and height.
fn turns(orientation: Orientation) -> bool {
    matches!(
        orientation,
        Orientation::Rotate90
            | Orientation::Rotate270
            | Orientation::Rotate90FlipH
            | Orientation::Rotate270FlipH
    )
}

/// Decodes `bytes` within `limits`, keeping the colours when `colour` is set.
pub fn decode(bytes: &[u8], limits: DecodeLimits, colour: bool) -> Result<Decoded, DecodeError> {
    let format = sniff(bytes)?;
    let (width, height) = dimensions(bytes)?;
    let too_large = || DecodeError::TooLarge {
        width,
        height,
        limits,
    };
    if !limits.admit(width, height) {
        return Err(too_large());
    }
    if width == 0 || height == 0 {
        return Err(DecodeError::Corrupt("the image has no pixels".into()));
    }
    let mut reader = reader(bytes, format);
    let mut caps = image::Limits::default();
    caps.max_image_width = Some(limits.max_side);
    caps.max_image_height = Some(limits.max_side);
    // The decoded image at its widest (16-bit RGBA) and the decoder's own buffers.
    caps.max_alloc = Some(limits.max_pixels.saturating_mul(8).saturating_add(64 << 20));
    reader.limits(caps);
    let refused = |e: ImageError| match e {
        ImageError::Limits(l) if matches!(l.kind(), LimitErrorKind::DimensionError) => too_large(),
        other => corrupt(&other),
    };
    let mut decoder = reader.into_decoder().map_err(refused)?;
    let orientation = decoder.orientation().map_err(refused)?;
    let (mut image, note) = match format {
        // Strictly, so that a cut-off or damaged file is named (the lenient decoder fills it
        // with grey); the header was already judged against the limits.
        Codec::Jpeg => {
            drop(decoder);
            let read = super::jpeg::read(bytes, limits.max_side).map_err(|fault| match fault {
                super::jpeg::Fault::Truncated => DecodeError::Truncated,
                super::jpeg::Fault::Corrupt(what) => DecodeError::Corrupt(what),
            })?;
            (read.image, read.note)
        }
        Codec::Png | Codec::Raw => (DynamicImage::from_decoder(decoder).map_err(refused)?, None),
    };
    // As shown: `dimensions` already gave the turned size.
    image.apply_orientation(orientation);
    let grey = grey_levels(&image);
    let rgb = colour.then(|| image.to_rgb8().into_raw());
    Ok(Decoded {
        format,
        grey: Gray::new(width as usize, height as usize, grey),
        rgb,
        note,
    })
}

/// The image's grey levels at 16 bits: 8-bit grey, RGB and RGBA (what cameras and PNG
/// exports give) in integers here, and any other layout through the `image` crate's
/// conversion. That conversion goes through `f32` a channel at a time (three times slower);
/// the weights here are its own (sRGB's luma, 0.21264784 R + 0.7151792 G + 0.07217304 B),
/// in 2^-16 steps of a 16-bit level, so the two agree to within one 16-bit level.
/// An 8-bit RGB pixel's grey level at 16 bits (sRGB's luma, as [`decode`] weighs it).
pub fn luma(r: u8, g: u8, b: u8) -> u16 {
    const WEIGHTS: [u64; 3] = [3_581_575, 12_045_586, 1_215_593];
    let sum = WEIGHTS[0] * u64::from(r) + WEIGHTS[1] * u64::from(g) + WEIGHTS[2] * u64::from(b);
    ((sum + (1 << 15)) >> 16) as u16
}

fn grey_levels(image: &DynamicImage) -> Vec<u16> {
    match image {
        DynamicImage::ImageLuma8(grey) => {
            grey.as_raw().iter().map(|&v| u16::from(v) * 257).collect()
        }
        DynamicImage::ImageRgb8(rgb) => rgb
            .as_raw()
            .chunks_exact(3)
            .map(|p| luma(p[0], p[1], p[2]))
            .collect(),
        DynamicImage::ImageRgba8(rgba) => rgba
            .as_raw()
            .chunks_exact(4)
            .map(|p| luma(p[0], p[1], p[2]))
            .collect(),
        other => other.to_luma16().into_raw(),
    }
}

fn reader(bytes: &[u8], format: Codec) -> ImageReader<Cursor<&[u8]>> {
    ImageReader::with_format(
        Cursor::new(bytes),
        match format {
            Codec::Png | Codec::Raw => ImageFormat::Png,
            Codec::Jpeg => ImageFormat::Jpeg,
        },
    )
}

fn corrupt(e: &ImageError) -> DecodeError {
    match e {
        ImageError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            DecodeError::Truncated
        }
        other => {
            let text = other.to_string();
            if text.contains("CRC error") {
                DecodeError::Corrupt(
                    "a PNG chunk fails its checksum (CRC): the file was damaged in a copy or \
                     transfer"
                        .to_owned(),
                )
            } else if text.contains("ChunkType") || text.contains('{') || !text.is_ascii() {
                // The decoder's own words are its types' debug text (a garbled chunk name
                // included): said in ours.
                DecodeError::Corrupt(
                    "a PNG chunk is damaged (its name, length or place is not a PNG's): the \
                     file was damaged in a copy or transfer"
                        .to_owned(),
                )
            } else {
                DecodeError::Corrupt(text)
            }
        }
    }
}

/// A side-by-side frame (the left image in its left half, the right in its right half, as most
/// USB stereo cameras deliver one) cut into its two images, colour kept where it was decoded.
/// `Err` with the frame's width when it is odd or the halves would be narrower than
/// [`MIN_SIDE`].
pub fn split_side_by_side(frame: Decoded) -> Result<(Decoded, Decoded), usize> {
    let (w, h) = (frame.grey.width, frame.grey.height);
    if w % 2 != 0 || w / 2 < MIN_SIDE as usize {
        return Err(w);
    }
    let half = w / 2;
    let cut = |offset: usize| -> Vec<u16> {
        frame
            .grey
            .data
            .chunks_exact(w)
            .flat_map(|row| &row[offset..offset + half])
            .copied()
            .collect()
    };
    let cut_rgb = |rgb: &Vec<u8>, offset: usize| -> Vec<u8> {
        rgb.chunks_exact(3 * w)
            .flat_map(|row| &row[3 * offset..3 * (offset + half)])
            .copied()
            .collect()
    };
    let side = |offset: usize| Decoded {
        format: frame.format,
        grey: Gray::new(half, h, cut(offset)),
        rgb: frame.rgb.as_ref().map(|rgb| cut_rgb(rgb, offset)),
        note: frame.note.clone(),
    };
    Ok((side(0), side(half)))
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: DecodeLimits = DecodeLimits {
        max_side: 4096,
        max_pixels: 4_000_000,
    };

    fn png(width: u32, height: u32) -> Vec<u8> {
        let mut out = Vec::new();
        image::GrayImage::from_pixel(width, height, image::Luma([7]))
            .write_to(&mut Cursor::new(&mut out), ImageFormat::Png)
            .unwrap();
        out
    }

    /// Grey levels of 8-bit RGB and RGBA images are the `image` crate's to within one
    /// 16-bit level, over every grey and a spread of colours; 8-bit grey is scaled exactly.
    #[test]
    fn grey_levels_match_the_image_crate() {
        let mut colours: Vec<u8> = (0..=255u8).flat_map(|v| [v, v, v]).collect();
        let mut rng = crate::vision::synthetic::Rng::new(3);
        colours.extend((0..3 * 5000).map(|_| (rng.unit() * 255.999) as u8));
        let n = colours.len() as u32 / 3;
        let rgb = image::RgbImage::from_raw(n, 1, colours.clone()).unwrap();
        let ours = grey_levels(&DynamicImage::ImageRgb8(rgb.clone()));
        let theirs = DynamicImage::ImageRgb8(rgb).to_luma16().into_raw();
        let worst = ours.iter().zip(&theirs).map(|(a, b)| a.abs_diff(*b)).max();
        assert_eq!(worst, Some(1));
        // Greys are exact: 257 times the level.
        assert!((0..256).all(|v| ours[v] == 257 * v as u16));
        let rgba: Vec<u8> = colours
            .chunks_exact(3)
            .flat_map(|p| [p[0], p[1], p[2], 9])
            .collect();
        let rgba = image::RgbaImage::from_raw(n, 1, rgba).unwrap();
        assert_eq!(grey_levels(&DynamicImage::ImageRgba8(rgba)), ours);
        let grey = image::GrayImage::from_raw(3, 1, vec![0, 7, 255]).unwrap();
        assert_eq!(
            grey_levels(&DynamicImage::ImageLuma8(grey)),
            [0, 7 * 257, 65535]
        );
    }

    /// A PNG decodes to its size, grey levels scaled to 16 bits.
    #[test]
    fn decodes_png() {
        let d = decode(&png(5, 3), LIMITS, true).unwrap();
        assert_eq!((d.grey.width, d.grey.height, d.format), (5, 3, Codec::Png));
        assert!(d.grey.data.iter().all(|&v| v == 7 * 257));
        assert_eq!(d.rgb.unwrap().len(), 5 * 3 * 3);
    }

    /// A header that claims more pixels than allowed is refused before decoding: the file
    /// below is a 1 × 1 PNG whose header (and its checksum) was edited to say 20 000 × 20 000.
    #[test]
    fn refuses_a_huge_header_without_decoding() {
        let mut bytes = png(1, 1);
        bytes[16..20].copy_from_slice(&20_000u32.to_be_bytes());
        bytes[20..24].copy_from_slice(&20_000u32.to_be_bytes());
        let mut crc = flate2::Crc::new();
        crc.update(&bytes[12..29]);
        bytes[29..33].copy_from_slice(&crc.sum().to_be_bytes());
        assert_eq!(dimensions(&bytes), Ok((20_000, 20_000)));
        let e = decode(&bytes, LIMITS, false).unwrap_err();
        assert!(
            matches!(
                e,
                DecodeError::TooLarge {
                    width: 20_000,
                    height: 20_000,
                    ..
                }
            ),
            "{e:?}"
        );
    }

    /// A phone's portrait photo (stored landscape, EXIF orientation 6: turn 90° clockwise to
    /// show) is read as shown: its size swapped, its top-left corner at the top right.
    #[test]
    fn exif_orientation_is_applied() {
        let quadrants = |x: usize, y: usize| match (x < 32, y < 16) {
            (true, true) => 20,
            (false, true) => 230,
            _ => 128,
        };
        let rgb: Vec<u8> = (0..64 * 32)
            .flat_map(|i| [quadrants(i % 64, i / 64); 3])
            .collect();
        let bytes = super::super::synthetic::phone_jpeg(&rgb, 64, 32, 6);
        assert_eq!(dimensions(&bytes), Ok((32, 64)));
        let d = decode(&bytes, LIMITS, false).unwrap();
        assert_eq!((d.grey.width, d.grey.height), (32, 64));
        let at = |x: usize, y: usize| d.grey.data[y * 32 + x] / 257;
        // Stored top-left (dark) is shown top-right; stored top-right (light) bottom-right.
        assert!(at(28, 4) < 40, "{}", at(28, 4));
        assert!(at(28, 60) > 210, "{}", at(28, 60));
        assert!((110..150).contains(&at(4, 30)), "{}", at(4, 30));
        // Orientation 1 leaves it as stored.
        let plain = super::super::synthetic::phone_jpeg(&rgb, 64, 32, 1);
        assert_eq!(dimensions(&plain), Ok((64, 32)));
    }

    /// Other formats are named, and what is no image is said to be none.
    #[test]
    fn sniffs_formats() {
        assert_eq!(sniff(b"GIF89a..."), Err(DecodeError::Unsupported("GIF")));
        assert_eq!(sniff(b"hello"), Err(DecodeError::NotAnImage));
        assert_eq!(sniff(b""), Err(DecodeError::NotAnImage));
        assert_eq!(
            decode(b"\x89PNG\r\n\x1a\nbroken", LIMITS, false),
            Err(DecodeError::Truncated)
        );
        // A PNG whose data ends early is cut off; one with a flipped bit fails its checksum.
        let whole = png(40, 30);
        let cut = &whole[..whole.len() - 20];
        assert_eq!(decode(cut, LIMITS, false), Err(DecodeError::Truncated));
        let mut flipped = whole.clone();
        flipped[whole.len() - 20] ^= 1;
        assert!(matches!(
            decode(&flipped, LIMITS, false),
            Err(DecodeError::Corrupt(_))
        ));
        // A chunk whose name is garbled (`IDA¨` for `IDAT`) is said in words, not as the
        // decoder's debug text.
        let at = whole.windows(4).position(|w| w == b"IDAT").unwrap();
        let mut renamed = whole.clone();
        renamed[at + 3] = 0xA8;
        let Err(DecodeError::Corrupt(said)) = decode(&renamed, LIMITS, false) else {
            panic!("a garbled chunk is corrupt");
        };
        assert!(said.starts_with("a PNG chunk is damaged"), "{said}");
        assert!(said.is_ascii() && !said.contains('{'), "{said}");
    }

    /// A side-by-side frame's halves are its two images, pixel for pixel and in colour; an odd
    /// width is refused with the width.
    #[test]
    fn a_side_by_side_frame_splits_into_its_halves() {
        let (w, h) = (80usize, 40usize);
        let grey: Vec<u16> = (0..w * h)
            .map(|i| (i % w) as u16 * 100 + (i / w) as u16)
            .collect();
        let rgb: Vec<u8> = (0..w * h * 3).map(|i| (i / 3 % w) as u8).collect();
        let frame = Decoded {
            format: Codec::Png,
            grey: Gray::new(w, h, grey),
            rgb: Some(rgb),
            note: None,
        };
        let (left, right) = split_side_by_side(frame.clone()).unwrap();
        assert_eq!((left.grey.width, left.grey.height), (40, 40));
        assert_eq!(left.grey.data[3 * 40 + 5], 5 * 100 + 3);
        assert_eq!(right.grey.data[3 * 40 + 5], 45 * 100 + 3);
        assert_eq!(right.rgb.as_ref().unwrap()[3 * (2 * 40 + 7)], 47);
        assert_eq!(left.rgb.as_ref().unwrap().len(), 40 * 40 * 3);
        let odd = Decoded {
            grey: Gray::new(79, 1, vec![0; 79]),
            rgb: None,
            ..frame
        };
        assert_eq!(split_side_by_side(odd).unwrap_err(), 79);
    }
}
