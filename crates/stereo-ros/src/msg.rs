//! The messages a stereo rig records and a depth map answers, read and written in either
//! serialisation ([`Kind`]): `sensor_msgs/Image`, `CompressedImage`, `CameraInfo`,
//! `PointCloud2`, and `stereo_msgs/DisparityImage`. Field for field as ROS defines them; the
//! ROS 2 definitions an MCAP file carries as each channel's schema ([`schema`]).

use crate::wire::{Kind, Malformed, Reader, Writer};

/// `std_msgs/Header`: when, and in which frame (ROS 1's `seq` is read and written as 0).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Header {
    /// The stamp in nanoseconds since the epoch.
    pub stamp_ns: i64,
    pub frame_id: String,
}

impl Header {
    pub fn read(r: &mut Reader<'_>) -> Result<Header, Malformed> {
        let stamp_ns = match r.kind() {
            Kind::Ros1 => {
                r.u32("header.seq")?;
                let sec = r.u32("header.stamp.secs")?;
                let nsec = r.u32("header.stamp.nsecs")?;
                i64::from(sec) * 1_000_000_000 + i64::from(nsec)
            }
            Kind::Cdr => {
                let sec = r.i32("header.stamp.sec")?;
                let nsec = r.u32("header.stamp.nanosec")?;
                i64::from(sec) * 1_000_000_000 + i64::from(nsec)
            }
        };
        Ok(Header {
            stamp_ns,
            frame_id: r.string("header.frame_id")?,
        })
    }

    pub fn write(&self, w: &mut Writer) {
        let sec = self.stamp_ns.div_euclid(1_000_000_000);
        let nsec = self.stamp_ns.rem_euclid(1_000_000_000) as u32;
        match w.kind() {
            Kind::Ros1 => {
                w.u32(0);
                w.u32(sec.clamp(0, i64::from(u32::MAX)) as u32);
            }
            Kind::Cdr => w.i32(sec.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32),
        }
        w.u32(nsec);
        w.string(&self.frame_id);
    }
}

/// The header of any message that starts with one (an image, a camera's info): its stamp,
/// without reading the rest.
pub fn header_of(data: &[u8], kind: Kind) -> Result<Header, Malformed> {
    Header::read(&mut Reader::new(data, kind)?)
}

/// `sensor_msgs/Image`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Image {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub encoding: String,
    pub is_bigendian: bool,
    pub step: u32,
    pub data: Vec<u8>,
}

impl Image {
    pub fn decode(data: &[u8], kind: Kind) -> Result<Image, Malformed> {
        Image::read(&mut Reader::new(data, kind)?)
    }

    fn read(r: &mut Reader<'_>) -> Result<Image, Malformed> {
        Ok(Image {
            header: Header::read(r)?,
            height: r.u32("height")?,
            width: r.u32("width")?,
            encoding: r.string("encoding")?,
            is_bigendian: r.bool("is_bigendian")?,
            step: r.u32("step")?,
            data: r.bytes("data")?.to_vec(),
        })
    }

    pub fn encode(&self, kind: Kind) -> Vec<u8> {
        let mut w = Writer::new(kind, self.data.len());
        self.write(&mut w);
        w.finish()
    }

    fn write(&self, w: &mut Writer) {
        self.header.write(w);
        w.u32(self.height);
        w.u32(self.width);
        w.string(&self.encoding);
        w.bool(self.is_bigendian);
        w.u32(self.step);
        w.bytes(&self.data);
    }
}

/// `sensor_msgs/CompressedImage`: `format` names the codec (`jpeg`, `png`, or image_transport's
/// `bgr8; jpeg compressed bgr8`).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct CompressedImage {
    pub header: Header,
    pub format: String,
    pub data: Vec<u8>,
}

impl CompressedImage {
    pub fn decode(data: &[u8], kind: Kind) -> Result<CompressedImage, Malformed> {
        let mut r = Reader::new(data, kind)?;
        Ok(CompressedImage {
            header: Header::read(&mut r)?,
            format: r.string("format")?,
            data: r.bytes("data")?.to_vec(),
        })
    }

    pub fn encode(&self, kind: Kind) -> Vec<u8> {
        let mut w = Writer::new(kind, self.data.len());
        self.header.write(&mut w);
        w.string(&self.format);
        w.bytes(&self.data);
        w.finish()
    }
}

/// `sensor_msgs/RegionOfInterest`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RegionOfInterest {
    pub x_offset: u32,
    pub y_offset: u32,
    pub height: u32,
    pub width: u32,
    pub do_rectify: bool,
}

impl RegionOfInterest {
    fn read(r: &mut Reader<'_>) -> Result<RegionOfInterest, Malformed> {
        Ok(RegionOfInterest {
            x_offset: r.u32("roi.x_offset")?,
            y_offset: r.u32("roi.y_offset")?,
            height: r.u32("roi.height")?,
            width: r.u32("roi.width")?,
            do_rectify: r.bool("roi.do_rectify")?,
        })
    }

    fn write(&self, w: &mut Writer) {
        w.u32(self.x_offset);
        w.u32(self.y_offset);
        w.u32(self.height);
        w.u32(self.width);
        w.bool(self.do_rectify);
    }
}

/// `sensor_msgs/CameraInfo`: `d`, `k`, `r`, `p` as ROS 2 names them (ROS 1's `D`, `K`, `R`, `P`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CameraInfo {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub distortion_model: String,
    pub d: Vec<f64>,
    pub k: [f64; 9],
    pub r: [f64; 9],
    pub p: [f64; 12],
    pub binning_x: u32,
    pub binning_y: u32,
    pub roi: RegionOfInterest,
}

impl CameraInfo {
    /// A camera without distortion (a rectified one, or a pinhole model): `plumb_bob` with D
    /// all zeros, K from `[fx, fy, cx, cy]` in pixels, R the identity and P = [K | (tx, 0, 0)]:
    /// `tx` is −f·B for a pair's right camera (B in metres) and 0 for the left.
    pub fn pinhole(header: Header, [width, height]: [u32; 2], k: [f64; 4], tx: f64) -> Self {
        let [fx, fy, cx, cy] = k;
        CameraInfo {
            header,
            height,
            width,
            distortion_model: "plumb_bob".into(),
            d: vec![0.0; 5],
            k: [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: [fx, 0.0, cx, tx, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            ..CameraInfo::default()
        }
    }

    pub fn decode(data: &[u8], kind: Kind) -> Result<CameraInfo, Malformed> {
        let mut r = Reader::new(data, kind)?;
        Ok(CameraInfo {
            header: Header::read(&mut r)?,
            height: r.u32("height")?,
            width: r.u32("width")?,
            distortion_model: r.string("distortion_model")?,
            d: r.f64s("d")?,
            k: r.f64_array("k")?,
            r: r.f64_array("r")?,
            p: r.f64_array("p")?,
            binning_x: r.u32("binning_x")?,
            binning_y: r.u32("binning_y")?,
            roi: RegionOfInterest::read(&mut r)?,
        })
    }

    pub fn encode(&self, kind: Kind) -> Vec<u8> {
        let mut w = Writer::new(kind, 400);
        self.header.write(&mut w);
        w.u32(self.height);
        w.u32(self.width);
        w.string(&self.distortion_model);
        w.f64s(&self.d);
        w.f64_array(&self.k);
        w.f64_array(&self.r);
        w.f64_array(&self.p);
        w.u32(self.binning_x);
        w.u32(self.binning_y);
        self.roi.write(&mut w);
        w.finish()
    }
}

/// `stereo_msgs/DisparityImage`: a 32FC1 image of disparities, with the rig's `f` (px) and
/// `t` (the baseline, m), the disparities' range and their smallest step `delta_d`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DisparityImage {
    pub header: Header,
    pub image: Image,
    pub f: f32,
    pub t: f32,
    pub valid_window: RegionOfInterest,
    pub min_disparity: f32,
    pub max_disparity: f32,
    pub delta_d: f32,
}

impl DisparityImage {
    pub fn decode(data: &[u8], kind: Kind) -> Result<DisparityImage, Malformed> {
        let mut r = Reader::new(data, kind)?;
        Ok(DisparityImage {
            header: Header::read(&mut r)?,
            image: Image::read(&mut r)?,
            f: r.f32("f")?,
            t: r.f32("t")?,
            valid_window: RegionOfInterest::read(&mut r)?,
            min_disparity: r.f32("min_disparity")?,
            max_disparity: r.f32("max_disparity")?,
            delta_d: r.f32("delta_d")?,
        })
    }

    pub fn encode(&self, kind: Kind) -> Vec<u8> {
        let mut w = Writer::new(kind, self.image.data.len() + 200);
        self.header.write(&mut w);
        self.image.write(&mut w);
        w.f32(self.f);
        w.f32(self.t);
        self.valid_window.write(&mut w);
        w.f32(self.min_disparity);
        w.f32(self.max_disparity);
        w.f32(self.delta_d);
        w.finish()
    }
}

/// `sensor_msgs/PointField`'s `FLOAT32` datatype.
pub const FLOAT32: u8 = 7;

/// `sensor_msgs/PointField`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PointField {
    pub name: String,
    pub offset: u32,
    pub datatype: u8,
    pub count: u32,
}

/// `sensor_msgs/PointCloud2`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PointCloud2 {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub fields: Vec<PointField>,
    pub is_bigendian: bool,
    pub point_step: u32,
    pub row_step: u32,
    pub data: Vec<u8>,
    pub is_dense: bool,
}

impl PointCloud2 {
    pub fn decode(data: &[u8], kind: Kind) -> Result<PointCloud2, Malformed> {
        let mut r = Reader::new(data, kind)?;
        let header = Header::read(&mut r)?;
        let height = r.u32("height")?;
        let width = r.u32("width")?;
        let n = r.count(13, "fields")?;
        let mut fields = Vec::with_capacity(n);
        for _ in 0..n {
            fields.push(PointField {
                name: r.string("fields.name")?,
                offset: r.u32("fields.offset")?,
                datatype: r.u8("fields.datatype")?,
                count: r.u32("fields.count")?,
            });
        }
        Ok(PointCloud2 {
            header,
            height,
            width,
            fields,
            is_bigendian: r.bool("is_bigendian")?,
            point_step: r.u32("point_step")?,
            row_step: r.u32("row_step")?,
            data: r.bytes("data")?.to_vec(),
            is_dense: r.bool("is_dense")?,
        })
    }

    pub fn encode(&self, kind: Kind) -> Vec<u8> {
        let mut w = Writer::new(kind, self.data.len() + 200);
        self.header.write(&mut w);
        w.u32(self.height);
        w.u32(self.width);
        w.count(self.fields.len());
        for field in &self.fields {
            w.string(&field.name);
            w.u32(field.offset);
            w.u8(field.datatype);
            w.u32(field.count);
        }
        w.bool(self.is_bigendian);
        w.u32(self.point_step);
        w.u32(self.row_step);
        w.bytes(&self.data);
        w.bool(self.is_dense);
        w.finish()
    }
}

/// The types a bag's channel may hold that are read or written here.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Type {
    Image,
    CompressedImage,
    CameraInfo,
    DisparityImage,
    PointCloud2,
}

impl Type {
    pub const ALL: [Type; 5] = [
        Type::Image,
        Type::CompressedImage,
        Type::CameraInfo,
        Type::DisparityImage,
        Type::PointCloud2,
    ];

    /// The type named `name`, as ROS 2 (`sensor_msgs/msg/Image`) or ROS 1 (`sensor_msgs/Image`)
    /// names it.
    pub fn from_name(name: &str) -> Option<Type> {
        let short = name.replace("/msg/", "/");
        Type::ALL.into_iter().find(|t| t.ros1_name() == short)
    }

    /// ROS 1's name, `package/Type`.
    pub fn ros1_name(self) -> &'static str {
        match self {
            Type::Image => "sensor_msgs/Image",
            Type::CompressedImage => "sensor_msgs/CompressedImage",
            Type::CameraInfo => "sensor_msgs/CameraInfo",
            Type::DisparityImage => "stereo_msgs/DisparityImage",
            Type::PointCloud2 => "sensor_msgs/PointCloud2",
        }
    }

    /// ROS 2's name, `package/msg/Type`.
    pub fn ros2_name(self) -> String {
        self.ros1_name().replacen('/', "/msg/", 1)
    }
}

const TIME: &str = "int32 sec\nuint32 nanosec\n";
const HEADER: &str = "builtin_interfaces/Time stamp\nstring frame_id\n";
const IMAGE: &str = "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n\
                     uint8 is_bigendian\nuint32 step\nuint8[] data\n";
const COMPRESSED: &str = "std_msgs/Header header\nstring format\nuint8[] data\n";
const ROI: &str =
    "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n";
const CAMERA_INFO: &str = "std_msgs/Header header\nuint32 height\nuint32 width\n\
                           string distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\n\
                           float64[12] p\nuint32 binning_x\nuint32 binning_y\n\
                           sensor_msgs/RegionOfInterest roi\n";
const DISPARITY: &str = "std_msgs/Header header\nsensor_msgs/Image image\nfloat32 f\nfloat32 t\n\
                         sensor_msgs/RegionOfInterest valid_window\nfloat32 min_disparity\n\
                         float32 max_disparity\nfloat32 delta_d\n";
const POINT_FIELD: &str = "uint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\n\
                           uint8 INT32=5\nuint8 UINT32=6\nuint8 FLOAT32=7\nuint8 FLOAT64=8\n\
                           string name\nuint32 offset\nuint8 datatype\nuint32 count\n";
const CLOUD: &str = "std_msgs/Header header\nuint32 height\nuint32 width\n\
                     sensor_msgs/PointField[] fields\nbool is_bigendian\nuint32 point_step\n\
                     uint32 row_step\nuint8[] data\nbool is_dense\n";

/// The ROS 2 message definition (`ros2msg`, as `ros2 bag record` writes it into an MCAP
/// schema): the type's own fields, then each type it uses after a separator line.
pub fn schema(t: Type) -> String {
    let (own, used): (&str, &[(&str, &str)]) = match t {
        Type::Image => (IMAGE, &[]),
        Type::CompressedImage => (COMPRESSED, &[]),
        Type::CameraInfo => (CAMERA_INFO, &[("sensor_msgs/RegionOfInterest", ROI)]),
        Type::DisparityImage => (
            DISPARITY,
            &[
                ("sensor_msgs/Image", IMAGE),
                ("sensor_msgs/RegionOfInterest", ROI),
            ],
        ),
        Type::PointCloud2 => (CLOUD, &[("sensor_msgs/PointField", POINT_FIELD)]),
    };
    let mut text = own.to_owned();
    let header: [(&str, &str); 2] = [
        ("std_msgs/Header", HEADER),
        ("builtin_interfaces/Time", TIME),
    ];
    for (name, fields) in header.iter().chain(used) {
        text.push_str(&format!("{}\nMSG: {name}\n{fields}", "=".repeat(80)));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> Header {
        Header {
            stamp_ns: 1_700_000_000_123_456_789,
            frame_id: "left_optical".into(),
        }
    }

    /// Each message reads back as written, in both serialisations.
    #[test]
    fn every_message_round_trips() {
        for kind in [Kind::Cdr, Kind::Ros1] {
            let image = Image {
                header: header(),
                height: 2,
                width: 3,
                encoding: "mono8".into(),
                is_bigendian: false,
                step: 3,
                data: vec![1, 2, 3, 4, 5, 6],
            };
            assert_eq!(Image::decode(&image.encode(kind), kind).unwrap(), image);
            let info = CameraInfo {
                header: header(),
                height: 480,
                width: 640,
                distortion_model: "plumb_bob".into(),
                d: vec![0.1, -0.2, 0.0, 0.0, 0.01],
                k: [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0],
                r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                p: [
                    500.0, 0.0, 320.0, -50.0, 0.0, 500.0, 240.0, 0.0, 0.0, 0.0, 1.0, 0.0,
                ],
                ..CameraInfo::default()
            };
            assert_eq!(CameraInfo::decode(&info.encode(kind), kind).unwrap(), info);
            let disparity = DisparityImage {
                header: header(),
                image: image.clone(),
                f: 500.0,
                t: 0.1,
                min_disparity: 0.0,
                max_disparity: 64.0,
                delta_d: 0.0625,
                ..DisparityImage::default()
            };
            let read = DisparityImage::decode(&disparity.encode(kind), kind).unwrap();
            assert_eq!(read, disparity);
            let cloud = PointCloud2 {
                header: header(),
                height: 1,
                width: 1,
                fields: vec![PointField {
                    name: "x".into(),
                    offset: 0,
                    datatype: FLOAT32,
                    count: 1,
                }],
                point_step: 4,
                row_step: 4,
                data: 1.5f32.to_le_bytes().to_vec(),
                ..PointCloud2::default()
            };
            assert_eq!(
                PointCloud2::decode(&cloud.encode(kind), kind).unwrap(),
                cloud
            );
            let compressed = CompressedImage {
                header: header(),
                format: "jpeg".into(),
                data: vec![0xff, 0xd8],
            };
            let read = CompressedImage::decode(&compressed.encode(kind), kind).unwrap();
            assert_eq!(read, compressed);
        }
    }

    /// A message cut short names the field it ends in.
    #[test]
    fn a_cut_message_names_its_field() {
        let info = CameraInfo::default().encode(Kind::Cdr);
        let err = CameraInfo::decode(&info[..60], Kind::Cdr).unwrap_err();
        assert!(err.0.contains("of k"), "{err}");
    }

    /// Both spellings of a type's name are known, and a schema lists what the type uses.
    #[test]
    fn names_and_schemas() {
        assert_eq!(Type::from_name("sensor_msgs/msg/Image"), Some(Type::Image));
        assert_eq!(Type::from_name("sensor_msgs/Image"), Some(Type::Image));
        assert_eq!(Type::from_name("sensor_msgs/msg/Imu"), None);
        assert_eq!(
            Type::DisparityImage.ros2_name(),
            "stereo_msgs/msg/DisparityImage"
        );
        let schema = schema(Type::DisparityImage);
        assert!(schema.starts_with("std_msgs/Header header\nsensor_msgs/Image image\n"));
        assert!(schema.contains("\nMSG: sensor_msgs/RegionOfInterest\n"));
        assert!(schema.contains("\nMSG: builtin_interfaces/Time\nint32 sec\n"));
    }
}
