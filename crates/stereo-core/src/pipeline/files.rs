//! The files a depth map is written as ([`Product`], the one catalogue of outputs): PFM, KITTI
//! PNG, NPY, NPZ, 16-bit depth PNG, a preview, PLY, and the depth in the raw left frame.

use super::depth::DepthMap;
use super::latlon::along_axis;
use crate::physics::LengthUnit;
use crate::vision::{Disparity, encode};

/// The file a depth map is written as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Product {
    /// Middlebury's PFM of the disparities, invalid = +inf.
    DisparityPfm,
    /// KITTI's 16-bit PNG: round(d · 256), 0 = invalid.
    DisparityPng,
    /// NumPy float32 disparities, invalid = NaN.
    DisparityNpy,
    /// NumPy float32 depths in the rig's unit, invalid = NaN.
    DepthNpy,
    /// NumPy float32 σ_d in pixels.
    DisparityStdNpy,
    /// PFM of σ_d in pixels.
    DisparityStdPfm,
    /// NumPy float32 σ_Z in the rig's unit.
    DepthStdNpy,
    /// NumPy's NPZ of the disparity, σ_d and, with a rig, depth, σ_Z (twice), and `filled`.
    ArraysNpz,
    /// 16-bit PNG of depth in millimetres, 0 = invalid.
    DepthPng,
    /// The disparities in Turbo colours, near = warm, invalid = black.
    PreviewPng,
    /// Binary PLY of the valid pixels in the left camera's frame, coloured, with σ_Z.
    PointsPly,
    /// NumPy float32 depths at the raw left frame's pixels, along the left camera's own axis
    /// ([`super::left_frame`]), invalid = NaN.
    LeftDepthNpy,
}

/// The media type of a PFM file.
pub const PFM: &str = "image/x-portable-floatmap";
/// The media type of an NPY file.
pub const NPY: &str = "application/x-npy";
/// The media type of an NPZ file (a zip archive of NPY files).
pub const NPZ: &str = "application/zip";
/// The media type of a PLY file.
pub const PLY: &str = "application/x-ply";

impl Product {
    /// Every file a depth map is written as: the one catalogue of outputs, which the service's
    /// `output` choices, the command's `--output` and the OpenAPI document all follow.
    pub const ALL: [Product; 12] = [
        Product::DisparityPfm,
        Product::DisparityPng,
        Product::DisparityNpy,
        Product::DepthNpy,
        Product::DisparityStdNpy,
        Product::DisparityStdPfm,
        Product::DepthStdNpy,
        Product::ArraysNpz,
        Product::DepthPng,
        Product::PreviewPng,
        Product::PointsPly,
        Product::LeftDepthNpy,
    ];

    /// The file's name, as a caller asks for it (`output=depth.npy`) and as it is written.
    pub fn name(self) -> &'static str {
        match self {
            Product::DisparityPfm => "disparity.pfm",
            Product::DisparityPng => "disparity.png",
            Product::DisparityNpy => "disparity.npy",
            Product::DepthNpy => "depth.npy",
            Product::DisparityStdNpy => "disparity_std.npy",
            Product::DisparityStdPfm => "disparity_std.pfm",
            Product::DepthStdNpy => "depth_std.npy",
            Product::ArraysNpz => "arrays.npz",
            Product::DepthPng => "depth.png",
            Product::PreviewPng => "preview.png",
            Product::PointsPly => "points.ply",
            Product::LeftDepthNpy => "left_depth.npy",
        }
    }

    /// The file's media type.
    pub fn media_type(self) -> &'static str {
        match self {
            Product::DisparityPfm | Product::DisparityStdPfm => PFM,
            Product::DisparityPng | Product::DepthPng | Product::PreviewPng => "image/png",
            Product::DisparityNpy
            | Product::DepthNpy
            | Product::DisparityStdNpy
            | Product::DepthStdNpy
            | Product::LeftDepthNpy => NPY,
            Product::PointsPly => PLY,
            Product::ArraysNpz => NPZ,
        }
    }

    /// Whether the file holds depths, hence needs a rig.
    pub fn needs_rig(self) -> bool {
        matches!(
            self,
            Product::DepthNpy
                | Product::DepthStdNpy
                | Product::DepthPng
                | Product::PointsPly
                | Product::LeftDepthNpy
        )
    }

    /// Whether the file holds σ_Z.
    pub fn wants_depth_std(self) -> bool {
        matches!(
            self,
            Product::DepthStdNpy | Product::ArraysNpz | Product::PointsPly
        )
    }

    /// Whether the file wants the left image's colours.
    pub fn wants_colour(self) -> bool {
        self == Product::PointsPly
    }

    /// The bytes a pixel of the map costs to write this file, besides the matcher's: a point
    /// cloud's colours, σ_Z and the 4 more bytes of each point and vertex, or the NPZ's four
    /// more arrays and the archive's copy of all five (and the fill's one-byte mask, twice).
    pub fn extra_bytes_per_pixel(self) -> usize {
        match self {
            Product::PointsPly => 15,
            Product::ArraysNpz => 42,
            Product::DepthStdNpy => 4,
            // The raw frame's depths (a raw frame up to twice the map's pixels).
            Product::LeftDepthNpy => 8,
            _ => 0,
        }
    }

    /// The file's bytes; `Err` only when the NPZ archive cannot be written.
    pub fn encode(self, map: &DepthMap) -> Result<Vec<u8>, String> {
        let d = &map.disparity;
        let (w, h) = (d.width, d.height);
        let depth = map.depth.as_deref().unwrap_or_default();
        let depth_std = map.depth_std.as_deref().unwrap_or_default();
        Ok(match self {
            Product::DisparityPfm => encode::pfm(w, h, &d.data),
            Product::DisparityPng => encode::png16(w, h, &encode::kitti_disparity(&d.data)),
            Product::DisparityNpy => encode::npy(w, h, &d.data),
            Product::DepthNpy => encode::npy(w, h, depth),
            Product::DisparityStdNpy => encode::npy(w, h, &d.std),
            Product::DisparityStdPfm => encode::pfm(w, h, &d.std),
            Product::DepthStdNpy => encode::npy(w, h, depth_std),
            Product::ArraysNpz => arrays(map)?,
            Product::DepthPng => {
                let unit = map.rig.map_or(LengthUnit::Millimetre, |r| r.unit());
                let mm: Vec<f32> = depth
                    .iter()
                    .map(|&z| unit.convert(f64::from(z), LengthUnit::Millimetre) as f32)
                    .collect();
                encode::png16(w, h, &encode::millimetres(&mm))
            }
            Product::PreviewPng => encode::png_rgb(w, h, &preview(d)),
            Product::PointsPly => encode::ply(&points(map), &[map.projection_note()]),
            Product::LeftDepthNpy => match super::left_frame::left_depths(map) {
                Some((w, h, depth)) => encode::npy(w, h, &depth),
                None => encode::npy(w, h, depth),
            },
        })
    }
}

/// The NPZ: the disparity and its σ_d and, with a rig, the depth, its σ_Z, and σ_Z again as
/// `depth_error` (its earlier name); with `fill`, `filled`; the `projection` and, for latlon,
/// its system (`latlon`: f_az, f_el in pixels a radian, cx, cy).
fn arrays(map: &DepthMap) -> Result<Vec<u8>, String> {
    let d = &map.disparity;
    let (w, h) = (d.width, d.height);
    let mut entries = vec![
        ("disparity", encode::npy(w, h, &d.data)),
        ("disparity_std", encode::npy(w, h, &d.std)),
    ];
    if let (Some(depth), Some(depth_std)) = (&map.depth, &map.depth_std) {
        let std = encode::npy(w, h, depth_std);
        entries.push(("depth", encode::npy(w, h, depth)));
        entries.push(("depth_std", std.clone()));
        entries.push(("depth_error", std));
    }
    if !d.filled.is_empty() {
        entries.push(("filled", encode::npy_bool(w, h, &d.filled)));
    }
    entries.push(("projection", encode::npy_text(map.projection())));
    if let Some(l) = &map.latlon {
        entries.push(("latlon", encode::npy_f64(&[l.fx, l.fy, l.cx, l.cy])));
    }
    encode::npz(&entries).map_err(|e| format!("the NPZ was not written: {e}"))
}

/// The disparity map coloured: Turbo from the smallest valid disparity (far, blue) to the
/// largest (near, red), invalid black.
pub fn preview(map: &Disparity) -> Vec<u8> {
    let (lo, hi) = map
        .data
        .iter()
        .filter(|d| !d.is_nan())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &d| {
            (lo.min(d), hi.max(d))
        });
    let span = (hi - lo).max(1e-3);
    map.data
        .iter()
        .flat_map(|&d| {
            if d.is_nan() {
                [0, 0, 0]
            } else {
                encode::turbo((d - lo) / span)
            }
        })
        .collect()
}

/// The valid pixels as points in the left camera's frame (the same formula as `/distance`'s
/// `point`), coloured from the left image, each with its σ_Z.
pub fn points(map: &DepthMap) -> Vec<encode::ColouredPoint> {
    let (Some(rig), Some(depth)) = (map.rig, &map.depth) else {
        return Vec::new();
    };
    // A latlon pixel's point lies along its ray: the depth over cos(az)·cos(el) is its range.
    let point = |x: f64, y: f64, z: f64| match &map.latlon {
        Some(l) => {
            let p = l.ray([x, y]) * (z / along_axis(l, x, y));
            Some(Ok(crate::physics::Point3 {
                x: p.x,
                y: p.y,
                z: p.z,
            }))
        }
        None => rig.point_at(x, y, z),
    };
    let width = map.disparity.width;
    let depth_std = map.depth_std.as_deref().unwrap_or_default();
    let rgb = map.rgb.as_deref().unwrap_or_default();
    let mut out = Vec::new();
    for (i, &z) in depth.iter().enumerate() {
        if z.is_nan() {
            continue;
        }
        let (x, y) = ((i % width) as f64, (i / width) as f64);
        let Some(Ok(p)) = point(x, y, f64::from(z)) else {
            continue;
        };
        let colour = rgb
            .get(i * 3..i * 3 + 3)
            .map_or([200; 3], |c| [c[0], c[1], c[2]]);
        out.push(encode::ColouredPoint {
            xyz: [p.x as f32, p.y as f32, p.z as f32],
            rgb: colour,
            depth_std: depth_std.get(i).copied().unwrap_or(f32::NAN),
        });
    }
    out
}
