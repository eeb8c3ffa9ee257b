//! `/calibrate`'s faults: the engine's as 422s naming the board's members or the views (the
//! `board` part itself is read by [`crate::api::images::board`]).

use crate::api::error::{ApiError, FieldError};
use crate::api::images::limits;
use stereo_core::pipeline::calibrate as engine;

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
        engine::CalibrateFault::InitialNeedsPair => ApiError::Invalid(vec![FieldError::new(
            "initial",
            "calibrates a pair again: send a right image for each left one",
        )]),
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
