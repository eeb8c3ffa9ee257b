//! What a caller sent to describe its rig, parsed once at its edge (a form's parts, a stream's
//! settings, the command's flags) into a [`RigInput`]: a rig by its members, checked, or a
//! calibration file, read. [`RigInput::at`] makes it the rig of each frame size without
//! reading the file again, unless the file states no size and the size decides what it
//! describes (raw cameras rectified for the frames').

use super::calibrated::{Calibrated, Sent, SizeFault};
use crate::calibration::files::{self, Format, KittiPair, Read, ReadFault, ReadOptions, Source};
use crate::physics::{Fault, LengthUnit, Member, Rig, RigSpec};

/// The σ of a calibration's rectified rig sent beside its file, which a file from elsewhere
/// does not carry: the focal length's in pixels, the baseline's in `unit` (the file's when
/// `None`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StdBeside {
    pub focal_px: f64,
    pub baseline: f64,
    pub unit: Option<LengthUnit>,
}

impl StdBeside {
    /// `rig` with this σ, the baseline's converted from its unit to the rig's.
    fn on(self, rig: Rig) -> Result<Rig, Vec<Fault>> {
        let unit = self.unit.unwrap_or(rig.unit());
        let baseline = unit.convert(self.baseline, rig.unit());
        rig.with_calibration_std(self.focal_px, baseline)
    }
}

/// A calibration file as sent: its text (and the right camera's, for ROS), how to read it, and
/// the σ sent beside it.
#[derive(Debug, Clone)]
pub struct CalibrationFile {
    pub text: String,
    pub right_text: Option<String>,
    /// The format, or `None` to detect it.
    pub format: Option<Format>,
    pub kitti_pair: Option<KittiPair>,
    pub options: ReadOptions,
    pub std: Option<StdBeside>,
}

impl CalibrationFile {
    /// The file read for images of `size` (when known).
    fn read(&self, size: Option<(u32, u32)>) -> Result<Read, Vec<ReadFault>> {
        let source = Source {
            text: &self.text,
            right_text: self.right_text.as_deref(),
            format: self.format,
            kitti_pair: self.kitti_pair,
            alpha: None,
            image_size: size,
        };
        files::read(source, self.options)
    }
}

/// A calibration file and the rig read from it once, at `read_at`.
#[derive(Debug, Clone)]
pub struct ReadFile {
    file: CalibrationFile,
    read: Read,
    read_at: Option<(u32, u32)>,
}

/// What a caller sent to describe its rig, parsed: a value that exists is valid.
#[derive(Debug, Clone, Default)]
pub enum RigInput {
    /// No rig: disparities only.
    #[default]
    Nothing,
    /// A rectified rig by its members (`/distance`'s), its image size as declared (`None`: the
    /// frames').
    Members(Box<RigSpec>),
    /// A calibration file, read.
    File(Box<ReadFile>),
}

/// Why what was sent is not the rig of frames of a size.
#[derive(Debug, Clone, PartialEq)]
pub enum AtFault {
    /// The file, read again for the frames' size (it states none), is refused.
    Read(Vec<ReadFault>),
    /// The file is not the calibration of these frames.
    Size(SizeFault),
    /// The members declare another image size: `(member, declared, the frames')`.
    Declared(Vec<(Member, u32, u32)>),
    /// The rig made for the frames' size, or with the σ sent beside the file, is refused.
    Rig(Vec<Fault>),
}

impl RigInput {
    /// A rig by its members, checked as stated (at the size it declares, if any).
    pub fn members(spec: RigSpec) -> Result<RigInput, Vec<Fault>> {
        Rig::new(&spec)?;
        Ok(RigInput::Members(Box::new(spec)))
    }

    /// A calibration file, read once for frames of `size` (the request's, when it has one
    /// size; `None` for frames yet to come), the σ beside it checked against its rig.
    pub fn file(file: CalibrationFile, size: Option<(u32, u32)>) -> Result<RigInput, AtFault> {
        let read = file.read(size).map_err(AtFault::Read)?;
        if let Some(std) = file.std {
            std.on(read.rig).map_err(AtFault::Rig)?;
        }
        Ok(RigInput::File(Box::new(ReadFile {
            file,
            read,
            read_at: size,
        })))
    }

    /// What was sent.
    pub fn sent(&self) -> Sent {
        match self {
            RigInput::Nothing => Sent::Nothing,
            RigInput::Members(_) => Sent::Rig,
            RigInput::File(_) => Sent::Calibration,
        }
    }

    /// The rig of frames of `size` (unknown: `None`), or `None` when nothing was sent.
    pub fn at(&self, size: Option<(u32, u32)>) -> Result<Option<Calibrated>, AtFault> {
        match self {
            RigInput::Nothing => Ok(None),
            RigInput::Members(spec) => members_at(spec, size).map(Some),
            RigInput::File(file) => file.at(size).map(Some),
        }
    }
}

/// The members' rig for frames of `size`: a declared size must be theirs, a missing one is
/// taken from them.
fn members_at(spec: &RigSpec, size: Option<(u32, u32)>) -> Result<Calibrated, AtFault> {
    let mut spec = spec.clone();
    if let Some((w, h)) = size {
        let mut declared = Vec::new();
        for (member, given, actual) in [
            (Member::ImageWidth, &mut spec.camera.image_width, w),
            (Member::ImageHeight, &mut spec.camera.image_height, h),
        ] {
            match *given {
                Some(d) if d != actual => declared.push((member, d, actual)),
                _ => *given = Some(actual),
            }
        }
        if !declared.is_empty() {
            return Err(AtFault::Declared(declared));
        }
    }
    let rig = Rig::new(&spec).map_err(AtFault::Rig)?;
    Ok(Calibrated::of_rig(rig))
}

impl ReadFile {
    /// Whether the rig read once serves frames of `size`: read at that size, or from a file
    /// that states its own (its raw cameras' or its rig's), which no size changes.
    fn serves(&self, size: Option<(u32, u32)>) -> bool {
        self.read_at == size
            || self.read_at.is_none()
                && (self.read.raw.is_some() || self.read.rig.image_width().is_some())
    }

    fn at(&self, size: Option<(u32, u32)>) -> Result<Calibrated, AtFault> {
        let read = if self.serves(size) {
            self.read.clone()
        } else {
            self.file.read(size).map_err(AtFault::Read)?
        };
        let given = Calibrated::from_file(read, size).map_err(AtFault::Size)?;
        let Some(std) = self.file.std else {
            return Ok(given);
        };
        let rig = std.on(given.rig).map_err(AtFault::Rig)?;
        Ok(Calibrated { rig, ..given })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MIDDLEBURY: &str = "cam0=[400 0 80; 0 400 60; 0 0 1]\ncam1=[400 0 80; 0 400 60; 0 0 1]\n\
                              doffs=0\nbaseline=120\nwidth=160\nheight=120\nndisp=48\n";

    fn file(text: &str, std: Option<StdBeside>) -> CalibrationFile {
        CalibrationFile {
            text: text.to_owned(),
            right_text: None,
            format: None,
            kitti_pair: None,
            options: ReadOptions::default(),
            std,
        }
    }

    /// A file that states its size is read once and serves every frame size: its own, and
    /// another refused with both sizes named.
    #[test]
    fn a_file_read_once_serves_every_size() {
        let input = RigInput::file(file(MIDDLEBURY, None), None).unwrap();
        let RigInput::File(read) = &input else {
            panic!("a file")
        };
        assert!(read.serves(Some((160, 120))) && read.serves(Some((320, 240))));
        let rig = input.at(Some((160, 120))).unwrap().unwrap();
        assert_eq!(rig.rig.baseline(), 120.0);
        assert_eq!(rig.max_disparity, Some(48));
        assert_eq!(
            input.at(Some((320, 240))).unwrap_err(),
            AtFault::Size(SizeFault::Mismatch {
                calibrated: (160.0, 120.0),
                images: (320, 240)
            })
        );
        assert_eq!(input.sent(), Sent::Calibration);
    }

    /// The σ sent beside a file reaches the rig, converted from its unit to the file's; a
    /// negative σ is refused when the input is parsed, naming the member.
    #[test]
    fn the_std_beside_a_file_is_the_rigs() {
        let std = StdBeside {
            focal_px: 0.5,
            baseline: 0.2,
            unit: Some(LengthUnit::Centimetre),
        };
        let input = RigInput::file(file(MIDDLEBURY, Some(std)), None).unwrap();
        let rig = input.at(Some((160, 120))).unwrap().unwrap().rig;
        assert_eq!(rig.focal_std_px(), 0.5);
        assert!(
            (rig.baseline_std() - 2.0).abs() < 1e-12,
            "{}",
            rig.baseline_std()
        );
        let bad = StdBeside {
            focal_px: -1.0,
            ..std
        };
        let Err(AtFault::Rig(faults)) = RigInput::file(file(MIDDLEBURY, Some(bad)), None) else {
            panic!("refused")
        };
        assert_eq!(faults[0].member.name(), "focal_length_std_px");
    }

    /// Members take the frames' size when they declare none, and name the member whose
    /// declared size is not the frames'.
    #[test]
    fn members_take_the_frames_size() {
        let mut spec = RigSpec {
            baseline: Some(0.1),
            cx: Some(80.0),
            cy: Some(60.0),
            ..RigSpec::default()
        };
        spec.camera.focal.px = Some(400.0);
        let input = RigInput::members(spec.clone()).unwrap();
        let rig = input.at(Some((160, 120))).unwrap().unwrap().rig;
        assert_eq!(rig.image_width(), Some(160.0));
        spec.camera.image_width = Some(640);
        let input = RigInput::members(spec).unwrap();
        assert_eq!(
            input.at(Some((160, 120))).unwrap_err(),
            AtFault::Declared(vec![(Member::ImageWidth, 640, 160)])
        );
        assert_eq!(input.sent(), Sent::Rig);
    }
}
