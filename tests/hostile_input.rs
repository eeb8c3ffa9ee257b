//! Bounded random input under `cargo test`, the in-CI counterpart of the cargo-fuzz target in
//! `fuzz/`: arbitrary bytes, mutated request examples, random JSON objects of the API's member
//! names and random query strings, each sent to every operation as a body and as a query
//! through the full router. The oracle is [`stereo_conformance`]: no 5xx or panic,
//! a 4xx is a problem naming a field, a 2xx holds no null.
//!
//! More cases: `PROPTEST_CASES=20000 cargo test --release --test hostile_input`.

use std::sync::OnceLock;

use axum::http::StatusCode;
use proptest::{collection::vec, prelude::*};
use serde_json::{Map, Value};
use stereo_conformance::Harness;

fn harness() -> &'static Harness {
    static HARNESS: OnceLock<Harness> = OnceLock::new();
    HARNESS.get_or_init(Harness::new)
}

/// Every request example in the OpenAPI document, serialized: the valid starting points.
fn examples() -> &'static [Vec<u8>] {
    static EXAMPLES: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    EXAMPLES.get_or_init(|| {
        let spec = serde_json::to_value(stereo_distance::api::openapi()).unwrap();
        let mut found = Vec::new();
        for item in spec["paths"].as_object().unwrap().values() {
            let content = &item["post"]["requestBody"]["content"]["application/json"];
            if let Some(examples) = content["examples"].as_object() {
                for example in examples.values() {
                    found.push(serde_json::to_vec(&example["value"]).unwrap());
                }
            }
        }
        assert!(found.len() >= 10, "the spec has request examples");
        found
    })
}

/// Member names the API knows, and a few it does not.
const NAMES: &[&str] = &[
    "focal_length_px",
    "focal_length_mm",
    "sensor_width_mm",
    "pixel_size_um",
    "horizontal_fov_deg",
    "baseline",
    "unit",
    "image_width",
    "image_height",
    "x_left",
    "x_right",
    "disparity_px",
    "focal_length_y_px",
    "scale",
    "text",
    "right_text",
    "cameras",
    "calibration_unit",
    "y",
    "doffs",
    "cx",
    "cy",
    "disparity_error_px",
    "distance_min",
    "distance_max",
    "disparity_min",
    "disparity_max",
    "spacing",
    "steps",
    "points",
    "format",
    "rig",
    "max_disparity_px",
    "min_disparity_px",
    "at_distances",
    "max_relative_error",
    "max_depth_error",
    "target_distance",
    "focal_lenght",
    "",
];

/// Number spellings that have broken parsers and arithmetic elsewhere.
const TOKENS: &[&str] = &[
    "0",
    "-0",
    "1e400",
    "-1e400",
    "1e-400",
    "5e-324",
    "1.7976931348623157e308",
    "4294967296",
    "2147483648",
    "-1",
    "0.5",
    "800.0",
    "NaN",
    "Infinity",
    "null",
    "true",
    "\"\"",
    "\"mm\"",
    "\"log\"",
    "\"csv\"",
    "[]",
    "{}",
    "[1,2,3]",
    "99999999999999999999999999",
    "\"\\u0000\"",
];

/// A JSON value of any kind, biased to numbers at the edges of f64.
fn value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        4 => any::<f64>().prop_filter_map("finite", |x| {
            serde_json::Number::from_f64(x).map(Value::Number)
        }),
        2 => any::<i64>().prop_map(Value::from),
        2 => (0..TOKENS.len()).prop_filter_map("parses", |i| serde_json::from_str(TOKENS[i]).ok()),
        1 => "[a-z]{0,6}".prop_map(Value::String),
        1 => Just(Value::Null),
        1 => any::<bool>().prop_map(Value::Bool),
    ];
    leaf.prop_recursive(3, 24, 6, |inner| {
        prop_oneof![
            vec(inner.clone(), 0..6).prop_map(Value::Array),
            vec((0..NAMES.len(), inner), 0..6).prop_map(|members| {
                Value::Object(
                    members
                        .into_iter()
                        .map(|(i, v)| (NAMES[i].to_owned(), v))
                        .collect(),
                )
            }),
        ]
    })
}

/// An object of API member names with random values, often close to a valid request.
fn object() -> impl Strategy<Value = Vec<u8>> {
    vec((0..NAMES.len(), value()), 0..12).prop_map(|members| {
        let object: Map<String, Value> = members
            .into_iter()
            .map(|(i, v)| (NAMES[i].to_owned(), v))
            .collect();
        serde_json::to_vec(&object).unwrap()
    })
}

/// A valid example with one edit: a splice of a token or of random bytes, a cut, or a
/// doubling.
fn mutated_example() -> impl Strategy<Value = Vec<u8>> {
    (
        0..examples().len(),
        any::<prop::sample::Index>(),
        any::<prop::sample::Index>(),
        0..TOKENS.len(),
        vec(any::<u8>(), 0..8),
        0u8..4,
    )
        .prop_map(|(which, at, to, token, noise, edit)| {
            let mut bytes = examples()[which].clone();
            let at = at.index(bytes.len() + 1);
            let to = at + to.index(bytes.len() + 1 - at);
            match edit {
                0 => {
                    bytes.splice(at..to, TOKENS[token].bytes());
                }
                1 => {
                    bytes.splice(at..at, noise);
                }
                2 => bytes.truncate(at),
                _ => {
                    let copy = bytes[at..to].to_vec();
                    bytes.splice(at..at, copy);
                }
            }
            bytes
        })
}

/// Small valid images of the project's own synthetic scene (a PNG, and a JPEG encoded by the
/// `image` crate): the starting points of the image mutations.
fn images() -> &'static [Vec<u8>] {
    static IMAGES: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    IMAGES.get_or_init(|| {
        use stereo_core::vision::{encode, synthetic};
        let pair = synthetic::render(&synthetic::layered(40, 32));
        let png = encode::png_rgb(40, 32, &pair.left_rgb);
        let mut jpeg = Vec::new();
        image::RgbImage::from_raw(40, 32, pair.left_rgb.clone())
            .unwrap()
            .write_to(
                &mut std::io::Cursor::new(&mut jpeg),
                image::ImageFormat::Jpeg,
            )
            .unwrap();
        vec![png, jpeg]
    })
}

/// A valid image with a few bytes overwritten, inserted or cut: deep into the decoders.
fn mutated_image() -> impl Strategy<Value = Vec<u8>> {
    (
        0..2usize,
        vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        0u8..3,
    )
        .prop_map(|(which, edits, how)| {
            let mut bytes = images()[which].clone();
            for (at, byte) in edits {
                let i = at.index(bytes.len());
                match how {
                    0 => bytes[i] = byte,
                    1 => bytes.insert(i, byte),
                    _ => bytes.truncate(i.max(8)),
                }
            }
            bytes
        })
}

/// A query string of API member names and number spellings, with some raw noise.
fn query() -> impl Strategy<Value = Vec<u8>> {
    vec(
        (
            0..NAMES.len(),
            prop_oneof![
                (0..TOKENS.len()).prop_map(|i| TOKENS[i].to_owned()),
                any::<f64>().prop_map(|x| x.to_string()),
                "[%&=+,a-z0-9.]{0,8}",
            ],
        ),
        0..12,
    )
    .prop_map(|pairs| {
        pairs
            .into_iter()
            .map(|(i, v)| format!("{}={v}", NAMES[i]))
            .collect::<Vec<_>>()
            .join("&")
            .into_bytes()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Arbitrary bytes, as a body and as a query, to every operation.
    #[test]
    fn arbitrary_bytes(input in vec(any::<u8>(), 0..512)) {
        harness().check(&input).map_err(TestCaseError::fail)?;
    }

    /// The spec's request examples, each with one random edit.
    #[test]
    fn mutated_examples(input in mutated_example()) {
        harness().check(&input).map_err(TestCaseError::fail)?;
    }

    /// Objects of the API's member names holding random JSON values.
    #[test]
    fn random_objects(input in object()) {
        harness().check(&input).map_err(TestCaseError::fail)?;
    }

    /// Valid PNG and JPEG images with a few bytes changed, as both images of a form (and as
    /// everything else).
    #[test]
    fn mutated_images(input in mutated_image()) {
        harness().check(&input).map_err(TestCaseError::fail)?;
    }

    /// Query strings of the API's member names and hostile number spellings.
    #[test]
    fn random_queries(input in query()) {
        harness().check(&input).map_err(TestCaseError::fail)?;
    }
}

/// The oracle is not blind: every example passes it as it is, each is answered 200 by the
/// operation it belongs to, a list of points is matched, and a body that is not JSON is refused
/// everywhere.
#[test]
fn examples_pass_the_oracle() {
    for example in examples() {
        let statuses = harness().check(example).unwrap();
        assert!(statuses.contains(&StatusCode::OK), "{statuses:?}");
    }
    // A valid image is matched: both images of the form are it, so /depth-map answers 200.
    for image in images() {
        let statuses = harness().check(image).unwrap();
        assert!(statuses.contains(&StatusCode::OK), "{statuses:?}");
    }
    // A list of points is matched: /match takes it as the points (or the regions) of a pair.
    let statuses = harness().check(br#"[{"x": 5, "y": 4}]"#).unwrap();
    assert!(statuses.contains(&StatusCode::OK), "{statuses:?}");
    let statuses = harness().check(b"{not json").unwrap();
    assert!(statuses.iter().all(|s| s.is_client_error()), "{statuses:?}");
}
