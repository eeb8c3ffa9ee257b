//! Frames that come as pixels rather than files (a ROS `sensor_msgs/Image`): each layout's
//! rows read into the grey levels and colours [`super::decode::decode`] gives for a file of
//! the same pixels, so that a frame matches alike however it came. Bayer mosaics are
//! demosaiced bilinearly (each colour the mean of its samples in the 3×3 around the pixel).

use super::Gray;
use super::decode::{Codec, DecodeError, DecodeLimits, Decoded, luma};

/// The colour filter's 2×2 pattern, as read from the top-left pixel across then down.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mosaic {
    Rggb,
    Bggr,
    Gbrg,
    Grbg,
}

/// How a frame's pixels are laid out in a row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    Mono8,
    /// 16-bit grey, in the byte order given.
    Mono16 {
        big_endian: bool,
    },
    Rgb8,
    Bgr8,
    Rgba8,
    Bgra8,
    /// A colour filter's raw samples, 8 bits each.
    Bayer8(Mosaic),
    /// A colour filter's raw samples, 16 bits each, in the byte order given.
    Bayer16 {
        mosaic: Mosaic,
        big_endian: bool,
    },
}

impl Layout {
    /// Bytes a pixel.
    pub fn bytes(self) -> usize {
        match self {
            Layout::Mono8 | Layout::Bayer8(_) => 1,
            Layout::Mono16 { .. } | Layout::Bayer16 { .. } => 2,
            Layout::Rgb8 | Layout::Bgr8 => 3,
            Layout::Rgba8 | Layout::Bgra8 => 4,
        }
    }
}

/// The frame of `width × height` pixels laid out as `layout`, rows `step` bytes apart in
/// `data`: its grey levels (and colours, when `colour`), or why not (beyond the limits, or
/// fewer bytes than its size needs), judged before anything is allocated.
pub fn read(
    width: u32,
    height: u32,
    layout: Layout,
    step: usize,
    data: &[u8],
    limits: DecodeLimits,
    colour: bool,
) -> Result<Decoded, DecodeError> {
    if !limits.admit(width, height) {
        return Err(DecodeError::TooLarge {
            width,
            height,
            limits,
        });
    }
    let (w, h) = (width as usize, height as usize);
    if w == 0 || h == 0 {
        return Err(DecodeError::Corrupt("the image has no pixels".into()));
    }
    let row = w * layout.bytes();
    if step < row {
        return Err(DecodeError::Corrupt(format!(
            "its rows are {step} bytes apart, fewer than the {row} a row of {w} pixels needs"
        )));
    }
    let needed = step * (h - 1) + row;
    if data.len() < needed {
        return Err(DecodeError::Corrupt(format!(
            "{} bytes of pixels, fewer than the {needed} a {w} × {h} frame needs",
            data.len()
        )));
    }
    let rows = |y: usize| &data[y * step..y * step + row];
    let sixteen = |b: &[u8], big: bool| {
        if big {
            u16::from_be_bytes([b[0], b[1]])
        } else {
            u16::from_le_bytes([b[0], b[1]])
        }
    };
    let mut rgb: Vec<u8> = Vec::new();
    let grey: Vec<u16> = match layout {
        Layout::Mono8 => (0..h)
            .flat_map(|y| rows(y).iter().map(|&v| u16::from(v) * 257))
            .collect(),
        Layout::Mono16 { big_endian } => (0..h)
            .flat_map(|y| rows(y).chunks_exact(2).map(move |b| sixteen(b, big_endian)))
            .collect(),
        Layout::Rgb8 | Layout::Bgr8 | Layout::Rgba8 | Layout::Bgra8 => {
            let n = layout.bytes();
            let bgr = matches!(layout, Layout::Bgr8 | Layout::Bgra8);
            rgb.reserve_exact(w * h * 3);
            for y in 0..h {
                for p in rows(y).chunks_exact(n) {
                    let (r, b) = if bgr { (p[2], p[0]) } else { (p[0], p[2]) };
                    rgb.extend_from_slice(&[r, p[1], b]);
                }
            }
            rgb.chunks_exact(3)
                .map(|p| luma(p[0], p[1], p[2]))
                .collect()
        }
        Layout::Bayer8(mosaic) => {
            rgb = demosaic(w, h, mosaic, |x, y| u16::from(rows(y)[x]) * 257);
            rgb.chunks_exact(3)
                .map(|p| luma(p[0], p[1], p[2]))
                .collect()
        }
        Layout::Bayer16 { mosaic, big_endian } => {
            rgb = demosaic(w, h, mosaic, |x, y| sixteen(&rows(y)[2 * x..], big_endian));
            rgb.chunks_exact(3)
                .map(|p| luma(p[0], p[1], p[2]))
                .collect()
        }
    };
    let rgb = colour.then(|| {
        if rgb.is_empty() {
            grey.iter().flat_map(|&g| [(g >> 8) as u8; 3]).collect()
        } else {
            rgb
        }
    });
    Ok(Decoded {
        format: Codec::Raw,
        grey: Gray::new(w, h, grey),
        rgb,
        note: None,
    })
}

/// The colour (0 red, 1 green, 2 blue) of the filter at `(x, y)`.
fn filter(mosaic: Mosaic, x: usize, y: usize) -> usize {
    let pattern = match mosaic {
        Mosaic::Rggb => [0, 1, 1, 2],
        Mosaic::Bggr => [2, 1, 1, 0],
        Mosaic::Gbrg => [1, 2, 0, 1],
        Mosaic::Grbg => [1, 0, 2, 1],
    };
    pattern[(y % 2) * 2 + x % 2]
}

/// Bilinear demosaicing to 8-bit RGB: each colour the mean of the samples of that colour in
/// the 3×3 around the pixel (inside the frame).
fn demosaic(w: usize, h: usize, mosaic: Mosaic, at: impl Fn(usize, usize) -> u16) -> Vec<u8> {
    let mut out = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            let (mut sum, mut count) = ([0u32; 3], [0u32; 3]);
            for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    let c = filter(mosaic, xx, yy);
                    sum[c] += u32::from(at(xx, yy));
                    count[c] += 1;
                }
            }
            for c in 0..3 {
                let mean = sum[c] / count[c].max(1);
                out.push((mean >> 8) as u8);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: DecodeLimits = DecodeLimits {
        max_side: 1000,
        max_pixels: 1_000_000,
    };

    /// Grey and colour frames give the levels a PNG of the same pixels gives, whatever the
    /// channel order or the padding at each row's end.
    #[test]
    fn layouts_agree_with_a_png() {
        let (w, h) = (5u32, 3u32);
        let rgb: Vec<u8> = (0..w * h * 3).map(|i| (i * 37 % 251) as u8).collect();
        let mut png = Vec::new();
        use image::ImageEncoder;
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(&rgb, w, h, image::ExtendedColorType::Rgb8)
            .unwrap();
        let from_png = super::super::decode::decode(&png, LIMITS, true).unwrap();
        let bgr_padded: Vec<u8> = rgb
            .chunks_exact(15)
            .flat_map(|row| {
                let mut out: Vec<u8> = row
                    .chunks_exact(3)
                    .flat_map(|p| [p[2], p[1], p[0]])
                    .collect();
                out.extend_from_slice(&[9, 9]);
                out
            })
            .collect();
        let raw = read(w, h, Layout::Bgr8, 17, &bgr_padded, LIMITS, true).unwrap();
        assert_eq!(raw.grey, from_png.grey);
        assert_eq!(raw.rgb, from_png.rgb);
        let mono: Vec<u8> = (0..15u8).collect();
        let grey = read(w, h, Layout::Mono8, 5, &mono, LIMITS, false).unwrap();
        assert_eq!(grey.grey.data[14], 14 * 257);
        let be = read(
            1,
            1,
            Layout::Mono16 { big_endian: true },
            2,
            &[1, 2],
            LIMITS,
            false,
        );
        assert_eq!(be.unwrap().grey.data, vec![0x0102]);
    }

    /// A flat grey scene through any mosaic demosaics to that grey; a red one to red.
    #[test]
    fn bayer_demosaics() {
        for mosaic in [Mosaic::Rggb, Mosaic::Bggr, Mosaic::Gbrg, Mosaic::Grbg] {
            let flat = vec![128u8; 16];
            let got = read(4, 4, Layout::Bayer8(mosaic), 4, &flat, LIMITS, true).unwrap();
            assert!(got.rgb.unwrap().iter().all(|&v| v == 128), "{mosaic:?}");
            let red: Vec<u8> = (0..16)
                .map(|i| {
                    if filter(mosaic, i % 4, i / 4) == 0 {
                        200
                    } else {
                        0
                    }
                })
                .collect();
            let got = read(4, 4, Layout::Bayer8(mosaic), 4, &red, LIMITS, true).unwrap();
            let rgb = got.rgb.unwrap();
            assert!(
                rgb.chunks_exact(3).all(|p| p == [200, 0, 0]),
                "{mosaic:?}: {rgb:?}"
            );
        }
    }

    /// Too few bytes, rows closer than a row, and a frame past the limits are named.
    #[test]
    fn faults_are_named() {
        let short = read(4, 4, Layout::Rgb8, 12, &[0; 40], LIMITS, false).unwrap_err();
        assert!(
            matches!(short, DecodeError::Corrupt(ref s) if s.contains("48 a 4 × 4")),
            "{short:?}"
        );
        let step = read(4, 4, Layout::Rgb8, 8, &[0; 48], LIMITS, false).unwrap_err();
        assert!(matches!(step, DecodeError::Corrupt(ref s) if s.contains("8 bytes apart")));
        let big = read(2000, 1, Layout::Mono8, 2000, &[0; 2000], LIMITS, false);
        assert!(matches!(big, Err(DecodeError::TooLarge { .. })));
    }
}
