//! The `board` part of `/calibrate`, `/board` and `/calibration/check`: a chessboard or a
//! ChArUco board read from its JSON, each fault named `board.<member>`.

use axum::body::Bytes;

use crate::api::error::FieldErrors;
use crate::api::extract;
use crate::api::wire::board_calibration::{BoardSpec, BoardType};
use stereo_core::pipeline::calibrate as engine;

/// A `board` part as the messages show it.
const BOARD_EXAMPLE: &str = r#"{"columns": 9, "rows": 6, "square_size": 25, "unit": "mm"}"#;

/// A chessboard's own members, and a ChArUco board's.
const CHESSBOARD: [&str; 2] = ["columns", "rows"];
const CHARUCO: [&str; 5] = [
    "squares_x",
    "squares_y",
    "marker_size",
    "dictionary",
    "legacy",
];

/// The `board` part read into a target, each fault named `board.<member>`: the members its
/// type needs, the members of the other type, and every value out of its bounds.
pub fn read_board(bytes: Option<&Bytes>, problems: &mut FieldErrors) -> Option<engine::Target> {
    let Some(bytes) = bytes else {
        problems.add(
            "board",
            format!("is required: JSON such as {BOARD_EXAMPLE} (inner corners)"),
        );
        return None;
    };
    let Ok((spec, refused)) = extract::decode_json::<BoardSpec>(bytes) else {
        problems.add(
            "board",
            format!(
                "must be a JSON object such as {BOARD_EXAMPLE} (inner corners), not `{}`",
                stereo_core::numbers::clip(&String::from_utf8_lossy(bytes), 40)
            ),
        );
        return None;
    };
    let mut faulty = !refused.is_empty();
    problems.extend(FieldErrors::from(refused.prefixed("board.")));
    let charuco = spec.board_type.unwrap_or_default() == BoardType::Charuco;
    faulty |= members(&spec, charuco, problems);
    // The members that were read are judged even when others were missing or refused, so
    // that every fault is named at once; an absent member is judged as a valid stand-in.
    let judged = judge(&spec, charuco);
    match judged {
        Ok(target) => (!faulty).then_some(target),
        Err(faults) => {
            for (member, message) in faults {
                let name = format!("board.{member}");
                if !problems.has(&name) {
                    problems.add(&name, message);
                }
            }
            None
        }
    }
}

/// Names each member the board's type needs that is missing and each member of the other
/// type that is given; whether any was.
fn members(spec: &BoardSpec, charuco: bool, problems: &mut FieldErrors) -> bool {
    let mut faulty = false;
    let given = |member: &str| match member {
        "columns" => spec.columns.is_some(),
        "rows" => spec.rows.is_some(),
        "square_size" => spec.square_size.is_some(),
        "squares_x" => spec.squares_x.is_some(),
        "squares_y" => spec.squares_y.is_some(),
        "marker_size" => spec.marker_size.is_some(),
        "dictionary" => spec.dictionary.is_some(),
        _ => spec.legacy.is_some(),
    };
    let (needed, foreign): (&[&str], &[&str]) = if charuco {
        (
            &[
                "squares_x",
                "squares_y",
                "square_size",
                "marker_size",
                "dictionary",
            ],
            &CHESSBOARD,
        )
    } else {
        (&["columns", "rows", "square_size"], &CHARUCO)
    };
    for member in needed {
        let name = format!("board.{member}");
        if !given(member) && !problems.has(&name) {
            problems.add(&name, "is required");
            faulty = true;
        }
    }
    for member in foreign.iter().filter(|m| given(m)) {
        problems.add(
            &format!("board.{member}"),
            if charuco {
                "is a chessboard's member: a ChArUco board counts its squares (squares_x, \
                 squares_y)"
            } else {
                "is a ChArUco board's member: give \"type\": \"charuco\" with it"
            },
        );
        faulty = true;
    }
    faulty
}

/// The board the members describe (an absent member judged as a valid stand-in), or each
/// fault as its member's name and message.
fn judge(spec: &BoardSpec, charuco: bool) -> Result<engine::Target, Vec<(&'static str, String)>> {
    let unit = spec.unit.unwrap_or_default().into();
    let square = spec.square_size.unwrap_or_else(|| {
        spec.marker_size
            .filter(|m| m.is_finite() && *m > 0.0)
            .map_or(1.0, |m| 2.0 * m)
    });
    if charuco {
        engine::CharucoBoard::new(engine::CharucoSpec {
            squares_x: spec.squares_x.unwrap_or(5),
            squares_y: spec.squares_y.unwrap_or(5),
            square_size: square,
            marker_size: spec.marker_size.unwrap_or(square / 2.0),
            dictionary: spec
                .dictionary
                .map_or(engine::Dictionary::Dict6x6_250, Into::into),
            legacy: spec.legacy.unwrap_or(false),
            unit,
        })
        .map(engine::Target::Charuco)
        .map_err(|faults| {
            faults
                .into_iter()
                .map(|f| (f.member.name(), f.message))
                .collect::<Vec<_>>()
        })
    } else {
        engine::Board::new(
            spec.columns.unwrap_or(9),
            spec.rows.unwrap_or(6),
            square,
            unit,
        )
        .map(engine::Target::Chessboard)
        .map_err(|faults| {
            faults
                .into_iter()
                .map(|f| (f.member.name(), f.message))
                .collect::<Vec<_>>()
        })
    }
}
