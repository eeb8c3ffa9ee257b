//! Raw rigs as files and frames, shared by the API and browser tests: a `stereoCalibrate`
//! FileStorage of a pair, the smooth rectified scene, and a 180° fisheye pair's raw frames
//! rendered seeing that scene at a constant latitude-longitude disparity.

use nalgebra::Matrix3;
use stereo_core::camera::synthetic::{FISHEYE_180_SIZE as SIZE, fisheye_180};
use stereo_core::camera::{Latlon, LatlonOptions, Model, StereoPair};

/// The raw frames' size.
pub(crate) const W: u32 = 320;
pub(crate) const H: u32 = 240;

pub(crate) fn rows(m: &Matrix3<f64>) -> Vec<f64> {
    m.transpose().iter().copied().collect()
}

pub(crate) fn yaml_matrix(name: &str, rows: usize, cols: usize, data: &[f64]) -> String {
    let data: Vec<String> = data.iter().map(|v| format!("{v:?}")).collect();
    format!(
        "{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {} ]\n",
        data.join(", ")
    )
}

/// The intrinsics part of a `stereoCalibrate` FileStorage (M1 D1 M2 D2), as
/// `stereo_calib.cpp`'s `intrinsics.yml`.
pub(crate) fn intrinsics_yml(pair: &StereoPair, with_size: bool) -> String {
    let mut out = String::from("%YAML:1.0\n---\n");
    if with_size {
        out += &format!("imageSize: [ {W}, {H} ]\n");
    }
    if pair.left.distortion().model() == Model::Equidistant {
        out += "distortionModel: equidistant\n";
    }
    for (k, camera) in [(1, &pair.left), (2, &pair.right)] {
        out += &yaml_matrix(&format!("M{k}"), 3, 3, &rows(&camera.matrix()));
        let d = camera.distortion();
        out += &yaml_matrix(
            &format!("D{k}"),
            1,
            d.coefficients().len(),
            d.coefficients(),
        );
    }
    out
}

/// The extrinsics part (R T), as `extrinsics.yml` without R1 R2 P1 P2 Q.
pub(crate) fn extrinsics_yml(pair: &StereoPair) -> String {
    let t = pair.translation;
    format!(
        "%YAML:1.0\n---\n{}{}",
        yaml_matrix("R", 3, 3, &rows(pair.rotation.matrix())),
        yaml_matrix("T", 3, 1, &[t.x, t.y, t.z])
    )
}

/// A bare `stereoCalibrate` file in one text.
pub(crate) fn stereo_calibrate_yml(pair: &StereoPair) -> String {
    intrinsics_yml(pair, true) + &extrinsics_yml(pair)[14..]
}

/// The rectified scene: smooth texture in rectified left coordinates, with a horizontal
/// disparity of 8 px for the right camera (a plane), so that the truth of each rectified pixel
/// is known exactly.
pub(crate) fn scene(x: f64, y: f64) -> f64 {
    128.0 + 60.0 * (x / 7.0).sin() * (y / 9.0).cos() + 40.0 * ((x + 1.7 * y) / 13.0).sin()
}

/// A constant latlon disparity of the rendered scene, in pixels.
pub(crate) const DISPARITY: f64 = 6.0;

/// The raw frames of `pair` seeing [`scene`] laid over the latlon rectified images (the right
/// one shifted by [`DISPARITY`]): each raw pixel takes the scene's value where its ray lands
/// in the rectified image.
pub(crate) fn render(pair: &StereoPair, system: &Latlon) -> [Vec<u8>; 2] {
    [
        (&pair.left, &system.r1, 0.0),
        (&pair.right, &system.r2, -DISPARITY),
    ]
    .map(|(camera, rotation, shift)| {
        let mut img = vec![0u8; (W * H) as usize];
        for y in 0..H {
            for x in 0..W {
                let v = camera
                    .ray_of_pixel([f64::from(x), f64::from(y)])
                    .map_or(0.0, |ray| {
                        let [u, v] = system.pixel(&(rotation * ray));
                        scene(u - shift, v)
                    });
                img[(y * W + x) as usize] = v.round().clamp(0.0, 255.0) as u8;
            }
        }
        img
    })
}

/// The 180° fisheye pair, its latlon system at the defaults, its raw frames rendered seeing
/// [`scene`] there ([`render`]), and its calibration file.
pub(crate) fn rendered() -> (StereoPair, Latlon, [Vec<u8>; 2], String) {
    let pair = fisheye_180();
    let system = Latlon::new(&pair, SIZE, LatlonOptions::default()).unwrap();
    let frames = render(&pair, &system);
    let yml = stereo_calibrate_yml(&pair);
    (pair, system, frames, yml)
}
