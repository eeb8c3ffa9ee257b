//! `vision-calibration` 0.12's whole stereo rig (`RigExtrinsicsProblem`) on the corners of
//! `/calibrate?corners=true`, against the rendered truth and our own answer on the same corners:
//! `rig SET_DIR SUMMARY_JSON [k3]` (`k3` frees k3, which vision-calibration holds at 0 by default).

use vision_calibration::core::{
    CorrespondenceView, NoMeta, Pt2, Pt3, RigDataset, RigView, RigViewObs,
};
use vision_calibration::prelude::*;
use vision_calibration::rig_extrinsics::{
    RigExtrinsicsConfig, RigExtrinsicsProblem, run_calibration,
};

fn main() {
    let dir = std::env::args().nth(1).unwrap();
    let summary_path = std::env::args().nth(2).unwrap();
    let free_k3 = std::env::args().nth(3).as_deref() == Some("k3");
    let truth: serde_json::Value =
        serde_json::from_slice(&std::fs::read(format!("{dir}/truth.json")).unwrap()).unwrap();
    let ours: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&summary_path).unwrap()).unwrap();
    let (cols, rows) = (
        truth["board"]["columns"].as_u64().unwrap() as usize,
        truth["board"]["rows"].as_u64().unwrap() as usize,
    );
    let s = truth["board"]["square_size"].as_f64().unwrap();
    let object: Vec<Pt3> = (0..rows)
        .flat_map(|r| (0..cols).map(move |c| Pt3::new(c as f64 * s, r as f64 * s, 0.0)))
        .collect();
    let mut views = Vec::new();
    for v in ours["views"].as_array().unwrap() {
        if v["status"] != "used" {
            continue;
        }
        let cam = |k: &str| {
            let pts: Vec<Pt2> = v[k]
                .as_array()
                .unwrap()
                .iter()
                .map(|p| Pt2::new(p[0].as_f64().unwrap(), p[1].as_f64().unwrap()))
                .collect();
            Some(CorrespondenceView::new(object.clone(), pts).unwrap())
        };
        views.push(RigView {
            obs: RigViewObs {
                cameras: vec![cam("corners_left"), cam("corners_right")],
            },
            meta: NoMeta,
        });
    }
    let input = RigDataset::new(views, 2).unwrap();
    let t0 = std::time::Instant::now();
    let mut session = CalibrationSession::<RigExtrinsicsProblem>::new();
    session.set_input(input).unwrap();
    if free_k3 {
        let mut c = serde_json::to_value(RigExtrinsicsConfig::default()).unwrap();
        c["camera"]["fix"] = serde_json::json!({"distortion": []});
        session
            .set_config(serde_json::from_value(c).unwrap())
            .unwrap();
    }
    run_calibration(&mut session).unwrap();
    let export = session.export().unwrap();
    let el = t0.elapsed();
    let e = serde_json::to_value(&export).unwrap();
    let cam0 = &e["cameras"][0];
    let fx = cam0["intrinsics"]["fx"].as_f64().unwrap();
    let cx = cam0["intrinsics"]["cx"].as_f64().unwrap();
    let cy = cam0["intrinsics"]["cy"].as_f64().unwrap();
    let t1 = &export.cam_se3_rig[1];
    let tn = t1.translation.vector.norm();
    let tt: Vec<f64> = truth["translation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let ttn = (tt[0] * tt[0] + tt[1] * tt[1] + tt[2] * tt[2]).sqrt();
    let r = t1.rotation.to_rotation_matrix();
    let tr: Vec<f64> = truth["rotation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let rt = nalgebra::Matrix3::from_row_slice(&tr);
    let m = r.matrix();
    let rm = nalgebra::Matrix3::from_fn(|i, j| m[(i, j)]);
    let d = rm.transpose() * rt;
    let ang = ((d.trace() - 1.0) / 2.0)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    let tl = &truth["left"];
    println!(
        "vision-calibration{}: f {:.4} % pp {:.3} px |T| {:.4} % rot {:.4} deg rms {:.4} in {:.0} ms; distortion {}",
        if free_k3 {
            " (k3 free)"
        } else {
            " (defaults, k3 fixed)"
        },
        100.0 * (fx / tl["fx"].as_f64().unwrap() - 1.0).abs(),
        ((cx - tl["cx"].as_f64().unwrap()).powi(2) + (cy - tl["cy"].as_f64().unwrap()).powi(2))
            .sqrt(),
        100.0 * (tn / ttn - 1.0).abs(),
        ang,
        export.mean_reproj_error,
        el.as_secs_f64() * 1e3,
        cam0["distortion"]
    );
    let o = &ours["left"]["camera_matrix"];
    let (ofx, ocx, ocy) = (
        o[0][0].as_f64().unwrap(),
        o[0][2].as_f64().unwrap(),
        o[1][2].as_f64().unwrap(),
    );
    let ot: Vec<f64> = ours["translation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let otn = (ot[0] * ot[0] + ot[1] * ot[1] + ot[2] * ot[2]).sqrt();
    let orr: Vec<f64> = ours["rotation"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|row| {
            row.as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect::<Vec<_>>()
        })
        .collect();
    let om = nalgebra::Matrix3::from_row_slice(&orr);
    let od = om.transpose() * rt;
    let oang = ((od.trace() - 1.0) / 2.0)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    println!(
        "ours (same corners): f {:.4} % pp {:.3} px |T| {:.4} % rot {:.4} deg rms {:.4} solve {} ms",
        100.0 * (ofx / tl["fx"].as_f64().unwrap() - 1.0).abs(),
        ((ocx - tl["cx"].as_f64().unwrap()).powi(2) + (ocy - tl["cy"].as_f64().unwrap()).powi(2))
            .sqrt(),
        100.0 * (otn / ttn - 1.0).abs(),
        oang,
        ours["rms"],
        ours["timings_ms"]["solve"]
    );
}
