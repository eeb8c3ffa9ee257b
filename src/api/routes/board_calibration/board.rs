//! The `board` part of `/calibrate`: a chessboard or a ChArUco board read from its JSON, each
//! fault named `board.<member>`; and the engine's faults as 422s naming the board's members or
//! the views.

use axum::body::Bytes;

use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::extract;
use crate::api::images::limits;
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

/// The engine's fault as the answer names it: the views that cannot be decoded, the board's
/// members most images contradict, each view whose board was not found with the fit's fault,
/// or why the views do not determine the calibration.
pub fn fault(fault: engine::CalibrateFault, allowed: engine::DecodeLimits) -> ApiError {
    match fault {
        engine::CalibrateFault::Abandoned => {
            ApiError::Internal("the calibration was abandoned".to_owned())
        }
        engine::CalibrateFault::Undecodable(views) => ApiError::Invalid(
            views
                .into_iter()
                .map(|(view, e)| FieldError::new(view, limits::describe(&e, allowed)))
                .collect(),
        ),
        engine::CalibrateFault::OtherBoardSize {
            board,
            found,
            showing,
            images,
        } => size_mistake(&board, found, showing, images),
        engine::CalibrateFault::Charuco {
            board,
            mistake,
            images,
        } => charuco_mistake(&board, &mistake, images),
        engine::CalibrateFault::Fit {
            fault,
            reasons,
            views,
        } => {
            let mut errors = Vec::new();
            for (i, [l, r]) in reasons.iter().enumerate() {
                for (side, reason) in [("left", l), ("right", r)] {
                    if let Some(reason) = reason {
                        errors.push(FieldError::new(
                            format!("{side}[{i}]"),
                            format!("board not found: {reason}"),
                        ));
                    }
                }
            }
            errors.push(FieldError::new(
                "left",
                format!("{fault} (of {views} views sent)"),
            ));
            ApiError::Invalid(errors)
        }
        engine::CalibrateFault::Refused { cause, views } => {
            ApiError::Invalid(vec![FieldError::new(
                "left",
                format!("refused, {cause} (of {views} views sent)"),
            )])
        }
        engine::CalibrateFault::NotRectifiable => ApiError::Invalid(vec![FieldError::new(
            "right",
            "the calibrated pair cannot be rectified (the cameras do not overlap)",
        )]),
    }
}

/// Most images show a whole chessboard of another size than the board's: one 422 naming
/// each member that differs, with the size found.
fn size_mistake(
    board: &engine::Board,
    (columns, rows): (usize, usize),
    showing: usize,
    images: usize,
) -> ApiError {
    let (given_columns, given_rows) = (board.columns() as usize, board.rows() as usize);
    let mut errors = Vec::new();
    for (member, given, found) in [
        ("columns", given_columns, columns),
        ("rows", given_rows, rows),
    ] {
        if given != found {
            errors.push(FieldError::new(
                format!("board.{member}"),
                format!(
                    "is {given}, but {showing} of the {images} images show {found} this way: a \
                     chessboard of {columns} × {rows} inner corners, where the board says \
                     {given_columns} × {given_rows}. Count the inner corners (where four squares \
                     meet), not the squares: a board of 10 × 7 squares has 9 × 6"
                ),
            ));
        }
    }
    ApiError::Invalid(errors)
}

/// Most images say the ChArUco board was printed otherwise than described: one 422 naming
/// the members to correct.
fn charuco_mistake(
    board: &engine::CharucoBoard,
    mistake: &engine::CharucoMistake,
    images: usize,
) -> ApiError {
    let (x, y) = board.squares();
    let markers = board.marker_squares().len();
    let dictionary = board.dictionary().name();
    let errors = match *mistake {
        engine::CharucoMistake::Larger {
            highest,
            images: showing,
        } => {
            let why = format!(
                "a board of {x} × {y} squares has {markers} markers (ids 0 to {}) of {dictionary}, \
                 but {showing} of the {images} images show markers up to id {highest}, which it \
                 does not have. Give the board's squares along each side (OpenCV's squaresX × \
                 squaresY), not its inner corners",
                markers.saturating_sub(1)
            );
            vec![
                FieldError::new("board.squares_x", format!("is {x}: {why}")),
                FieldError::new("board.squares_y", format!("is {y}: {why}")),
            ]
        }
        engine::CharucoMistake::Dictionary {
            dictionary: other,
            images: showing,
        } => vec![FieldError::new(
            "board.dictionary",
            format!(
                "is {dictionary}, but {showing} of the {images} images show none of its markers \
                 and markers of {}: give the dictionary the board was printed with",
                other.name()
            ),
        )],
    };
    ApiError::Invalid(errors)
}
