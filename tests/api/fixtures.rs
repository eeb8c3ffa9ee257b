//! The requests the tests share: the seed calculator's rig and its example 1 (f = 35 px,
//! B = 150 mm, 800 × 600, x_left 400, x_right 350: Z = 105 mm), as JSON and as a raw request.

use serde_json::{Value, json};

/// The seed calculator's rig, its focal length read as pixels.
pub fn seed_rig() -> Value {
    json!({"focal_length_px": 35, "baseline": 150, "unit": "mm",
           "image_width": 800, "image_height": 600})
}

/// `base` with the members of `extra` added or replaced.
pub fn with(mut base: Value, extra: Value) -> Value {
    for (key, value) in extra.as_object().expect("extra members are an object") {
        base[key] = value.clone();
    }
    base
}

/// The seed's example 1: the seed rig and the correspondence 400 ↔ 350, 105 mm away.
pub fn example_one() -> Value {
    with(seed_rig(), json!({"x_left": 400, "x_right": 350}))
}

/// The head of a `POST` to `path` of `length` JSON bytes, with `Connection: close`.
pub fn post_head(path: &str, length: usize) -> String {
    format!(
        "POST {path} HTTP/1.1\r\nHost: test\r\nContent-Type: application/json\r\n\
         Content-Length: {length}\r\nConnection: close\r\n\r\n"
    )
}

/// Example 1 as a raw `POST /distance` with `Connection: close`: its head and its body.
pub fn example_one_request() -> (String, String) {
    let body = example_one().to_string();
    (post_head("/distance", body.len()), body)
}
