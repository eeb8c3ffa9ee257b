//! The calibration as the files users load elsewhere: OpenCV's FileStorage YAML (as
//! `stereo_calib.cpp` writes `intrinsics.yml` and `extrinsics.yml`, in one file) and ROS
//! `camera_calibration`'s YAML per camera (lengths in metres, as ROS has them).

use std::fmt::Write;

use nalgebra::{Matrix3, Matrix3x4};

use crate::calibrate::{Board, Fit};
use crate::camera::{Camera, Model, Rectification};
use crate::physics::LengthUnit;

/// A number as both OpenCV's and our YAML readers take it (always with a `.` or an exponent).
fn num(v: f64) -> String {
    format!("{v:?}")
}

fn opencv_matrix(out: &mut String, name: &str, rows: usize, cols: usize, data: &[f64]) {
    let data: Vec<String> = data.iter().map(|&v| num(v)).collect();
    let _ = writeln!(
        out,
        "{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {} ]",
        data.join(", ")
    );
}

fn row_major3(m: &Matrix3<f64>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

fn row_major34(m: &Matrix3x4<f64>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

/// OpenCV FileStorage YAML with M1 D1 M2 D2 R T E F R1 R2 P1 P2 Q, `imageSize` and the board
/// (`cv2.FileStorage(path, cv2.FILE_STORAGE_READ).getNode("M1").mat()`). Lengths are in the
/// board's unit, which is recorded as `unit`.
pub fn opencv_yml(fit: &Fit, board: &Board, rect: &Rectification) -> Option<String> {
    let pair = fit.pair()?;
    let mut out = String::from("%YAML:1.0\n---\n");
    let _ = writeln!(
        out,
        "imageSize: [ {}, {} ]",
        fit.size.width, fit.size.height
    );
    let _ = writeln!(
        out,
        "boardSize: [ {}, {} ]\nsquareSize: {}\nunit: \"{}\"\ndistortionModel: \"{}\"",
        board.columns(),
        board.rows(),
        num(board.square_size()),
        board.unit().symbol(),
        fit.model.name()
    );
    for (k, camera) in [(1, &pair.left), (2, &pair.right)] {
        opencv_matrix(
            &mut out,
            &format!("M{k}"),
            3,
            3,
            &row_major3(&camera.matrix()),
        );
        let d = camera.distortion();
        opencv_matrix(
            &mut out,
            &format!("D{k}"),
            1,
            d.coefficients().len(),
            d.coefficients(),
        );
    }
    opencv_matrix(&mut out, "R", 3, 3, &row_major3(pair.rotation.matrix()));
    opencv_matrix(&mut out, "T", 3, 1, pair.translation.as_slice());
    opencv_matrix(&mut out, "E", 3, 3, &row_major3(&fit.essential()?));
    opencv_matrix(&mut out, "F", 3, 3, &row_major3(&fit.fundamental()?));
    opencv_matrix(&mut out, "R1", 3, 3, &row_major3(&rect.r1));
    opencv_matrix(&mut out, "R2", 3, 3, &row_major3(&rect.r2));
    opencv_matrix(&mut out, "P1", 3, 4, &row_major34(&rect.p1));
    opencv_matrix(&mut out, "P2", 3, 4, &row_major34(&rect.p2));
    opencv_matrix(&mut out, "Q", 4, 4, rect.q.transpose().as_slice());
    Some(out)
}

/// ROS `camera_calibration`'s YAML for one camera of the pair, as `camera_info_manager` reads
/// it: K, D with its model, the rectifying rotation and the rectified projection, whose
/// translation is in metres.
pub fn ros_yaml(
    camera: &Camera,
    name: &str,
    fit: &Fit,
    rotation: &Matrix3<f64>,
    projection: &Matrix3x4<f64>,
    unit: LengthUnit,
) -> String {
    let mut p = *projection;
    p[(0, 3)] = unit.convert(p[(0, 3)], LengthUnit::Metre);
    p[(1, 3)] = unit.convert(p[(1, 3)], LengthUnit::Metre);
    p[(2, 3)] = unit.convert(p[(2, 3)], LengthUnit::Metre);
    let list = |data: &[f64]| data.iter().map(|&v| num(v)).collect::<Vec<_>>().join(", ");
    let d = camera.distortion();
    let model = match d.model() {
        Model::PlumbBob => "plumb_bob",
        Model::RationalPolynomial => "rational_polynomial",
        Model::Equidistant => "equidistant",
    };
    format!(
        "image_width: {}\nimage_height: {}\ncamera_name: {name}\ncamera_matrix:\n  rows: 3\n  \
         cols: 3\n  data: [{}]\ndistortion_model: {model}\ndistortion_coefficients:\n  rows: 1\n  \
         cols: {}\n  data: [{}]\nrectification_matrix:\n  rows: 3\n  cols: 3\n  data: [{}]\n\
         projection_matrix:\n  rows: 3\n  cols: 4\n  data: [{}]\n",
        fit.size.width,
        fit.size.height,
        list(&row_major3(&camera.matrix())),
        d.coefficients().len(),
        list(d.coefficients()),
        list(&row_major3(rotation)),
        list(&row_major34(&p)),
    )
}
