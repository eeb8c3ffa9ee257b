//! The wire types of `/depth-map`: the multipart form (documentation), the query's options, and
//! the JSON summary.

use std::time::Duration;

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::extract::QueryForm;
use crate::api::wire::de::{choice_members, latlon_request};
pub use crate::api::wire::depth_output::{CDR, DepthMapOutput, RosOutput};
use crate::api::wire::images::FileBody;
use crate::api::wire::images::image_form;
pub use crate::api::wire::images::{
    LatlonSystem, ProjectionAsked, ProjectionChoice, RectifyMode, StageTimes,
};
use crate::api::wire::openapi::{image_answers, named};
use crate::api::wire::rig::CalibratedRig;
use stereo_core::pipeline::{self, DepthMap};

use stereo_core::vision::{Params, Preset, RangeEnd, Settings, Subpixel};

/// How the disparity is refined between whole pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum SubpixelChoice {
    /// Whole pixels.
    Off,
    /// A parabola through the best cost and its neighbours (OpenCV's fit).
    Parabola,
    /// The equiangular (V) fit, which locks less to whole pixels (the default).
    Equiangular,
}

impl From<SubpixelChoice> for Subpixel {
    fn from(c: SubpixelChoice) -> Self {
        match c {
            SubpixelChoice::Off => Subpixel::Off,
            SubpixelChoice::Parabola => Subpixel::Parabola,
            SubpixelChoice::Equiangular => Subpixel::Equiangular,
        }
    }
}

impl From<Subpixel> for SubpixelChoice {
    fn from(s: Subpixel) -> Self {
        match s {
            Subpixel::Off => SubpixelChoice::Off,
            Subpixel::Parabola => SubpixelChoice::Parabola,
            Subpixel::Equiangular => SubpixelChoice::Equiangular,
        }
    }
}

/// A named set of the matcher's settings: what a setting not given takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum PresetChoice {
    /// The most accurate maps (the default): 8 paths where the pair is noisy, 5 where its
    /// texture stands well above its noise, and a 3 × 3 median.
    Accurate,
    /// For video: one pass on every pair (the 4 paths from above and the left on a clear
    /// pair, and the path from the right too on a noisy one) and no median, for less time.
    Fast,
}

impl From<PresetChoice> for Preset {
    fn from(c: PresetChoice) -> Self {
        match c {
            PresetChoice::Accurate => Preset::Accurate,
            PresetChoice::Fast => Preset::Fast,
        }
    }
}

impl From<Preset> for PresetChoice {
    fn from(p: Preset) -> Self {
        match p {
            Preset::Accurate => PresetChoice::Accurate,
            Preset::Fast => PresetChoice::Fast,
        }
    }
}

choice_members!(SubpixelChoice, PresetChoice);

/// What `max_disparity` means, on `/depth-map`, `/match` and the stream.
pub const RANGE_END: &str = "The search stops before this disparity: `min_disparity ≤ d < \
     max_disparity`, at most 512 disparities. `auto` finds it from the pair (its coarse view's \
     nearest matches with a margin; the answer's `disparity_range` says what was searched and \
     why). Default: the calibration file's `ndisp` when one is given, else `auto`.";

/// [`RANGE_END`]'s schema.
pub fn range_end() -> utoipa::openapi::schema::Schema {
    super::de::max_disparity_schema(RANGE_END)
}

/// What `min_disparity` means, on `/depth-map`, `/match` and the stream.
pub const RANGE_START: &str = "The smallest disparity searched, in pixels. `auto` finds it \
     from the pair: its coarse view's farthest matches less a margin, rounded down to 16 and \
     never below 0, so that a scene near everywhere is not searched from 0 (the pixels short of \
     it are refused). Default: `auto` where `max_disparity` is found, else 0.";

/// [`RANGE_START`]'s schema.
pub fn range_start() -> utoipa::openapi::schema::Schema {
    super::de::min_disparity_schema(RANGE_START)
}

latlon_request! {
    /// The options of `/depth-map`, in the query string.
    pub struct DepthMapQuery {
        /// The smallest disparity searched ([`RANGE_START`]).
        #[schema(schema_with = range_start)]
        min_disparity: RangeEnd,
        /// The search stops before this disparity: `min_disparity ≤ d < max_disparity`, at
        /// most 512 disparities ([`RANGE_END`]).
        #[schema(schema_with = range_end)]
        max_disparity: RangeEnd,
        /// What to answer (default `summary`); also chosen by `Accept` for
        /// `application/json`, `image/x-portable-floatmap` and `application/x-ply`.
        #[schema(inline, default = "summary")]
        output: DepthMapOutput,
        /// The named set of matcher settings that the settings not given take: `accurate`
        /// (the default) or `fast` (for video). A setting given wins over its preset's.
        #[schema(inline, default = "accurate")]
        preset: PresetChoice,
        /// The paths the aggregation sums: 8 (two passes, the most robust to noise), 5 (one
        /// pass) or 4 (one pass, none from the right). Default: the preset's (`accurate` takes 8
        /// on a noisy pair and 5 on a clear one, `fast` always 4).
        #[schema(minimum = 4, maximum = 8, example = 5)]
        paths: u32,
        /// Fill invalid pixels from their row's background (the smaller of the nearest valid
        /// disparities left and right) instead of leaving them invalid; each filled pixel's
        /// σ_d is half the spread of the values it was chosen from (at least 0.7 px), and
        /// `arrays.npz` marks them (`filled`). Default false.
        #[schema(default = false)]
        fill: bool,
        /// SGM penalty for a disparity step of one pixel, in census bits. Default 16.
        #[schema(minimum = 1, maximum = 255, default = 16)]
        p1: u32,
        /// SGM penalty for a larger jump, in census bits, where the intensity is flat.
        /// Default 64.
        #[schema(minimum = 2, maximum = 1024, default = 64)]
        p2: u32,
        /// The intensity step (grey levels of 255) across which `p2` is halved:
        /// P2' = max(P1 + 1, P2 · T / (T + |ΔI|)); 0 keeps P2 constant. Default 16.
        #[schema(minimum = 0, maximum = 255, default = 16)]
        p2_edge: u32,
        /// How much lower (in percent) the best cost must be than any other more than one
        /// pixel away; otherwise the pixel is invalid. Default 15.
        #[schema(minimum = 0, maximum = 100, default = 15)]
        uniqueness: u32,
        /// The left-right check: whether to run it. Default true.
        #[schema(default = true)]
        lr_check: bool,
        /// The left-right check's tolerance in pixels. Default 1.
        #[schema(minimum = 0.0, maximum = 64.0, default = 1.0)]
        lr_tolerance: f64,
        /// The sub-pixel fit. Default `equiangular`.
        #[schema(inline, default = "equiangular")]
        subpixel: SubpixelChoice,
        /// Regions with fewer pixels than this are removed as speckles; 0 keeps them.
        /// Default 100.
        #[schema(minimum = 0, maximum = 1000000, default = 100)]
        speckle_size: u32,
        /// Neighbours whose disparities differ by at most this many pixels are one region.
        /// Default 2.
        #[schema(exclusive_minimum = 0.0, maximum = 64.0, default = 2.0)]
        speckle_range: f64,
        /// The keep rule: a pixel whose disparity's σ_d (the `disparity_std` outputs) exceeds
        /// this many pixels is dropped (before `fill`). Default 4, which drops only the values
        /// known to ±4 px or worse; 0.5 keeps only sure pixels. To judge the pixels by σ_d alone,
        /// also set `uniqueness=0` and `speckle_size=0`.
        #[schema(exclusive_minimum = 0.0, maximum = 64.0, example = 1.0, default = 4.0)]
        max_disparity_std: f64,
        /// A 3 × 3 median filter of the result. Default true.
        #[schema(default = true)]
        median: bool,
        /// Rectify the pair first: `auto` (the default) when the calibration describes raw
        /// cameras (a stereoCalibrate file, a ROS CameraInfo pair with D K R P, KITTI's raw
        /// calib_cam_to_cam.txt, /calibrate's opencv.yml) and the frames are their raw size;
        /// `yes`, or `no`. A rectified pair's outputs are in the rectified left camera's
        /// frame and size.
        #[schema(inline, default = "auto")]
        rectify: RectifyMode,
        /// With rectification: recompute it as `cv2.stereoRectify` does with this `alpha`
        /// (0 only valid pixels, 1 every raw pixel). Default: the file's own, or 0.
        #[schema(minimum = 0.0, maximum = 1.0)]
        alpha: f64,
        /// With rectification: the rectified projection, `pinhole` (default), `latlon`
        /// (wide and fisheye lenses, as `/rectify`'s; the map is then in azimuth and
        /// elevation, the depths along the rectified axis) or `auto` (latlon where the
        /// cameras see wider than 100°, pinhole for the ROS outputs; the summary says which).
        #[schema(inline, default = "pinhole")]
        projection: ProjectionAsked,
    }
}

impl QueryForm for DepthMapQuery {}

impl DepthMapQuery {
    /// The matcher's settings the query asks for.
    pub fn settings(&self) -> Settings {
        Settings {
            min_disparity: self.min_disparity,
            max_disparity: self.max_disparity,
            p1: self.p1,
            p2: self.p2,
            p2_edge: self.p2_edge,
            uniqueness: self.uniqueness,
            lr_check: self.lr_check,
            lr_tolerance: self.lr_tolerance,
            subpixel: self.subpixel.map(Into::into),
            speckle_size: self.speckle_size,
            speckle_range: self.speckle_range,
            max_disparity_std: self.max_disparity_std,
            median: self.median,
            fill: self.fill,
            paths: self.paths,
            preset: self.preset.map(Into::into),
            ..Settings::default()
        }
    }
}

image_form! {
    /// The `multipart/form-data` parts of `/depth-map` (for the documentation: the handler
    /// reads the parts itself, to name each one in its errors). Give `rig` or `calibration`
    /// for depth outputs.
    pub struct DepthMapForm {}
}

/// The smallest, median and largest of the valid values, to 4 decimals.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Spread {
    pub min: f64,
    /// NumPy's median (`numpy.nanmedian` of the NPY and NPZ outputs): the middle value, or
    /// the mean of the two middle ones of an even count.
    pub median: f64,
    pub max: f64,
}

impl From<pipeline::Spread> for Spread {
    fn from(s: pipeline::Spread) -> Self {
        Spread {
            min: s.min,
            median: s.median,
            max: s.max,
        }
    }
}

/// How a depth map's or a match's disparity range was chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum RangeChosen {
    /// `max_disparity` (or the calibration file's `ndisp`).
    Given,
    /// Found from the pair: its coarse view's nearest matches, with a margin.
    Found,
    /// The default 0 .. 128: too little of the pair matched to find it.
    Default,
}

/// The range searched and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RangeAnswer {
    pub chosen: RangeChosen,
    /// Why, in a sentence.
    pub why: String,
}

impl From<&pipeline::RangeUsed> for RangeAnswer {
    fn from(used: &pipeline::RangeUsed) -> Self {
        RangeAnswer {
            chosen: match used.chosen {
                pipeline::Chosen::Given => RangeChosen::Given,
                pipeline::Chosen::Found { .. } => RangeChosen::Found,
                pipeline::Chosen::Default => RangeChosen::Default,
            },
            why: used.why(),
        }
    }
}

impl DepthMapSummary {
    /// The summary of a depth map matched with `params` from a pair that took `decode` to
    /// read, with the rig it used echoed.
    pub fn of(
        map: &DepthMap,
        params: &Params,
        rig: Option<CalibratedRig>,
        decode: Duration,
    ) -> Self {
        let ms = |d: Duration| (d.as_secs_f64() * 1e4).round() / 10.0;
        let d = &map.disparity;
        let t = &map.timings;
        let spreads = pipeline::Spreads::of(map);
        DepthMapSummary {
            width: d.width,
            height: d.height,
            min_disparity: map.range.min,
            max_disparity: map.range.max,
            disparity_range: RangeAnswer::from(&map.range),
            valid_fraction: (map.valid_fraction * 1e4).round() / 1e4,
            disparity_px: spreads.disparity.map(Spread::from),
            distance: spreads.depth.map(Spread::from),
            disparity_std_px: spreads.disparity_std.map(Spread::from),
            distance_std: spreads.depth_std.map(Spread::from),
            rig,
            parameters: MatcherParameters::of(params, t.paths),
            timings_ms: StageTimes {
                decode: ms(decode),
                cost: ms(t.cost),
                aggregate: ms(t.aggregate),
                refine: ms(t.refine),
                rectify: map.rectify.map(ms),
            },
            rectified: map.rectify.is_some(),
            projection: match map.latlon {
                Some(_) => ProjectionChoice::Latlon,
                None => ProjectionChoice::Pinhole,
            },
            latlon: map
                .latlon
                .as_ref()
                .zip(map.rig)
                .map(|(l, r)| LatlonSystem::of(l, r.unit())),
            warnings: map.said(),
        }
    }
}

impl MatcherParameters {
    /// The parameters a match used, with the paths its finest level aggregated.
    pub fn of(params: &Params, paths: Option<pipeline::Paths>) -> Self {
        MatcherParameters {
            preset: params.preset().into(),
            paths: paths.map_or(8, pipeline::Paths::count),
            p1: params.penalties().p1.into(),
            p2: params.penalties().p2.into(),
            p2_edge: params.penalties().edge.into(),
            uniqueness: params.uniqueness(),
            lr_tolerance: params.lr_tolerance().map(f64::from),
            subpixel: params.subpixel().into(),
            speckle_size: params.speckle_size() as u32,
            speckle_range: f64::from(params.speckle_range()),
            max_disparity_std: params.max_disparity_std(),
            median: params.median(),
            fill: params.fill(),
        }
    }
}

/// The matcher's parameters as used.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct MatcherParameters {
    /// The preset the settings not given came from.
    pub preset: PresetChoice,
    /// The paths aggregated, 4, 5 or 8 (decided by the pair's noise where not given).
    pub paths: u32,
    pub p1: u32,
    pub p2: u32,
    pub p2_edge: u32,
    pub uniqueness: u32,
    /// The left-right tolerance in pixels; absent when the check was off.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub lr_tolerance: Option<f64>,
    pub subpixel: SubpixelChoice,
    pub speckle_size: u32,
    pub speckle_range: f64,
    /// The keep rule's largest σ_d, in pixels.
    pub max_disparity_std: f64,
    pub median: bool,
    pub fill: bool,
}

/// The depth map in numbers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({
    "width": 741, "height": 500, "min_disparity": 0, "max_disparity": 64, "disparity_range": {"chosen": "given", "why": "given: max_disparity (or the calibration file's ndisp)"}, "rectified": false, "projection": "pinhole",
    "valid_fraction": 0.859,
    "disparity_px": {"min": 3.21, "median": 28.4, "max": 61.9},
    "distance": {"min": 1196.1, "median": 3215.0, "max": 14987.2},
    "disparity_std_px": {"min": 0.155, "median": 0.262, "max": 4.1},
    "distance_std": {"min": 2.1, "median": 28.6, "max": 2210.4},
    "rig": {"focal_length_px": 994.978, "baseline": 193.001, "unit": "mm", "cx": 311.193,
            "cy": 254.877, "doffs": 31.086, "image_width": 741, "image_height": 500},
    "parameters": {"preset": "accurate", "paths": 5, "p1": 16, "p2": 64, "p2_edge": 16, "uniqueness": 15, "lr_tolerance": 1.0,
                   "subpixel": "equiangular", "speckle_size": 100, "speckle_range": 2.0,
                   "max_disparity_std": 4.0, "median": true, "fill": false},
    "timings_ms": {"decode": 14.2, "cost": 9.8, "aggregate": 41.0, "refine": 18.3},
    "warnings": []
}))]
pub struct DepthMapSummary {
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// The smallest disparity searched.
    pub min_disparity: i32,
    /// The search stopped before this disparity.
    pub max_disparity: i32,
    /// How the disparity range was chosen: given, found from the pair, or the default.
    pub disparity_range: RangeAnswer,
    /// The share of pixels with a disparity, in [0, 1].
    pub valid_fraction: f64,
    /// The valid disparities, in pixels; absent when none is valid.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub disparity_px: Option<Spread>,
    /// The depths Z = B·f / (d + doffs) of the valid pixels, in the rig's unit; absent without
    /// a rig or when none is valid.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub distance: Option<Spread>,
    /// The valid pixels' σ_d (each disparity's standard deviation), in pixels; absent when
    /// none is valid.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub disparity_std_px: Option<Spread>,
    /// The valid pixels' σ_Z (each depth's standard deviation, with the rig's σ_f and σ_B),
    /// in the rig's unit; absent without a rig or when none is valid.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub distance_std: Option<Spread>,
    /// The rig used, when one was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub rig: Option<CalibratedRig>,
    pub parameters: MatcherParameters,
    pub timings_ms: StageTimes,
    /// Whether the raw pair was rectified here first; the maps and the size are then the
    /// rectified left camera's.
    pub rectified: bool,
    /// The rectified projection the map is in; for `latlon`, its system (its columns are
    /// azimuth and rows elevation; `rig` is then the latlon pair's at its centre column).
    pub projection: ProjectionChoice,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub latlon: Option<LatlonSystem>,
    /// Things to know about the answer (such as a calibration option that did not apply).
    pub warnings: Vec<String>,
}

image_answers! {
    /// `/depth-map`'s responses: the map in the `output` asked for, or the errors.
    pub struct DepthMapAnswers: "The depth map in the `output` asked for." {
        "application/json" => named::<DepthMapSummary>(),
        "image/png" => named::<FileBody>(),
        "image/x-portable-floatmap" => named::<FileBody>(),
        "application/x-npy" => named::<FileBody>(),
        "application/x-ply" => named::<FileBody>(),
        "application/zip" => named::<FileBody>(),
        "application/x-cdr" => named::<FileBody>(),
    }
}
