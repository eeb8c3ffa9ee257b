//! `stereoRectify` against OpenCV 4.14's own numbers for one plumb_bob pair (produced by
//! `cv2.stereoRectify` on the inputs below; the script is in the comment of each test), and
//! against the geometry it promises for any pair.

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::*;
use crate::physics::LengthUnit;

const SIZE: Size = Size {
    width: 640,
    height: 480,
};

fn close(label: &str, ours: &[f64], theirs: &[f64], tolerance: f64) {
    for (i, (a, b)) in ours.iter().zip(theirs).enumerate() {
        assert!(
            (a - b).abs() <= tolerance,
            "{label}[{i}]: ours {a}, OpenCV {b} (±{tolerance})"
        );
    }
}

fn rows(m: &Matrix3<f64>) -> Vec<f64> {
    m.transpose().iter().copied().collect()
}

/// R1 and R2 equal OpenCV's to 1e-12, and for alpha 0, 0.5 and 1 the focal length, the
/// principal point, P2's T·f and Q equal OpenCV's within 0.01 px (OpenCV undistorts the
/// corners in 5 fixed-point steps and averages them in float), the ROIs within a pixel.
#[test]
fn stereo_rectify_reproduces_opencv() {
    // (alpha, f, P2[0][3], roi_left, roi_right) from cv2.stereoRectify(..., alpha=alpha,
    // flags=cv2.CALIB_ZERO_DISPARITY); cx, cy = 316.40111923217773, 241.54851913452148.
    let cases = [
        (
            0.0,
            831.9577121731737,
            -99866.11900175788,
            [0, 0, 639, 480],
            [0, 0, 640, 480],
        ),
        (
            1.0,
            726.6555664619012,
            -87225.91330275303,
            [10, 20, 588, 435],
            [38, 23, 592, 438],
        ),
        (
            0.5,
            779.3066393175375,
            -93546.01615225546,
            [0, 4, 618, 467],
            [18, 8, 622, 470],
        ),
    ];
    let r1 = [
        0.9997817050724968,
        -0.02087878374203865,
        -0.0007865060612800862,
        0.02087358996149439,
        0.9997634124262786,
        -0.006116568963248318,
        0.0009140265043462627,
        0.006098816542244514,
        0.9999809843153685,
    ];
    let r2 = [
        0.9996876464081227,
        -0.014995314696125403,
        0.019993752928164327,
        0.014872903025206257,
        0.9998698135718221,
        0.006257208918730029,
        -0.020084978829740488,
        -0.005957889308638627,
        0.9997805245054511,
    ];
    for (alpha, f, tf, roi_l, roi_r) in cases {
        let options = RectifyOptions {
            alpha: Alpha::new(alpha).unwrap(),
            ..RectifyOptions::default()
        };
        let r = stereo_rectify(&opencv_pair(), SIZE, options).unwrap();
        close("R1", &rows(&r.r1), &r1, 1e-12);
        close("R2", &rows(&r.r2), &r2, 1e-12);
        let (cx, cy) = (316.40111923217773, 241.54851913452148);
        close(
            "P1",
            &[r.p1[(0, 0)], r.p1[(1, 1)], r.p1[(0, 2)], r.p1[(1, 2)]],
            &[f, f, cx, cy],
            0.01,
        );
        close("P2", &[r.p2[(0, 2)], r.p2[(1, 2)]], &[cx, cy], 0.01);
        close("P2 T·f", &[r.p2[(0, 3)]], &[tf], 0.01 * 120.0);
        close(
            "Q",
            &[
                r.q[(0, 3)],
                r.q[(1, 3)],
                r.q[(2, 3)],
                r.q[(3, 2)],
                r.q[(3, 3)],
            ],
            &[-cx, -cy, f, 0.008330730386734358, 0.0],
            0.01,
        );
        let roi = |r: Roi| [r.x, r.y, r.width, r.height];
        for (ours, theirs) in [(roi(r.roi_left), roi_l), (roi(r.roi_right), roi_r)] {
            for (a, b) in ours.iter().zip(theirs) {
                assert!(
                    (a - b).abs() <= 1,
                    "alpha {alpha}: ROI {ours:?} vs OpenCV {theirs:?}"
                );
            }
        }
    }
}

/// Without `CALIB_ZERO_DISPARITY` only the rows are shared: OpenCV's cx 332.891 and
/// 299.911, cy 241.549 and f 809.026 at alpha 0.
#[test]
fn without_zero_disparity_the_principal_points_differ_in_x() {
    let options = RectifyOptions {
        zero_disparity: false,
        ..RectifyOptions::default()
    };
    let r = stereo_rectify(&opencv_pair(), SIZE, options).unwrap();
    close(
        "P1, P2",
        &[
            r.p1[(0, 0)],
            r.p1[(0, 2)],
            r.p1[(1, 2)],
            r.p2[(0, 2)],
            r.p2[(1, 2)],
        ],
        &[
            809.0264214874645,
            332.89137268066406,
            241.54851913452148,
            299.9108657836914,
            241.54851913452148,
        ],
        0.01,
    );
    let rig = r.rig(LengthUnit::Millimetre).unwrap();
    assert!((rig.doffs() - (299.9108657836914 - 332.89137268066406)).abs() < 0.02);
}

/// For any pair the construction promises: a 3D point seen by both raw cameras lands on the
/// same row of both rectified images, and the rectified rig's Z = B·f/(d + doffs) is the
/// point's depth in the left rectified camera, for every model.
#[test]
fn rectified_rows_agree_and_the_rig_gives_the_depth() {
    let fisheye = Camera::new(
        Intrinsics {
            fx: 420.0,
            fy: 421.0,
            cx: 322.0,
            cy: 241.0,
        },
        Distortion::new(Model::Equidistant, &[-0.03, 0.006, -0.002, 0.0003]).unwrap(),
    )
    .unwrap();
    let rational = Camera::new(
        Intrinsics {
            fx: 700.0,
            fy: 698.0,
            cx: 318.0,
            cy: 236.0,
        },
        Distortion::new(
            Model::RationalPolynomial,
            &[0.6, -0.2, 0.0005, -0.0004, 0.01, 0.9, -0.1, 0.02],
        )
        .unwrap(),
    )
    .unwrap();
    let pairs = [
        opencv_pair(),
        StereoPair {
            left: fisheye,
            right: fisheye,
            ..opencv_pair()
        },
        StereoPair {
            left: rational,
            right: rational,
            rotation: Rotation3::from_scaled_axis(Vector3::new(-0.01, 0.03, -0.004)),
            translation: Vector3::new(-0.065, -0.001, 0.002),
        },
    ];
    for (n, pair) in pairs.iter().enumerate() {
        for alpha in [0.0, 1.0] {
            let options = RectifyOptions {
                alpha: Alpha::new(alpha).unwrap(),
                ..RectifyOptions::default()
            };
            let r = stereo_rectify(pair, SIZE, options).unwrap();
            let rig = r.rig(LengthUnit::Millimetre).unwrap();
            let scale = pair.translation.norm();
            for point in [[0.1, -0.05, 1.0], [-0.4, 0.3, 2.5], [0.2, 0.25, 0.8]] {
                let left_point = Vector3::from(point) * (scale / 0.12);
                let right_point = pair.rotation * left_point + pair.translation;
                let seen_l = pair.left.project(&left_point).unwrap();
                let seen_r = pair.right.project(&right_point).unwrap();
                let k1 = r.p1.fixed_view::<3, 3>(0, 0).into_owned();
                let k2 = r.p2.fixed_view::<3, 3>(0, 0).into_owned();
                let l = pair.left.undistort_to(seen_l, &r.r1, &k1).unwrap();
                let rr = pair.right.undistort_to(seen_r, &r.r2, &k2).unwrap();
                assert!(
                    (l[1] - rr[1]).abs() < 1e-6,
                    "pair {n}: rows {} and {}",
                    l[1],
                    rr[1]
                );
                let depth = (r.r1 * left_point).z;
                let z = rig.baseline() * rig.focal_px() / (l[0] - rr[0] + rig.doffs());
                assert!(
                    (z - depth).abs() < 1e-9 * depth,
                    "pair {n}: Z {z} vs {depth}"
                );
            }
        }
    }
}

/// What cannot be rectified is refused by name: alpha outside 0..=1, no baseline, a zero
/// size, and a vertical pair asked for a horizontal rig.
#[test]
fn refuses_what_it_cannot_rectify() {
    let pair = opencv_pair();
    assert_eq!(Alpha::new(1.5), Err(AlphaOutOfRange(1.5)));
    assert!(Alpha::new(f64::NAN).is_err() && Alpha::new(-0.1).is_err());
    let still = StereoPair {
        translation: Vector3::zeros(),
        ..pair
    };
    assert_eq!(
        stereo_rectify(&still, SIZE, RectifyOptions::default()),
        Err(RectifyFault::NoBaseline)
    );
    let empty = Size {
        width: 0,
        height: 480,
    };
    assert_eq!(
        stereo_rectify(&pair, empty, RectifyOptions::default()),
        Err(RectifyFault::Size)
    );
    let vertical = StereoPair {
        translation: Vector3::new(1.0, -80.0, 0.5),
        ..pair
    };
    let r = stereo_rectify(&vertical, SIZE, RectifyOptions::default()).unwrap();
    assert!(r.vertical);
    assert_eq!(r.rig(LengthUnit::Millimetre), Err(RigFault::Vertical));
}
