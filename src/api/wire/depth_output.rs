//! What `/depth-map` (and a stream's `outputs`) answer: the JSON summary, the engine's files,
//! or a ROS 2 message in CDR; each output's name, media type and what the engine makes for it.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::wire::de::choice_members;
use stereo_core::pipeline::Product;
use stereo_core::pipeline::files::{NPZ, PFM, PLY};

/// What `/depth-map` answers.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
pub enum DepthMapOutput {
    /// JSON: the size, the range searched, the valid fraction, disparity and depth statistics,
    /// the rig, the parameters and the stage times.
    #[default]
    #[serde(rename = "summary")]
    Summary,
    /// Middlebury's PFM (`Pf`, little-endian, rows bottom to top), invalid = +inf.
    #[serde(rename = "disparity.pfm")]
    DisparityPfm,
    /// KITTI's 16-bit PNG: round(d · 256), 0 = invalid.
    #[serde(rename = "disparity.png")]
    DisparityPng,
    /// NumPy float32 array (height × width) of disparities, invalid = NaN.
    #[serde(rename = "disparity.npy")]
    DisparityNpy,
    /// NumPy float32 array (height × width) of depths Z in the rig's unit, invalid = NaN.
    #[serde(rename = "depth.npy")]
    DepthNpy,
    /// NumPy float32 array (height × width) of each disparity's standard deviation σ_d in
    /// pixels, invalid = NaN.
    #[serde(rename = "disparity_std.npy")]
    DisparityStdNpy,
    /// Middlebury's PFM of σ_d in pixels (as `disparity.pfm`), invalid = +inf.
    #[serde(rename = "disparity_std.pfm")]
    DisparityStdPfm,
    /// NumPy float32 array (height × width) of each depth's standard deviation σ_Z in the rig's
    /// unit: √((Z²·σ_d / (f·B))² + (Z·σ_f / f)² + (Z·σ_B / B)²), invalid = NaN.
    #[serde(rename = "depth_std.npy")]
    DepthStdNpy,
    /// NumPy's NPZ (`numpy.load(p)`), float32, invalid = NaN: `disparity` and `disparity_std`
    /// (σ_d, pixels) and, with a rig, `depth`, `depth_std` (σ_Z, the rig's unit, with the
    /// rig's σ_f and σ_B) and `depth_error` (the same σ_Z under its earlier name; it was once
    /// one Δd propagated for every pixel); with `fill=true`, `filled` (bool: the pixels the
    /// fill gave a value, whose σ_d says how little is known of them).
    #[serde(rename = "arrays.npz")]
    ArraysNpz,
    /// 16-bit PNG of depth in millimetres (ROS `16UC1`), 0 = invalid or beyond 65.535 m.
    #[serde(rename = "depth.png")]
    DepthPng,
    /// The depth coloured for people (Turbo on inverse depth, near = warm), invalid = black.
    #[serde(rename = "preview.png")]
    PreviewPng,
    /// Binary PLY point cloud of the valid pixels, x y z in the rig's unit in the left
    /// camera's frame, coloured from the left image, each with its σ_Z (`depth_std`, the
    /// same unit).
    #[serde(rename = "points.ply")]
    PointsPly,
    /// NumPy float32 depths (the rig's unit, invalid = NaN) at the raw left frame's pixels,
    /// along the left camera's own optical axis: a raw pair's map in the left camera's own
    /// pixels (of the frame's size), whatever the projection it was matched in.
    #[serde(rename = "left_depth.npy")]
    LeftDepthNpy,
    /// ROS 2's `stereo_msgs/msg/DisparityImage` in CDR, as `stereo_image_proc` publishes it:
    /// 32FC1 disparities (NaN where none), `f` in pixels and `t` the baseline in metres, so
    /// that Z = f·t/d. Stamped when made, in frame `left_camera`.
    #[serde(rename = "disparity.cdr")]
    DisparityCdr,
    /// ROS 2's `sensor_msgs/msg/Image` in CDR: the depth, 32FC1 in metres, NaN where none
    /// (REP 118).
    #[serde(rename = "depth.cdr")]
    DepthCdr,
    /// ROS 2's `sensor_msgs/msg/Image` in CDR: σ_Z of each depth, 32FC1 in metres.
    #[serde(rename = "depth_std.cdr")]
    DepthStdCdr,
    /// ROS 2's `sensor_msgs/msg/PointCloud2` in CDR: x, y, z (m, the left camera's optical
    /// frame), rgb and depth_std (m) of each pixel with a depth.
    #[serde(rename = "points.cdr")]
    PointsCdr,
}

/// A ROS 2 message a depth map answers in CDR.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RosOutput {
    Disparity,
    Depth,
    DepthStd,
    Points,
}

/// The media type of a CDR answer.
pub const CDR: &str = "application/x-cdr";

impl DepthMapOutput {
    /// The name, as the query takes it and as the file is called ([`Product::name`]).
    pub fn name(self) -> &'static str {
        match self.ros() {
            Some(RosOutput::Disparity) => "disparity.cdr",
            Some(RosOutput::Depth) => "depth.cdr",
            Some(RosOutput::DepthStd) => "depth_std.cdr",
            Some(RosOutput::Points) => "points.cdr",
            None => self.product().map_or("summary", Product::name),
        }
    }

    /// The media type of the answer ([`Product::media_type`]).
    pub fn media_type(self) -> &'static str {
        if self.ros().is_some() {
            return CDR;
        }
        self.product()
            .map_or("application/json", Product::media_type)
    }

    /// The ROS 2 message the answer is, for the CDR outputs.
    pub fn ros(self) -> Option<RosOutput> {
        Some(match self {
            DepthMapOutput::DisparityCdr => RosOutput::Disparity,
            DepthMapOutput::DepthCdr => RosOutput::Depth,
            DepthMapOutput::DepthStdCdr => RosOutput::DepthStd,
            DepthMapOutput::PointsCdr => RosOutput::Points,
            _ => return None,
        })
    }

    /// Whether the answer is a file (the engine's or a ROS message), not the JSON summary.
    pub fn is_file(self) -> bool {
        self != DepthMapOutput::Summary
    }

    /// What the engine makes for the answer, named by the engine's file that holds the same
    /// arrays: the file itself, or for a ROS message the depths (`disparity.cdr` carries f
    /// and B with its disparities, so it needs the rig as well), their σ, or the points with
    /// their colours and σ. The rig, σ_Z, the colours and the memory a map takes are asked
    /// for as for that file; `None` for the summary.
    pub fn needs(self) -> Option<Product> {
        match self.ros() {
            Some(RosOutput::Disparity | RosOutput::Depth) => Some(Product::DepthNpy),
            Some(RosOutput::DepthStd) => Some(Product::DepthStdNpy),
            Some(RosOutput::Points) => Some(Product::PointsPly),
            None => self.product(),
        }
    }

    /// The engine's file the answer is; `None` for the summary and the ROS messages.
    pub fn product(self) -> Option<Product> {
        Some(match self {
            DepthMapOutput::Summary
            | DepthMapOutput::DisparityCdr
            | DepthMapOutput::DepthCdr
            | DepthMapOutput::DepthStdCdr
            | DepthMapOutput::PointsCdr => return None,
            DepthMapOutput::DisparityPfm => Product::DisparityPfm,
            DepthMapOutput::DisparityPng => Product::DisparityPng,
            DepthMapOutput::DisparityNpy => Product::DisparityNpy,
            DepthMapOutput::DepthNpy => Product::DepthNpy,
            DepthMapOutput::DisparityStdNpy => Product::DisparityStdNpy,
            DepthMapOutput::DisparityStdPfm => Product::DisparityStdPfm,
            DepthMapOutput::DepthStdNpy => Product::DepthStdNpy,
            DepthMapOutput::ArraysNpz => Product::ArraysNpz,
            DepthMapOutput::DepthPng => Product::DepthPng,
            DepthMapOutput::PreviewPng => Product::PreviewPng,
            DepthMapOutput::PointsPly => Product::PointsPly,
            DepthMapOutput::LeftDepthNpy => Product::LeftDepthNpy,
        })
    }

    /// Whether the answer needs depths, hence a rig.
    pub fn needs_rig(self) -> bool {
        self.needs().is_some_and(Product::needs_rig)
    }

    /// Whether the answer carries σ_Z (computed only then): the summary's spread, or a file's.
    pub fn wants_depth_std(self) -> bool {
        self.needs().is_none_or(Product::wants_depth_std)
    }

    /// The output an `Accept` header asks for, when one of its media types names exactly one.
    pub fn from_accept(accept: &str) -> Option<DepthMapOutput> {
        accept
            .split(',')
            .map(|m| {
                m.split(';')
                    .next()
                    .unwrap_or("")
                    .trim()
                    .to_ascii_lowercase()
            })
            .find_map(|m| match m.as_str() {
                "application/json" => Some(DepthMapOutput::Summary),
                PFM => Some(DepthMapOutput::DisparityPfm),
                PLY => Some(DepthMapOutput::PointsPly),
                NPZ => Some(DepthMapOutput::ArraysNpz),
                _ => None,
            })
    }
}

choice_members!(DepthMapOutput);

#[cfg(test)]
mod tests {
    use super::*;

    /// The wire's outputs are the engine's catalogue, the summary and the four ROS 2
    /// messages, no more and no less: each file the engine writes is an `output` of its own
    /// name that maps back to it, each CDR output is named by its serde name, and the OpenAPI
    /// schema's choices are those names.
    #[test]
    fn the_outputs_are_the_engines_catalogue() {
        for product in Product::ALL {
            let output: DepthMapOutput =
                serde_json::from_value(product.name().into()).expect("an output of its name");
            assert_eq!(output.product(), Some(product));
            assert_eq!(output.name(), product.name());
        }
        let schema = serde_json::to_value(<DepthMapOutput as utoipa::PartialSchema>::schema())
            .expect("a schema");
        let mut choices: Vec<String> =
            serde_json::from_value(schema["enum"].clone()).expect("the schema's choices");
        let ros = ["disparity.cdr", "depth.cdr", "depth_std.cdr", "points.cdr"];
        for name in ros {
            let output: DepthMapOutput = serde_json::from_value(name.into()).expect("an output");
            assert_eq!((output.name(), output.media_type()), (name, CDR));
            assert!(output.ros().is_some() && output.needs_rig() && output.is_file());
            assert_eq!(output.product(), None, "{name} is no engine file");
        }
        let mut names: Vec<String> = std::iter::once("summary")
            .chain(Product::ALL.map(Product::name))
            .chain(ros)
            .map(str::to_owned)
            .collect();
        choices.sort();
        names.sort();
        assert_eq!(choices, names);
    }
}
