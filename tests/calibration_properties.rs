//! Property tests of the calibration readers: a rig written in each format (as that format's
//! own tools write it) and read back is the same rig, and no text at all makes a reader panic.

use proptest::prelude::*;
use stereo_core::calibration::files::{self, Calibration, Format, KittiPair, Source};

/// A rectified rig as the files describe it, lengths in the format's unit.
#[derive(Debug, Clone, Copy)]
struct Rig {
    f: f64,
    fy: f64,
    baseline: f64,
    cx: f64,
    cy: f64,
    doffs: f64,
    width: u32,
    height: u32,
}

fn rig() -> impl Strategy<Value = Rig> {
    (
        100.0..6000.0f64,
        prop_oneof![Just(1.0), 0.98..1.02f64],
        0.01..2.0f64,
        0.0..3000.0f64,
        0.0..2000.0f64,
        prop_oneof![Just(0.0), -50.0..250.0f64],
        16u32..6000,
        16u32..4000,
    )
        .prop_map(|(f, aspect, baseline, cx, cy, doffs, width, height)| Rig {
            f,
            fy: f * aspect,
            baseline,
            cx,
            cy,
            doffs,
            width,
            height,
        })
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
}

/// The parsed calibration states `rig` (the baseline in the same unit).
fn same(parsed: &Calibration, rig: &Rig, sized: bool) -> Result<(), TestCaseError> {
    prop_assert!(
        close(parsed.focal_px, rig.f),
        "f {} vs {}",
        parsed.focal_px,
        rig.f
    );
    prop_assert!(close(parsed.focal_y_px, rig.fy), "fy");
    prop_assert!(
        close(parsed.baseline, rig.baseline),
        "B {} vs {}",
        parsed.baseline,
        rig.baseline
    );
    prop_assert!(close(parsed.cx, rig.cx), "cx");
    prop_assert!(close(parsed.cy, rig.cy), "cy");
    prop_assert!(
        close(parsed.doffs, rig.doffs),
        "doffs {} vs {}",
        parsed.doffs,
        rig.doffs
    );
    if sized {
        prop_assert_eq!(parsed.image_size, Some((rig.width, rig.height)));
    }
    Ok(())
}

fn read(text: &str, right: Option<&str>) -> Calibration {
    files::parse(Source {
        text,
        right_text: right,
        ..Source::default()
    })
    .unwrap_or_else(|e| panic!("{e:?}\n{text}"))
}

/// Middlebury 2014 `calib.txt`, with CRLF line ends as the dataset's Windows copies have.
fn middlebury(r: &Rig) -> String {
    format!(
        "cam0=[{f:?} 0 {cx:?}; 0 {fy:?} {cy:?}; 0 0 1]\r\ncam1=[{f:?} 0 {cx1:?}; 0 {fy:?} {cy:?}; 0 0 1]\r\n\
         doffs={doffs:?}\r\nbaseline={b:?}\r\nwidth={w}\r\nheight={h}\r\nndisp=256\r\nisint=0\r\n",
        f = r.f,
        fy = r.fy,
        cx = r.cx,
        cy = r.cy,
        cx1 = r.cx + r.doffs,
        doffs = r.doffs,
        b = r.baseline,
        w = r.width,
        h = r.height,
    )
}

/// A KITTI projection row-major: `[f 0 cx f·tx; 0 fy cy 0; 0 0 1 0]`.
fn projection(r: &Rig, cx: f64, tx: f64) -> String {
    [
        r.f,
        0.0,
        cx,
        r.f * tx,
        0.0,
        r.fy,
        r.cy,
        0.0,
        0.0,
        0.0,
        1.0,
        0.0,
    ]
    .iter()
    .map(|v| format!("{v:e}"))
    .collect::<Vec<_>>()
    .join(" ")
}

/// KITTI raw `calib_cam_to_cam.txt`: the left colour camera 6 cm from camera 0, as in KITTI.
fn kitti_raw(r: &Rig) -> String {
    let offset = 0.06;
    format!(
        "calib_time: 09-Jan-2012 13:57:47\ncorner_dist: 9.950000e-02\nS_rect_02: {w:e} {h:e}\n\
         P_rect_02: {l}\nS_rect_03: {w:e} {h:e}\nP_rect_03: {rt}\n",
        w = f64::from(r.width),
        h = f64::from(r.height),
        l = projection(r, r.cx, offset),
        rt = projection(r, r.cx + r.doffs, offset - r.baseline),
    )
}

/// KITTI odometry `calib.txt`: P0..P3, the grey pair 0-1.
fn kitti_odometry(r: &Rig) -> String {
    format!(
        "P0: {}\nP1: {}\nP2: {}\nP3: {}\nTr: 1 0 0 0 0 1 0 0 0 0 1 0\n",
        projection(r, r.cx, 0.0),
        projection(r, r.cx + r.doffs, -r.baseline),
        projection(r, r.cx, 0.06),
        projection(r, r.cx, -0.47),
    )
}

/// ROS 1 `camera_calibration` YAML for one camera.
fn ros1(r: &Rig, cx: f64, p3: f64) -> String {
    format!(
        "image_width: {w}\nimage_height: {h}\ncamera_name: cam\ncamera_matrix:\n  rows: 3\n  \
         cols: 3\n  data: [{f:?}, 0, {cx:?}, 0, {fy:?}, {cy:?}, 0, 0, 1]\n\
         distortion_model: plumb_bob\nprojection_matrix:\n  rows: 3\n  cols: 4\n  \
         data: [{f:?}, 0, {cx:?}, {p3:?}, 0, {fy:?}, {cy:?}, 0, 0, 0, 1, 0]\n",
        w = r.width,
        h = r.height,
        f = r.f,
        fy = r.fy,
        cy = r.cy,
    )
}

/// ROS 2 `ros2 topic echo` of a CameraInfo: block lists.
fn ros2(r: &Rig, cx: f64, p3: f64) -> String {
    let list = |values: &[f64]| {
        values
            .iter()
            .map(|v| format!("- {v:?}\n"))
            .collect::<String>()
    };
    format!(
        "header:\n  stamp:\n    sec: 0\n    nanosec: 0\n  frame_id: cam\nheight: {h}\n\
         width: {w}\ndistortion_model: plumb_bob\nd: []\nk:\n{k}p:\n{p}binning_x: 0\n---\n",
        h = r.height,
        w = r.width,
        k = list(&[r.f, 0.0, cx, 0.0, r.fy, r.cy, 0.0, 0.0, 1.0]),
        p = list(&[r.f, 0.0, cx, p3, 0.0, r.fy, r.cy, 0.0, 0.0, 0.0, 1.0, 0.0]),
    )
}

/// The rectified projections `stereoRectify` writes: P1 at the origin, P2 a baseline to the
/// right (`P2[0,3] = −f·B`), row-major.
fn projections(r: &Rig) -> [[f64; 12]; 2] {
    let p = |cx: f64, tx: f64| [r.f, 0.0, cx, tx, 0.0, r.fy, r.cy, 0.0, 0.0, 0.0, 1.0, 0.0];
    [p(r.cx, 0.0), p(r.cx + r.doffs, -r.f * r.baseline)]
}

/// OpenCV FileStorage YAML with Q (and P1, P2 for fy), as `cv::FileStorage` writes it.
fn opencv_yaml(r: &Rig) -> String {
    let matrix = |name: &str, rows: usize, data: &[f64]| {
        let values: Vec<String> = data.iter().map(|v| format!("{v:?}")).collect();
        format!(
            "{name}: !!opencv-matrix\n   rows: {rows}\n   cols: 4\n   dt: d\n   data: [ {} ]\n",
            values.join(",\n       ")
        )
    };
    let q32 = 1.0 / r.baseline;
    let q = [
        [1.0, 0.0, 0.0, -r.cx],
        [0.0, 1.0, 0.0, -r.cy],
        [0.0, 0.0, 0.0, r.f],
        [0.0, 0.0, q32, r.doffs * q32],
    ];
    let [p1, p2] = projections(r);
    format!(
        "%YAML:1.0\n---\n{}{}{}imageSize: [ {}, {} ]\n",
        matrix("P1", 3, &p1),
        matrix("P2", 3, &p2),
        matrix("Q", 4, q.as_flattened()),
        r.width,
        r.height,
    )
}

/// OpenCV FileStorage XML with P1 and P2 only.
fn opencv_xml(r: &Rig) -> String {
    let matrix = |name: &str, data: &[f64]| {
        let values: Vec<String> = data.iter().map(|v| format!("{v:e}")).collect();
        format!(
            "<{name} type_id=\"opencv-matrix\">\n  <rows>3</rows>\n  <cols>4</cols>\n  \
             <dt>d</dt>\n  <data>\n    {}</data></{name}>\n",
            values.join(" ")
        )
    };
    let [p1, p2] = projections(r);
    format!(
        "<?xml version=\"1.0\"?>\n<opencv_storage>\n{}{}<imageSize>\n  {} {}</imageSize>\n\
         </opencv_storage>\n",
        matrix("P1", &p1),
        matrix("P2", &p2),
        r.width,
        r.height,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Middlebury: written and read back, the same rig, with `ndisp`.
    #[test]
    fn middlebury_round_trips(r in rig()) {
        let parsed = read(&middlebury(&r), None);
        prop_assert_eq!(parsed.format, Format::Middlebury);
        prop_assert_eq!(parsed.max_disparity_px, Some(256));
        same(&parsed, &r, true)?;
        prop_assert!(parsed.warnings.is_empty(), "{:?}", parsed.warnings);
    }

    /// KITTI raw (colour pair, left camera offset from camera 0) and odometry (grey pair).
    #[test]
    fn kitti_round_trips(r in rig()) {
        let parsed = read(&kitti_raw(&r), None);
        prop_assert_eq!(parsed.format, Format::Kitti);
        same(&parsed, &r, true)?;
        let parsed = files::parse(Source {
            text: &kitti_odometry(&r),
            kitti_pair: Some(KittiPair::Grey),
            ..Source::default()
        })
        .unwrap();
        same(&parsed, &r, false)?;
    }

    /// ROS 1 YAML and ROS 2 echo pairs.
    #[test]
    fn ros_round_trips(r in rig()) {
        let p3 = -r.f * r.baseline;
        let parsed = read(&ros1(&r, r.cx, 0.0), Some(&ros1(&r, r.cx + r.doffs, p3)));
        prop_assert_eq!(parsed.format, Format::Ros);
        same(&parsed, &r, true)?;
        let parsed = read(&ros2(&r, r.cx, 0.0), Some(&ros2(&r, r.cx + r.doffs, p3)));
        same(&parsed, &r, true)?;
    }

    /// OpenCV YAML (from Q, fy from P1) and XML (from P1 and P2).
    #[test]
    fn opencv_round_trips(r in rig()) {
        let parsed = read(&opencv_yaml(&r), None);
        prop_assert_eq!(parsed.format, Format::OpenCv);
        same(&parsed, &r, true)?;
        prop_assert!(parsed.warnings.is_empty(), "{:?}", parsed.warnings);
        let parsed = read(&opencv_xml(&r), None);
        same(&parsed, &r, true)?;
    }

    /// No text, in any format or none, makes a reader panic: it is a rig or errors.
    #[test]
    fn any_text_is_a_rig_or_errors(
        text in ".{0,400}",
        right in proptest::option::of(".{0,200}"),
        format in proptest::option::of(prop_oneof![
            Just(Format::Middlebury), Just(Format::Kitti), Just(Format::Ros), Just(Format::OpenCv)
        ]),
    ) {
        let _ = files::parse(Source { text: &text, right_text: right.as_deref(), format,
                                            ..Source::default() });
    }

    /// Damaged real files (a character changed, a line cut) are rigs or errors, never panics.
    #[test]
    fn damaged_files_are_rigs_or_errors(r in rig(), which in 0usize..6, at in any::<prop::sample::Index>(),
                                        c in any::<char>()) {
        let text = [middlebury(&r), kitti_raw(&r), kitti_odometry(&r), ros1(&r, r.cx, 0.0),
                    opencv_yaml(&r), opencv_xml(&r)][which].clone();
        let mut chars: Vec<char> = text.chars().collect();
        let i = at.index(chars.len());
        chars[i] = c;
        let damaged: String = chars.into_iter().collect();
        let _ = files::parse(Source { text: &damaged, right_text: Some(&ros1(&r, r.cx, -1.0)),
                                            ..Source::default() });
        let half: String = damaged.chars().take(damaged.chars().count() / 2).collect();
        let _ = files::parse(Source { text: &half, ..Source::default() });
    }
}
