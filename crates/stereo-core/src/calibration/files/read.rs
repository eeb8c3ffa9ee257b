//! A calibration file read into a checked rig: the format's own unit or the one the caller
//! gives, the answer's unit, the warnings worth knowing, and the rig built through
//! [`Rig::new`] like every other rig. Everything `/calibration` and the image routes'
//! `calibration` part do besides naming their fields.

use super::{Format, ParseError, Part, Source, parse};
use crate::physics::{self, LengthUnit, Rig, RigSpec};

/// What the caller adds to a file's text.
#[derive(Debug, Clone, Copy, Default)]
pub struct ReadOptions {
    /// The unit the file's lengths are in; required for OpenCV files, an override for the
    /// others.
    pub calibration_unit: Option<LengthUnit>,
    /// The unit of the rig's lengths (default: the file's own).
    pub unit: Option<LengthUnit>,
}

/// A calibration file read into a rig.
#[derive(Debug, Clone, PartialEq)]
pub struct Read {
    pub format: Format,
    /// The rig, in the unit asked for, with the image size when the file gives it.
    pub rig: Rig,
    /// The disparity search range the file recommends (Middlebury's `ndisp`).
    pub max_disparity_px: Option<u32>,
    pub warnings: Vec<String>,
    /// The raw cameras and their rectification, when the file describes them; T stays in
    /// the file's unit, [`Read::file_unit`].
    pub raw: Option<Box<super::Raw>>,
    /// The unit of the file's lengths.
    pub file_unit: LengthUnit,
}

/// Why a file gives no rig.
#[derive(Debug, Clone, PartialEq)]
pub enum ReadFault {
    /// The text (or the right camera's) cannot be read.
    Parse(ParseError),
    /// An OpenCV file without `calibration_unit`.
    UnitRequired,
    /// The rig the file states is refused, as any rig with that member would be.
    Rig(physics::Fault),
}

/// Why an OpenCV file needs its unit.
pub const UNIT_REQUIRED: &str = "is required for OpenCV files: their lengths (T, P2, Q) are in \
     the unit the calibration target's squares were measured in, which the file does not \
     record; give that unit (mm, cm, m, in or ft)";

/// Reads `source` into a rig. Every fault is reported: those of the text and the unit
/// together, the rig's once the text is read.
pub fn read(source: Source, options: ReadOptions) -> Result<Read, Vec<ReadFault>> {
    let mut faults = Vec::new();
    let (parsed, format) = match parse(source) {
        Ok(calibration) => {
            let format = calibration.format;
            (Some(calibration), Some(format))
        }
        Err(rejected) => {
            faults.extend(rejected.errors.into_iter().map(ReadFault::Parse));
            (None, rejected.format)
        }
    };
    let mut warnings = Vec::new();
    // The unit the file records (our own opencv.yml) counts as the format's own.
    let recorded = parsed.as_ref().and_then(|c| c.unit);
    let file_unit = match (
        options.calibration_unit,
        recorded.or(format.and_then(Format::unit)),
    ) {
        (Some(given), Some(own)) => {
            if given != own {
                warnings.push(format!(
                    "calibration_unit {} overrides this format's own unit, {}",
                    given.symbol(),
                    own.symbol()
                ));
            }
            Some(given)
        }
        (Some(given), None) => Some(given),
        (None, Some(own)) => Some(own),
        (None, None) if format == Some(Format::OpenCv) => {
            faults.push(ReadFault::UnitRequired);
            None
        }
        (None, None) => None,
    };
    if let Some(format) = format {
        if source.right_text.is_some() && !matches!(format, Format::Ros | Format::OpenCv) {
            warnings.push(format!(
                "right_text is read only for ROS files (the right camera's) and OpenCV files (a \
                 second file, such as extrinsics.yml); this is a {} file, so it was ignored",
                format.name()
            ));
        }
        if source.kitti_pair.is_some() && format != Format::Kitti {
            warnings.push(format!(
                "cameras applies only to KITTI files; this is a {} file, so it was ignored",
                format.name()
            ));
        }
    }
    let (Some(parsed), Some(file_unit)) = (parsed, file_unit) else {
        return Err(faults);
    };
    let unit = options.unit.unwrap_or(file_unit);
    let mut spec = RigSpec::pixels(
        parsed.focal_px,
        file_unit.convert(parsed.baseline, unit),
        unit,
    );
    spec.camera.focal_y_px = Some(parsed.focal_y_px);
    (spec.camera.image_width, spec.camera.image_height) = parsed.image_size.unzip();
    spec.cx = Some(parsed.cx);
    spec.cy = Some(parsed.cy);
    spec.doffs = Some(parsed.doffs);
    if let Some(std) = parsed.rig_std {
        spec.focal_std_px = Some(std.focal_px);
        spec.baseline_std = Some(file_unit.convert(std.baseline, unit));
    }
    let rig = Rig::new(&spec).map_err(|f| f.into_iter().map(ReadFault::Rig).collect::<Vec<_>>())?;
    warnings.extend(parsed.warnings);
    Ok(Read {
        format: parsed.format,
        rig,
        max_disparity_px: parsed.max_disparity_px,
        warnings,
        raw: parsed.raw,
        file_unit,
    })
}

impl ReadFault {
    /// What is wrong, in words that follow the name of the field at fault.
    pub fn message(&self) -> String {
        match self {
            ReadFault::Parse(e) => e.to_string(),
            ReadFault::UnitRequired => UNIT_REQUIRED.to_owned(),
            ReadFault::Rig(f) => f.message.clone(),
        }
    }
}

/// Which of the caller's inputs a fault is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// The file's text.
    Text,
    /// The right camera's file.
    RightText,
    /// The unit the file's lengths are in.
    CalibrationUnit,
    /// A member of the rig the file states.
    Rig(physics::Member),
}

impl ReadFault {
    /// The input the fault is in.
    pub fn input(&self) -> Input {
        match self {
            ReadFault::Parse(ParseError {
                part: Part::Text, ..
            }) => Input::Text,
            ReadFault::Parse(_) => Input::RightText,
            ReadFault::UnitRequired => Input::CalibrationUnit,
            ReadFault::Rig(f) => Input::Rig(f.member),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MIDDLEBURY: &str = "cam0=[3979.911 0 1244.772; 0 3979.911 1019.507; 0 0 1]\n\
                              cam1=[3979.911 0 1369.115; 0 3979.911 1019.507; 0 0 1]\n\
                              doffs=124.343\nbaseline=193.001\nwidth=2964\nheight=2000\n\
                              ndisp=270\n";

    /// Motorcycle's file is a checked rig in mm, or in m when asked.
    #[test]
    fn a_file_becomes_a_rig_in_the_unit_asked_for() {
        let source = Source {
            text: MIDDLEBURY,
            ..Source::default()
        };
        let read = read(source, ReadOptions::default()).unwrap();
        assert_eq!(read.rig.unit(), LengthUnit::Millimetre);
        assert_eq!(read.rig.baseline(), 193.001);
        assert_eq!(read.rig.image_width(), Some(2964.0));
        assert_eq!(read.max_disparity_px, Some(270));
        let metres = super::read(
            source,
            ReadOptions {
                unit: Some(LengthUnit::Metre),
                ..ReadOptions::default()
            },
        )
        .unwrap();
        assert!((metres.rig.baseline() - 0.193001).abs() < 1e-12);
    }

    /// A principal point off the file's own image is refused as any rig's would be, naming
    /// the rig's member.
    #[test]
    fn a_rig_off_its_image_is_refused() {
        let text = MIDDLEBURY.replace("1244.772", "3100");
        let faults = read(
            Source {
                text: &text,
                ..Source::default()
            },
            ReadOptions::default(),
        )
        .unwrap_err();
        assert_eq!(faults.len(), 1);
        assert_eq!(faults[0].input(), Input::Rig(physics::Member::Cx));
        assert!(faults[0].message().contains("[0, 2964]"));
    }

    /// An OpenCV file without its unit names the unit; with a damaged text, both.
    #[test]
    fn opencv_needs_its_unit() {
        let text = "%YAML:1.0\n---\nQ: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   \
                    data: [ 1., 0., 0., -640., 0., 1., 0., -360., 0., 0., 0., 900., 0., 0., \
                    1.6666666666666666e-02, 0. ]\n";
        let faults = read(
            Source {
                text,
                ..Source::default()
            },
            ReadOptions::default(),
        )
        .unwrap_err();
        assert_eq!(
            faults.iter().map(ReadFault::input).collect::<Vec<_>>(),
            [Input::CalibrationUnit]
        );
    }
}
