//! ChArUco corners by `calib-targets` 0.16 on a folder written by `scripts/evaluations/charuco.py`,
//! printed in the shape of `examples/boards charuco` so that the script scores both alike:
//! `charuco DIR` reads `DIR/board.json` and each `DIR/*.png`, and prints
//! `{"file.png": {"ids": […], "points": [[x, y], …], "ms": …}, …}`. calib-targets has no
//! legacy pattern: a legacy board prints nothing but a note on stderr.

use calib_targets::charuco::{CharucoBoardSpec, CharucoParams};
use calib_targets::detect;

fn main() {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).expect("usage: charuco DIR"));
    let spec: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("board.json")).expect("board.json"))
            .expect("board.json");
    if spec["legacy"] == true {
        eprintln!("calib-targets has no legacy ChArUco pattern");
        println!("{{}}");
        return;
    }
    let number = |key: &str| spec[key].as_f64().expect(key);
    let dictionary = calib_targets::aruco::builtins::builtin_dictionary(
        spec["dictionary"].as_str().expect("dictionary"),
    )
    .expect("a dictionary calib-targets has");
    let board = CharucoBoardSpec::new(
        number("squares_y") as u32,
        number("squares_x") as u32,
        number("square_size") as f32,
        (number("marker_size") / number("square_size")) as f32,
        dictionary,
    );
    let params = CharucoParams::for_board(board);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("the folder")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    files.sort();
    let mut out = serde_json::Map::new();
    for path in files {
        let image = image::open(&path).expect("an image").to_luma8();
        let started = std::time::Instant::now();
        let found = detect::detect_charuco(&image, &params);
        let ms = started.elapsed().as_secs_f64() * 1e3;
        let (ids, points): (Vec<u32>, Vec<[f64; 2]>) = match found {
            Ok(d) => d
                .corners
                .iter()
                .map(|c| (c.id, [f64::from(c.position.x), f64::from(c.position.y)]))
                .unzip(),
            Err(_) => (Vec::new(), Vec::new()),
        };
        out.insert(
            path.file_name().unwrap().to_string_lossy().into_owned(),
            serde_json::json!({"ids": ids, "points": points, "ms": ms}),
        );
    }
    println!("{}", serde_json::Value::Object(out));
}
