//! `stereo-distance depth-map` over a folder of frames, run as its users run it: the binary,
//! its stderr a pipe (no progress bar), in process and against a spawned server.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use stereo_core::vision::encode;

use crate::depth_map::{H, W, pair};
use crate::helpers::spawn_app;

/// f·B of the calibration written below: 400 px × 120 mm.
const FB: f64 = 48_000.0;

/// A recording in `dir`: `left/000N.png` and `right/000N.png` for N = 1..=3 (the rendered
/// scene), a left frame without a partner (0004) and a right "frame" that is not an image
/// (0005), and a Middlebury calibration of the rectified pair. Returns the calibration's path.
fn recording(dir: &Path) -> PathBuf {
    let _ = std::fs::remove_dir_all(dir);
    for side in ["left", "right"] {
        std::fs::create_dir_all(dir.join(side)).unwrap();
    }
    let pair = pair();
    for n in 1..=3 {
        std::fs::write(
            dir.join(format!("left/000{n}.png")),
            encode::png_rgb(W, H, &pair.left_rgb),
        )
        .unwrap();
        std::fs::write(
            dir.join(format!("right/000{n}.png")),
            encode::png_rgb(W, H, &pair.right_rgb),
        )
        .unwrap();
    }
    std::fs::write(
        dir.join("left/0004.png"),
        encode::png_rgb(W, H, &pair.left_rgb),
    )
    .unwrap();
    std::fs::write(
        dir.join("left/0005.png"),
        encode::png_rgb(W, H, &pair.left_rgb),
    )
    .unwrap();
    std::fs::write(dir.join("right/0005.png"), b"not a picture").unwrap();
    let calib = dir.join("calib.txt");
    std::fs::write(
        &calib,
        format!(
            "cam0=[400 0 {cx}; 0 400 {cy}; 0 0 1]\ncam1=[400 0 {cx}; 0 400 {cy}; 0 0 1]\n\
             doffs=0\nbaseline=120\nwidth={W}\nheight={H}\nndisp=48\n",
            cx = W / 2,
            cy = H / 2
        ),
    )
    .unwrap();
    calib
}

/// `stereo-distance depth-map` on the recording in `dir` (its `left` and `right` folders),
/// writing into `dir/{out}`, with `extra` arguments.
pub(crate) fn command(dir: &Path, out: &str, extra: &[&str]) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_stereo-distance"));
    command
        .arg("depth-map")
        .arg("--left")
        .arg(dir.join("left"))
        .arg("--right")
        .arg(dir.join("right"))
        .arg("--out")
        .arg(dir.join(out))
        .args(extra);
    command
}

/// [`command`] run to its end, its stderr a pipe.
fn run(dir: &Path, out: &str, extra: &[&str]) -> Output {
    command(dir, out, extra).output().expect("the binary runs")
}

/// The float32 values of an NPY file of the scene's size.
fn npy_values(path: &Path) -> Vec<f32> {
    crate::depth_map::npy(&std::fs::read(path).unwrap())
}

/// The median of the finite values.
fn median(values: &[f32]) -> f64 {
    let mut v: Vec<f32> = values.iter().copied().filter(|z| z.is_finite()).collect();
    v.sort_by(f32::total_cmp);
    f64::from(v[v.len() / 2])
}

/// In process: each pair of the folders becomes a depth NPY whose depths are f·B / d of the
/// scene; the unpaired frame and the broken one are named with their reasons and the rest go
/// on (exit 1); no progress bar is drawn into a pipe; a second run skips what is written.
#[test]
fn a_folder_becomes_depth_maps_and_a_rerun_skips_them() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("recording-in-process");
    let calib = recording(&dir);
    let out = dir.join("out");
    let args = [
        "--calibration",
        calib.to_str().unwrap(),
        "--calibration-unit",
        "mm",
    ];
    let first = run(&dir, "out", &args);
    let said = String::from_utf8_lossy(&first.stderr).into_owned();
    assert_eq!(first.status.code(), Some(1), "{said}");
    assert!(
        said.contains("0004.png: no right frame of the same name"),
        "{said}"
    );
    assert!(
        said.contains("failed 0005:") && said.contains("right/0005.png: is not an image"),
        "{said}"
    );
    assert!(said.contains("wrote 3 of 4 pairs"), "{said}");
    assert!(
        !said.contains('\r') && !said.contains("frames/s  "),
        "a bar in a pipe: {said:?}"
    );
    let truth = median(&pair().seen_truth());
    let mut written = Vec::new();
    for n in 1..=3 {
        let path = out.join(format!("000{n}.depth.npy"));
        let z = median(&npy_values(&path));
        assert!(
            (z - FB / truth).abs() < 0.03 * FB / truth,
            "{path:?}: median {z}, truth {}",
            FB / truth
        );
        written.push(std::fs::metadata(&path).unwrap().modified().unwrap());
    }
    assert!(!out.join("0005.depth.npy").exists());
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(leftovers.len(), 3, "{leftovers:?}");

    let again = run(&dir, "out", &args);
    let said = String::from_utf8_lossy(&again.stderr).into_owned();
    assert!(said.contains("3 of 4 pairs already written"), "{said}");
    assert!(said.contains("wrote 0 of 1 pairs"), "{said}");
    for (n, when) in (1..=3).zip(&written) {
        let path = out.join(format!("000{n}.depth.npy"));
        assert_eq!(&std::fs::metadata(&path).unwrap().modified().unwrap(), when);
    }
}

/// `--server`: the same folder sent to a running service, two pairs in flight, as PFM files
/// read back as Middlebury's readers read them; a service that is not there stops the run
/// with its address (at once with `--retries 0`).
#[tokio::test]
async fn the_server_option_sends_the_frames_to_a_running_service() {
    let app = spawn_app().await;
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("recording-server");
    let calib = recording(&dir);
    std::fs::remove_file(dir.join("right/0005.png")).unwrap();
    std::fs::remove_file(dir.join("left/0005.png")).unwrap();
    std::fs::remove_file(dir.join("left/0004.png")).unwrap();
    let address = app.address.clone();
    let sent = dir.clone();
    let output = tokio::task::spawn_blocking(move || {
        run(
            &sent,
            "out",
            &[
                "--calibration",
                calib.to_str().unwrap(),
                "--output",
                "disparity.pfm",
                "--preset",
                "fast",
                "--server",
                &address,
            ],
        )
    })
    .await
    .unwrap();
    let said = String::from_utf8_lossy(&output.stderr).into_owned();
    assert_eq!(output.status.code(), Some(0), "{said}");
    assert!(said.contains("wrote 3 of 3 pairs"), "{said}");
    for n in 1..=3 {
        let bytes = std::fs::read(dir.join(format!("out/000{n}.disparity.pfm"))).unwrap();
        let header = format!("Pf\n{W} {H}\n-1\n");
        assert!(bytes.starts_with(header.as_bytes()));
        let d = crate::depth_map::floats(&bytes[header.len()..]);
        assert_eq!(d.len(), W * H);
        assert!(d.iter().filter(|v| v.is_finite()).count() > W * H / 2);
    }
    let nowhere = run(
        &dir,
        "out2",
        &["--server", "http://127.0.0.1:1", "--retries", "0"],
    );
    let said = String::from_utf8_lossy(&nowhere.stderr).into_owned();
    assert_eq!(nowhere.status.code(), Some(1), "{said}");
    assert!(
        said.contains("error: cannot connect to 127.0.0.1:1"),
        "{said}"
    );
    assert!(said.contains("wrote 0 of 3 pairs"), "{said}");
}

/// The command in process (the engine called directly, the calibration resolved once) and
/// the same command against a running service (`--server`) write the same files, byte for
/// byte, for a rectified recording under a Middlebury file and for raw frames under an OpenCV
/// `stereoCalibrate` file (rectified first), in every file format a user picks.
#[tokio::test]
async fn in_process_and_server_runs_write_the_same_bytes() {
    let app = spawn_app().await;
    let base = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("recording-same-bytes");
    let rectified = base.join("rectified");
    let calib = recording(&rectified);
    for n in [4, 5] {
        let _ = std::fs::remove_file(rectified.join(format!("left/000{n}.png")));
        let _ = std::fs::remove_file(rectified.join(format!("right/000{n}.png")));
    }
    let raw = base.join("raw");
    let scene = crate::rectify::raw_scene();
    for side in ["left", "right"] {
        std::fs::create_dir_all(raw.join(side)).unwrap();
    }
    for n in 1..=2 {
        for (side, rgb) in [("left", &scene.raw_left), ("right", &scene.raw_right)] {
            std::fs::write(
                raw.join(format!("{side}/000{n}.png")),
                encode::png_rgb(160, 120, rgb),
            )
            .unwrap();
        }
    }
    let yml = raw.join("stereo.yml");
    std::fs::write(&yml, &scene.yml).unwrap();
    let cases = [
        (
            &rectified,
            calib,
            &["depth.npy", "arrays.npz", "points.ply"][..],
        ),
        (
            &raw,
            yml,
            &[
                "disparity.pfm",
                "depth_std.npy",
                "arrays.npz",
                "points.ply",
                "depth.png",
            ][..],
        ),
    ];
    for (dir, calibration, outputs) in cases {
        for output in outputs {
            let mut files = Vec::new();
            for server in [None, Some(app.address.clone())] {
                let out = format!("out-{}-{}", output, server.is_some());
                let mut args = vec![
                    "--calibration".to_owned(),
                    calibration.to_string_lossy().into_owned(),
                    "--calibration-unit".to_owned(),
                    "mm".to_owned(),
                    "--output".to_owned(),
                    (*output).to_owned(),
                ];
                args.extend(server.into_iter().flat_map(|s| ["--server".to_owned(), s]));
                let dir_for = dir.to_path_buf();
                let out_for = out.clone();
                let done = tokio::task::spawn_blocking(move || {
                    let args: Vec<&str> = args.iter().map(String::as_str).collect();
                    run(&dir_for, &out_for, &args)
                })
                .await
                .unwrap();
                let said = String::from_utf8_lossy(&done.stderr).into_owned();
                assert_eq!(done.status.code(), Some(0), "{output}: {said}");
                let mut written: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir.join(&out))
                    .unwrap()
                    .flatten()
                    .map(|e| {
                        let name = e.file_name().to_string_lossy().into_owned();
                        (name, std::fs::read(e.path()).unwrap())
                    })
                    .collect();
                written.sort();
                assert!(!written.is_empty() && written.iter().all(|(_, b)| b.len() > 100));
                files.push(written);
            }
            assert_eq!(files[0].len(), files[1].len(), "{output}");
            for ((name, here), (_, there)) in files[0].iter().zip(&files[1]) {
                assert!(here == there, "{dir:?} {name}: the two runs differ");
            }
        }
    }
}
