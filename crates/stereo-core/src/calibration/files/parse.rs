//! A calibration file parsed in the format it is given in or detected as ([`super::detect`]):
//! each format's parser called, and a format given that the file does not have named.

use super::{
    Calibration, Format, MAX_ERRORS, ParseError, Source, detect, kitti, middlebury, opencv, ros,
};

/// A calibration that could not be read: the format it was read as (`None` when it matches
/// none) and every problem found.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejected {
    pub format: Option<Format>,
    pub errors: Vec<ParseError>,
}

/// Reads a calibration. A file that matches no format says which were tried and why each did
/// not fit.
pub fn parse(source: Source) -> Result<Calibration, Rejected> {
    let format = match source.format {
        Some(format) => format,
        None => detect(source.text, source.right_text.is_some()).map_err(|errors| Rejected {
            format: None,
            errors,
        })?,
    };
    let parsed = match format {
        Format::Middlebury => middlebury::parse(source.text),
        Format::Kitti => kitti::parse(source.text, source.kitti_pair, source.alpha),
        Format::Ros => ros::parse(
            source.text,
            source.right_text,
            source.alpha,
            source.image_size,
        ),
        Format::OpenCv => opencv::parse(
            source.text,
            source.right_text,
            source.alpha,
            source.image_size,
        ),
    };
    parsed.map_err(|mut errors| {
        // A format given by the caller that the file does not have: say which it looks like.
        if source.format.is_some()
            && let Ok(looks) = detect(source.text, source.right_text.is_some())
            && looks != format
        {
            errors.insert(
                0,
                ParseError::whole(format!(
                    "this looks like a {} file, not {}: send format auto or {}",
                    looks.name(),
                    format.name(),
                    looks.name()
                )),
            );
        }
        if errors.len() > MAX_ERRORS {
            let more = errors.len() - MAX_ERRORS;
            errors.truncate(MAX_ERRORS);
            errors.push(ParseError::whole(format!(
                "and {more} more problems like these"
            )));
        }
        Rejected {
            format: Some(format),
            errors,
        }
    })
}
