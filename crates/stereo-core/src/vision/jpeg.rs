//! JPEG pixels read strictly, so that a damaged file is named instead of shown: a file cut off
//! before its image ends (an interrupted copy) and entropy data that does not decode are
//! refused, as libjpeg warns "Premature end of JPEG file" and "Corrupt JPEG data"; a file
//! whose scans are complete but whose end-of-image marker is missing is read whole, with a
//! note saying so; a file that strays from the standard in a way decoders forgive (extra
//! bytes between segments, markers where none belong between scans) is read as browsers
//! read it, also with a note.
//!
//! The decoder is zune-jpeg's (the one the `image` crate uses), run in its strict mode, which
//! reports what its lenient mode papers over (it fills a cut-off image with grey).

use image::DynamicImage;
use zune_core::bytestream::ZCursor;
use zune_core::colorspace::ColorSpace;
use zune_core::options::DecoderOptions;
use zune_jpeg::JpegDecoder;
use zune_jpeg::errors::DecodeErrors;

/// What a JPEG file gave: its pixels as stored (before any EXIF turn), and a note when it was
/// read despite a fault it could be forgiven.
pub struct Read {
    pub image: DynamicImage,
    pub note: Option<String>,
}

/// Why a JPEG file gave no pixels.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Fault {
    /// The data ends before the image does.
    Truncated,
    /// The header or the entropy-coded data is damaged (the decoder's words).
    Corrupt(String),
}

/// The note of a file read whole without its end-of-image marker.
pub const MISSING_END: &str = "has no end-of-image marker (FFD9) after its complete scans; \
                               it was read whole, but check the copy that made it";

/// Reads `bytes` (a JPEG file) at most `max_side` pixels a side.
pub fn read(bytes: &[u8], max_side: u32) -> Result<Read, Fault> {
    if !has_end_marker(bytes) {
        // Cut off somewhere: whole scans without their marker, or scans cut short.
        return match without_end(bytes, max_side) {
            Some(image) => Ok(Read {
                image,
                note: Some(MISSING_END.to_owned()),
            }),
            None => Err(Fault::Truncated),
        };
    }
    match pixels(bytes, max_side, true) {
        Ok(image) => Ok(Read { image, note: None }),
        Err(e) if cut_off(&e) => Err(Fault::Truncated),
        Err(e) if damaged(&e) => Err(Fault::Corrupt(words(&e))),
        Err(strict) => match pixels(bytes, max_side, false) {
            Ok(image) => Ok(Read {
                image,
                note: Some(format!(
                    "does not follow the JPEG standard ({}); it was read as browsers read it",
                    words(&strict)
                )),
            }),
            Err(e) => Err(Fault::Corrupt(words(&e))),
        },
    }
}

/// The image of a file without its end-of-image marker, when its scans are complete: read
/// twice with the marker put back, once right after the data and once after filler bytes. A
/// decoder that ran short of data reads the filler as image data (zune-jpeg's strict mode
/// does not notice a shortfall within the last row of blocks, nor a progressive file's), so
/// the two differ; complete scans never reach the filler, so they agree.
fn without_end(bytes: &[u8], max_side: u32) -> Option<DynamicImage> {
    const FILLER: [u8; 64] = [0x5A; 64];
    let with = |filler: &[u8]| {
        let mut whole = Vec::with_capacity(bytes.len() + filler.len() + 2);
        whole.extend_from_slice(bytes);
        whole.extend_from_slice(filler);
        whole.extend_from_slice(&[0xFF, 0xD9]);
        pixels(&whole, max_side, false).ok()
    };
    let plain = with(&[])?;
    (with(&FILLER)? == plain).then_some(plain)
}

/// The decoder's error in a sentence.
fn words(e: &DecodeErrors) -> String {
    let text = e.to_string();
    text.trim_matches('"').to_owned()
}

/// Whether the decoder ran out of data before the image's last row of blocks.
fn cut_off(e: &DecodeErrors) -> bool {
    match e {
        DecodeErrors::ExhaustedData => true,
        DecodeErrors::FormatStatic(s) => s.contains("Premature end"),
        DecodeErrors::IoErrors(_) => true,
        _ => false,
    }
}

/// Whether the entropy-coded data itself does not decode (what no decoder forgives without
/// drawing garbage).
fn damaged(e: &DecodeErrors) -> bool {
    match e {
        DecodeErrors::HuffmanDecode(_) | DecodeErrors::MCUError(_) => true,
        DecodeErrors::Format(s) => {
            s.contains("Huffman") || s.contains("bit stream") || s.contains("found where not")
        }
        _ => false,
    }
}

/// The pixels, 8 bits a channel, in the file's own layout (grey, grey-alpha, RGB or RGBA; any
/// other colour space as RGB).
fn pixels(bytes: &[u8], max_side: u32, strict: bool) -> Result<DynamicImage, DecodeErrors> {
    let side = max_side as usize;
    let options = DecoderOptions::default()
        .set_strict_mode(strict)
        .set_max_width(side)
        .set_max_height(side);
    let mut decoder = JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    decoder.decode_headers()?;
    let given = decoder
        .input_colorspace()
        .ok_or(DecodeErrors::FormatStatic("no colour space"))?;
    let out = match given {
        ColorSpace::RGB | ColorSpace::RGBA | ColorSpace::Luma | ColorSpace::LumaA => given,
        _ => ColorSpace::RGB,
    };
    decoder.set_options(decoder.options().jpeg_set_out_colorspace(out));
    let data = decoder.decode()?;
    let (w, h) = decoder
        .dimensions()
        .ok_or(DecodeErrors::FormatStatic("no dimensions"))?;
    let (w, h) = (w as u32, h as u32);
    let wrong = || DecodeErrors::FormatStatic("the decoded pixels do not fill the image");
    Ok(match out {
        ColorSpace::Luma => {
            DynamicImage::ImageLuma8(image::GrayImage::from_raw(w, h, data).ok_or_else(wrong)?)
        }
        ColorSpace::LumaA => DynamicImage::ImageLumaA8(
            image::GrayAlphaImage::from_raw(w, h, data).ok_or_else(wrong)?,
        ),
        ColorSpace::RGBA => {
            DynamicImage::ImageRgba8(image::RgbaImage::from_raw(w, h, data).ok_or_else(wrong)?)
        }
        _ => DynamicImage::ImageRgb8(image::RgbImage::from_raw(w, h, data).ok_or_else(wrong)?),
    })
}

/// Whether the file has its end-of-image marker: the segments before the first scan are
/// skipped by their lengths (so an EXIF thumbnail's own marker is not taken for the file's),
/// and from the first scan on, `FF D9` is found anywhere (entropy-coded data stuffs every
/// `FF` it holds with `00`, so the pair is a marker wherever it stands, whatever damage lies
/// before it). Whatever follows the marker (a phone's trailer) is not read.
pub fn has_end_marker(bytes: &[u8]) -> bool {
    let mut i = 2;
    while i + 3 < bytes.len() {
        if bytes[i] != 0xFF {
            // Bytes between segments (which lenient decoders pass over): search on.
            return bytes[i..].windows(2).any(|w| w == [0xFF, 0xD9]);
        }
        match bytes[i + 1] {
            0xFF => i += 1,
            0xD9 => return true,
            0xDA => return bytes[i..].windows(2).any(|w| w == [0xFF, 0xD9]),
            _ => {
                let length = u16::from_be_bytes([bytes[i + 2], bytes[i + 3]]);
                i += 2 + usize::from(length);
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 96 × 64 colour JPEG of a ramp with texture: baseline from the `image` crate's
    /// encoder, progressive from OpenCV's (`tests/data/jpeg/`; the crate writes no progressive).
    fn jpeg(progressive: bool) -> Vec<u8> {
        if progressive {
            return include_bytes!("../../../../tests/data/jpeg/progressive.jpg").to_vec();
        }
        let (w, h) = (96usize, 64usize);
        let rgb: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                let (x, y) = (i % w, i / w);
                let v = ((x * 2 + (x * y) % 17 * 3) % 256) as u8;
                [v, v.wrapping_add(40), 255 - v]
            })
            .collect();
        crate::vision::synthetic::jpeg(&rgb, w, h, 90)
    }

    /// Whole files read without a note, baseline and progressive, and find their end marker.
    #[test]
    fn whole_files_read_cleanly() {
        for progressive in [false, true] {
            let bytes = jpeg(progressive);
            assert!(has_end_marker(&bytes));
            let read = read(&bytes, 8192).unwrap();
            assert_eq!((read.image.width(), read.image.height()), (96, 64));
            assert_eq!(read.note, None);
        }
    }

    /// A file cut anywhere inside its scans is Truncated, baseline and progressive, down to
    /// a few bytes short of its end, whereas the lenient decoder would have given a
    /// grey-filled image.
    #[test]
    fn cut_off_files_are_truncated() {
        for progressive in [false, true] {
            let bytes = jpeg(progressive);
            let n = bytes.len();
            for keep in [n * 3 / 10, n * 6 / 10, n * 9 / 10, n - 40, n - 8, n - 4] {
                let cut = &bytes[..keep];
                assert!(!has_end_marker(cut));
                assert_eq!(
                    read(cut, 8192).err(),
                    Some(Fault::Truncated),
                    "progressive {progressive}, kept {keep}"
                );
            }
        }
    }

    /// Complete scans without the end marker are read whole, with the note.
    #[test]
    fn a_missing_end_marker_is_repaired_with_a_note() {
        for progressive in [false, true] {
            let bytes = jpeg(progressive);
            let whole = read(&bytes, 8192).unwrap().image;
            let cut = &bytes[..bytes.len() - 2];
            let repaired = read(cut, 8192).unwrap();
            assert_eq!(repaired.note.as_deref(), Some(MISSING_END));
            assert_eq!(repaired.image, whole, "progressive {progressive}");
        }
    }

    /// A real photograph (OpenCV's left01.jpg) with a run of its entropy data overwritten, by
    /// zeros (a bad sector), every seventh byte changed (a garbled transfer) or a marker no
    /// standard defines put in its data, is Corrupt in the
    /// decoder's words; the whole file reads cleanly.
    #[test]
    fn overwritten_data_is_corrupt() {
        let photo = include_bytes!("../../../../tests/data/photographs/opencv-stereo/left01.jpg");
        assert_eq!(read(photo, 8192).map(|r| r.note).ok(), Some(None));
        let n = photo.len();
        let mut zeros = photo.to_vec();
        zeros[n / 3..n / 3 + 4000].fill(0);
        let mut garbled = photo.to_vec();
        for i in (n / 3..n / 3 + 2000).step_by(7) {
            garbled[i] = garbled[i].wrapping_mul(31).wrapping_add(17);
        }
        let mut marked = photo.to_vec();
        marked[n / 2..n / 2 + 2].copy_from_slice(&[0xFF, 0x05]);
        for damaged in [zeros, garbled, marked] {
            let fault = read(&damaged, 8192).err();
            assert!(matches!(fault, Some(Fault::Corrupt(_))), "{fault:?}");
        }
    }

    /// The end marker inside an APP segment (an EXIF thumbnail's) is not the file's.
    #[test]
    fn an_end_marker_inside_a_segment_is_skipped() {
        let mut bytes = vec![0xFF, 0xD8, 0xFF, 0xE1, 0x00, 0x06, 0xFF, 0xD9, 0x00, 0x00];
        assert!(!has_end_marker(&bytes));
        bytes.extend_from_slice(&[0xFF, 0xDA, 0x00, 0x02, 0x12, 0xFF, 0x00, 0xFF, 0xD9]);
        assert!(has_end_marker(&bytes));
    }
}
