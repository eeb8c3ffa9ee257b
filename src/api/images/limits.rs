//! What the server accepts of an image request: the images' sizes (judged from their headers)
//! and, when a request cannot fit in the memory budget, what to shrink.

use axum::body::Bytes;

use crate::api::error::{ApiError, FieldError, FieldErrors};
use stereo_core::vision::decode::{DecodeError, DecodeLimits, MAX_SIDE, MIN_SIDE};

/// The decoder's limits for every image route: [`MAX_SIDE`] a side and the server's
/// `--max-image-pixels`.
pub fn decode_limits(max_pixels: usize) -> DecodeLimits {
    DecodeLimits {
        max_side: MAX_SIDE,
        max_pixels: max_pixels as u64,
    }
}

/// What a decode error says about a part, with the limits it was decoded under.
pub fn describe(e: &DecodeError, limits: DecodeLimits) -> String {
    match e {
        DecodeError::NotAnImage => "is not an image: send a PNG or JPEG file".to_owned(),
        DecodeError::Unsupported(format) => {
            format!("is a {format} file; send the image as PNG or JPEG")
        }
        DecodeError::TooLarge { width, height, .. } => too_many_pixels(*width, *height, limits),
        DecodeError::Truncated => "is cut off: the file ends before its image does (an \
                                    interrupted copy or upload?); send the whole file"
            .to_owned(),
        DecodeError::Corrupt(what) => {
            format!(
                "could not be decoded: {}",
                stereo_core::numbers::clip(what, 120)
            )
        }
    }
}

fn too_many_pixels(width: u32, height: u32, limits: DecodeLimits) -> String {
    format!(
        "is {width} × {height} pixels; this server takes at most {} pixels a side and {} \
         megapixels: send smaller images (scale the rig with them)",
        limits.max_side,
        stereo_core::numbers::short(limits.max_pixels as f64 / 1e6)
    )
}

/// Why an image of `(width, height)` pixels is refused (413), when it is past `limits`.
pub fn over_the_limits((w, h): (u32, u32), limits: DecodeLimits) -> Option<String> {
    (!limits.admit(w, h)).then(|| too_many_pixels(w, h, limits))
}

/// Checks the pair's sizes: each within the limits (413 otherwise), each at least
/// [`MIN_SIDE`] pixels a side (naming the image), and the right the same size as the left
/// (naming `right`).
pub fn check_pair(
    left: (u32, u32),
    right: (u32, u32),
    limits: DecodeLimits,
    problems: &mut FieldErrors,
) -> Result<(), ApiError> {
    let mut oversized = Vec::new();
    for (name, size) in [("left", left), ("right", right)] {
        if let Some(message) = over_the_limits(size, limits) {
            oversized.push(FieldError::new(name, message));
        }
    }
    if !oversized.is_empty() {
        return Err(ApiError::Oversized(oversized));
    }
    for (name, (w, h)) in [("left", left), ("right", right)] {
        if w < MIN_SIDE || h < MIN_SIDE {
            problems.add(
                name,
                format!(
                    "is {w} × {h} pixels, smaller than {MIN_SIDE} pixels a side: too small to \
                     match; send the frames the cameras deliver"
                ),
            );
        }
    }
    if left != right {
        problems.add(
            "right",
            format!(
                "is {} × {} pixels but the left image is {} × {}: a rectified pair has one size",
                right.0, right.1, left.0, left.1
            ),
        );
    }
    Ok(())
}

/// What to shrink so that a `w × h` request searching `count` disparities, needing
/// `need(count)` bytes, fits in a budget of `total` bytes: the images (to how many megapixels
/// at this range) and, when a narrower range would fit, the range.
pub fn shrink(
    (w, h): (usize, usize),
    count: usize,
    total: usize,
    need: impl Fn(usize) -> usize,
) -> Vec<FieldError> {
    let needed = need(count);
    let per_pixel = needed / (w * h).max(1);
    let max_pixels = total / per_pixel.max(1);
    let mut fits = count;
    while fits > 16 && need(fits) > total {
        fits -= 16;
    }
    let mib = |b: usize| b / (1024 * 1024);
    let mut errors = vec![FieldError::new(
        "left",
        format!(
            "a {w} × {h} pair searching {count} disparities needs {} MiB, more than the {} MiB \
             this server has for image requests: send smaller images (at most {:.1} megapixels \
             at this range) or a narrower disparity range",
            mib(needed),
            mib(total),
            max_pixels as f64 / 1e6
        ),
    )];
    if need(fits) <= total {
        errors.push(FieldError::new(
            "max_disparity",
            format!("or search fewer disparities: at most {fits} fit at this size"),
        ));
    }
    errors
}

/// Every view's size from its header (`/calibrate`'s repeated `left` and `right` parts): past the limits is a 413 naming the part, a size other
/// than the first view's is named in `problems`. Returns the first image's size.
pub fn view_sizes(
    left: &[Bytes],
    right: &[Bytes],
    allowed: DecodeLimits,
    problems: &mut FieldErrors,
) -> Result<Option<(u32, u32)>, ApiError> {
    let mut first: Option<(u32, u32)> = None;
    let mut oversized = Vec::new();
    for (side, images) in [("left", left), ("right", right)] {
        for (i, bytes) in images.iter().enumerate() {
            let name = format!("{side}[{i}]");
            match stereo_core::vision::decode::dimensions(bytes) {
                Ok((w, h)) => {
                    if let Some(message) = over_the_limits((w, h), allowed) {
                        oversized.push(FieldError::new(name, message));
                        continue;
                    }
                    match first {
                        None => first = Some((w, h)),
                        Some((fw, fh)) if (fw, fh) != (w, h) => problems.add_new(
                            name,
                            format!(
                                "is {w} × {h} pixels but left[0] is {fw} × {fh}: every view \
                                 of a calibration has one size"
                            ),
                        ),
                        Some(_) => {}
                    }
                }
                Err(e) => problems.add_new(name, describe(&e, allowed)),
            }
        }
    }
    if !oversized.is_empty() {
        return Err(ApiError::Oversized(oversized));
    }
    Ok(first)
}
