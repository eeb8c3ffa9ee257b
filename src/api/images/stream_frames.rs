//! A stream frame's parts and answers: a pair frame cut into its two images, the errors that
//! name a frame's parts, and the files asked for written from its depth map.

use axum::body::Bytes;

use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::wire::depth_map::DepthMapOutput;
use crate::api::wire::depth_stream::FileAnswer;
use stereo_core::pipeline;
use stereo_core::vision::decode;

/// The files asked for, written from the map in order.
pub fn files(
    map: &pipeline::DepthMap,
    outputs: &[DepthMapOutput],
) -> Result<Vec<(FileAnswer, Vec<u8>)>, ApiError> {
    outputs
        .iter()
        .filter(|o| o.is_file())
        .map(|&output| {
            let bytes = super::ros::file(output, map).map_err(ApiError::Internal)?;
            let file = FileAnswer {
                name: output.name(),
                media_type: output.media_type(),
                bytes: bytes.len(),
            };
            Ok((file, bytes))
        })
        .collect()
}

/// A pair-layout frame's two images: after the left image's length (4 bytes, little-endian),
/// the left image, then the right.
pub fn pair_parts(bytes: &Bytes) -> Result<(Bytes, Bytes), ApiError> {
    let Some(head) = bytes.get(..4) else {
        return Err(ApiError::invalid(
            "frame",
            format!(
                "has {} bytes: a pair frame starts with the left image's length (4 bytes, \
                 little-endian)",
                bytes.len()
            ),
        ));
    };
    let len = u32::from_le_bytes([head[0], head[1], head[2], head[3]]) as usize;
    let rest = bytes.len() - 4;
    if len == 0 || len >= rest {
        return Err(ApiError::invalid(
            "frame",
            format!(
                "says its left image has {len} bytes, but {rest} follow the length: a pair \
                 frame is the left image's length (4 bytes, little-endian), the left image, \
                 then the right image"
            ),
        ));
    }
    Ok((bytes.slice(4..4 + len), bytes.slice(4 + len..)))
}

/// An error about a pair frame's `left` or `right` image, named `frame.left`, `frame.right`.
pub fn in_frame(e: ApiError) -> ApiError {
    let named = |errors: Vec<FieldError>| FieldErrors::from(errors).prefixed("frame.");
    match e {
        ApiError::Invalid(errors) => ApiError::Invalid(named(errors)),
        ApiError::Oversized(errors) => ApiError::Oversized(named(errors)),
        other => other,
    }
}

/// The error of a side-by-side frame that cannot be cut in two.
pub fn odd_width(width: usize) -> ApiError {
    ApiError::invalid(
        "frame",
        format!(
            "is {width} px wide: a side-by-side frame holds the left and right images of one \
             width side by side (an even width, each half at least {} px)",
            decode::MIN_SIDE
        ),
    )
}
