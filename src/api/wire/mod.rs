//! The wire: every request and answer as JSON and the OpenAPI document see it, and their
//! translation from the engine's types. What they share: the deserialization rules and the
//! macros that declare request types with the common members ([`de`]), the members as stated
//! before validation ([`params`]), the measured values every distance answer carries
//! ([`measured`]), the rig's wire shapes ([`rig`]), the calibration options ([`calibration`]),
//! the `board` part ([`board`]),
//! what the image routes share on the wire ([`images`]), and the OpenAPI glue ([`openapi`]).
//! Then each endpoint's own types, one module a route (its `types`, as the route names it):
//! [`distance`], [`table`], [`chart`], [`rig_design`], [`file_calibration`], [`depth_map`] (its
//! outputs in [`depth_output`]),
//! [`depth_stream`], [`matching`], [`rectify`], [`board_calibration`] (its summary made in
//! [`calibration_summary`]), [`calibration_check`]. The command (`batch`) writes the same
//! `/depth-map` answers from them.

pub mod board;
pub mod board_calibration;
pub mod calibration;
pub mod calibration_check;
pub mod calibration_summary;
pub mod chart;
pub mod de;
pub mod depth_map;
pub mod depth_output;
pub mod depth_stream;
pub mod distance;
pub mod file_calibration;
pub mod images;
pub mod matching;
pub mod measured;
pub mod openapi;
pub mod params;
pub mod rectify;
pub mod rig;
pub mod rig_design;
pub mod table;
