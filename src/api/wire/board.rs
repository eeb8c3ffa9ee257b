//! The `board` part as `/calibrate`, `/board` and `/calibration/check` take it (a chessboard
//! or a ChArUco board), and the board as a summary gives it back.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::wire::de::{choice_members, request};
use crate::api::wire::params::Unit;
use stereo_core::pipeline::calibrate as engine;

/// The kind of board printed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum BoardType {
    /// A chessboard, found whole in each view (`columns` × `rows` inner corners).
    #[default]
    Chessboard,
    /// A ChArUco board (OpenCV's `CharucoBoard`): a chessboard with ArUco markers in its
    /// white squares, so that a view showing part of it counts.
    Charuco,
}

/// A ChArUco board's ArUco dictionary, by OpenCV's name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
pub enum DictionaryName {
    #[serde(rename = "DICT_4X4_50")]
    Dict4x4_50,
    #[serde(rename = "DICT_5X5_100")]
    Dict5x5_100,
    #[serde(rename = "DICT_6X6_250")]
    Dict6x6_250,
    #[serde(rename = "DICT_ARUCO_ORIGINAL")]
    ArucoOriginal,
}

impl From<DictionaryName> for engine::Dictionary {
    fn from(d: DictionaryName) -> Self {
        match d {
            DictionaryName::Dict4x4_50 => engine::Dictionary::Dict4x4_50,
            DictionaryName::Dict5x5_100 => engine::Dictionary::Dict5x5_100,
            DictionaryName::Dict6x6_250 => engine::Dictionary::Dict6x6_250,
            DictionaryName::ArucoOriginal => engine::Dictionary::ArucoOriginal,
        }
    }
}

impl From<engine::Dictionary> for DictionaryName {
    fn from(d: engine::Dictionary) -> Self {
        match d {
            engine::Dictionary::Dict4x4_50 => DictionaryName::Dict4x4_50,
            engine::Dictionary::Dict5x5_100 => DictionaryName::Dict5x5_100,
            engine::Dictionary::Dict6x6_250 => DictionaryName::Dict6x6_250,
            engine::Dictionary::ArucoOriginal => DictionaryName::ArucoOriginal,
        }
    }
}

request! {
    /// The printed board. A chessboard (the default): its inner corners (as OpenCV's
    /// `patternSize`) and its squares' side. A ChArUco board (`"type": "charuco"`): OpenCV's
    /// `CharucoBoard` terms, its squares along x and y, the square and marker sides, the
    /// dictionary and the legacy pattern; its corners' ids and positions are OpenCV's.
    #[schema(example = json!({"columns": 9, "rows": 6, "square_size": 25, "unit": "mm"}))]
    pub struct BoardSpec {
        /// `chessboard` (default) or `charuco`.
        #[serde(rename = "type")]
        board_type: BoardType,
        /// A chessboard's inner corners along a row (3 to 64).
        #[schema(minimum = 3, maximum = 64)]
        columns: u32,
        /// A chessboard's inner corners along a column (3 to 64).
        #[schema(minimum = 3, maximum = 64)]
        rows: u32,
        /// A square's side, in `unit`.
        #[schema(required = true, exclusive_minimum = 0.0)]
        square_size: f64,
        /// The unit of `square_size`, `marker_size` and of the translation and baseline
        /// answered (default `mm`).
        unit: Unit,
        /// A ChArUco board's squares along x (3 to 65; OpenCV's `size.width`).
        #[schema(minimum = 3, maximum = 65)]
        squares_x: u32,
        /// A ChArUco board's squares along y (3 to 65; OpenCV's `size.height`).
        #[schema(minimum = 3, maximum = 65)]
        squares_y: u32,
        /// A ChArUco marker's side, in `unit`, smaller than `square_size`.
        #[schema(exclusive_minimum = 0.0)]
        marker_size: f64,
        /// A ChArUco board's ArUco dictionary.
        dictionary: DictionaryName,
        /// OpenCV's legacy ChArUco pattern (`setLegacyPattern(true)`, boards made before
        /// OpenCV 4.6.0): for an even number of rows, the top-left square is white. Default
        /// false.
        legacy: bool,
    }
}

/// The board as used: its inner corners (for a ChArUco board, its squares less one each
/// way) and, for a ChArUco board, its own terms.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BoardUsed {
    #[serde(rename = "type")]
    pub board_type: BoardType,
    pub columns: u32,
    pub rows: u32,
    pub square_size: f64,
    pub unit: Unit,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub squares_x: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub squares_y: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub marker_size: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub dictionary: Option<DictionaryName>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub legacy: Option<bool>,
}

choice_members!(BoardType, DictionaryName);
