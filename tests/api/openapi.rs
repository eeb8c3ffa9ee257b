//! The OpenAPI document: served, committed, complete, and the Swagger UI is served offline.

use serde_json::{Value, json};

use crate::helpers::{assert_close, number_at, ok_json, spawn_app};

const COMMITTED: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/openapi/openapi.json");

/// The committed `openapi/openapi.json` is byte for byte the served one, and both are the
/// generated document. Regenerate it with `UPDATE_OPENAPI=1 cargo test --test api openapi`.
#[tokio::test]
async fn committed_spec_matches_generated() {
    let app = spawn_app().await;
    let response = app.get("/openapi.json").await;
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "application/json");
    let served = response.text().await.unwrap();
    let generated = stereo_distance::api::openapi();
    assert_eq!(
        served,
        stereo_distance::api::openapi_text(&generated),
        "the served spec is the generated one"
    );
    if std::env::var_os("UPDATE_OPENAPI").is_some() {
        std::fs::write(COMMITTED, &served).expect("openapi/openapi.json is writable");
    }
    let committed = std::fs::read_to_string(COMMITTED).expect("openapi/openapi.json is committed");
    assert!(
        committed == served,
        "openapi/openapi.json is stale: run UPDATE_OPENAPI=1 cargo test --test api openapi"
    );
}

/// The schema a `$ref` points at.
fn resolve<'a>(spec: &'a Value, schema: &'a Value) -> &'a Value {
    match schema["$ref"].as_str() {
        Some(reference) => &spec["components"]["schemas"][reference.rsplit('/').next().unwrap()],
        None => schema,
    }
}

/// Every operation is documented: GET and POST on each path, an example on every request
/// schema (each alternative of a `oneOf`), query parameters on GET for every member, one
/// success media type per operation (CSV has its own paths), and problem+json error responses.
#[tokio::test]
async fn every_operation_is_documented() {
    let app = spawn_app().await;
    let spec = ok_json(app.get("/openapi.json").await).await;
    let json = ["application/json"].as_slice();
    for (path, media) in [
        ("/distance", json),
        ("/table", json),
        ("/table.csv", ["text/csv"].as_slice()),
        ("/chart-data", json),
        ("/chart-data.csv", ["text/csv"].as_slice()),
        ("/rig", json),
        ("/baseline", json),
    ] {
        let post = &spec["paths"][path]["post"];
        let get = &spec["paths"][path]["get"];
        let body = resolve(
            &spec,
            &post["requestBody"]["content"]["application/json"]["schema"],
        );
        let alternatives: Vec<&Value> = match body["oneOf"].as_array() {
            Some(options) => options.iter().map(|o| resolve(&spec, o)).collect(),
            None => vec![body],
        };
        for schema in &alternatives {
            assert!(
                schema["example"].is_object(),
                "{path} request has an example"
            );
            assert_eq!(
                schema["additionalProperties"], false,
                "{path} request refuses unknown members"
            );
        }
        // The flat (first) form is the one a query string carries.
        let properties = alternatives[0]["properties"].as_object().unwrap();
        let params = get["parameters"].as_array().unwrap();
        assert_eq!(
            params.len(),
            properties.len(),
            "GET {path} takes every member"
        );
        for op in [post, get] {
            let content = op["responses"]["200"]["content"].as_object().unwrap();
            let types: Vec<&str> = content.keys().map(String::as_str).collect();
            assert_eq!(types, media, "{path} success media types");
            for status in ["400", "422"] {
                assert_eq!(
                    op["responses"][status]["content"]["application/problem+json"]["schema"]["$ref"],
                    "#/components/schemas/Problem",
                    "{path} documents {status}"
                );
            }
        }
        assert!(post["responses"]["413"].is_object() && post["responses"]["415"].is_object());
    }
    // The SVG chart takes the chart-data query and answers an image.
    let svg = &spec["paths"]["/chart.svg"]["get"];
    assert_eq!(
        svg["parameters"], spec["paths"]["/chart-data"]["get"]["parameters"],
        "/chart.svg takes the same query as /chart-data"
    );
    assert!(svg["responses"]["200"]["content"]["image/svg+xml"].is_object());
    assert!(svg["responses"]["422"].is_object());
    // Lists in a query string are comma-separated.
    let at = spec["paths"]["/rig"]["get"]["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "at_distances")
        .expect("GET /rig takes at_distances");
    assert_eq!(
        (&at["style"], &at["explode"]),
        (&json!("form"), &json!(false))
    );
}

/// Optional request members are optional, not nullable. The one `null` a schema admits is a
/// cell of the projection uncertainty's grid where the lens cannot be inverted: a grid keeps
/// its cells in place.
#[tokio::test]
async fn optional_members_are_not_nullable() {
    let spec = serde_json::to_value(stereo_distance::api::openapi()).unwrap();
    let mut schemas = spec["components"]["schemas"].clone();
    let grid = schemas
        .as_object_mut()
        .unwrap()
        .remove("ProjectionGrid")
        .expect("the projection grid's schema");
    assert!(grid["properties"]["grid"].to_string().contains("\"null\""));
    let text = schemas.to_string();
    assert!(!text.contains("\"null\""), "a schema admits null");
    // Only the baseline is required on its own: the image size, x_left and x_right are
    // required by the forms that need them (the schema cannot say "x_right or disparity_px").
    let required = &spec["components"]["schemas"]["DistanceRequest"]["required"];
    assert_eq!(required, &json!(["baseline"]));
}

/// Every `$ref` in the document names a schema it holds: an answer named by reference (the
/// image routes' bodies) is registered among the components, so that clients generated from
/// the document can read it.
#[tokio::test]
async fn every_reference_resolves() {
    fn refs(value: &Value, found: &mut Vec<String>) {
        match value {
            Value::Object(map) => {
                if let Some(Value::String(target)) = map.get("$ref") {
                    found.push(target.clone());
                }
                map.values().for_each(|v| refs(v, found));
            }
            Value::Array(items) => items.iter().for_each(|v| refs(v, found)),
            _ => {}
        }
    }
    let spec = serde_json::to_value(stereo_distance::api::openapi()).unwrap();
    let mut found = Vec::new();
    refs(&spec, &mut found);
    assert!(found.iter().any(|r| r.ends_with("/BoardAnswer")));
    for target in found {
        let name = target
            .strip_prefix("#/components/schemas/")
            .unwrap_or_else(|| panic!("{target} points into the components' schemas"));
        assert!(
            spec["components"]["schemas"][name].is_object(),
            "{target} is not in the document"
        );
    }
}

/// Swagger UI is served from the binary at /docs/, with no CDN.
#[tokio::test]
async fn swagger_ui_is_served_offline() {
    let app = spawn_app().await;
    let response = app.get("/docs/").await;
    assert_eq!(response.status(), 200);
    let html = response.text().await.unwrap();
    assert!(html.contains("swagger-ui"), "the page is Swagger UI");
    assert!(!html.contains("https://"), "no external assets");
    let script = app.get("/docs/swagger-ui-bundle.js").await;
    assert_eq!(script.status(), 200);
}

/// Every operation's documented responses other than 2xx carry exactly one representation,
/// `application/problem+json` with the `Problem` schema; the 503 of an operation that can shed
/// load documents `Retry-After`.
#[tokio::test]
async fn every_error_response_is_problem_json() {
    let spec = serde_json::to_value(stereo_distance::api::openapi()).unwrap();
    let mut errors = 0;
    for (path, item) in spec["paths"].as_object().unwrap() {
        for (method, op) in item.as_object().unwrap() {
            for (status, response) in op["responses"].as_object().unwrap() {
                if status.starts_with('2') {
                    continue;
                }
                errors += 1;
                let content = response["content"].as_object().unwrap();
                let types: Vec<&String> = content.keys().collect();
                assert_eq!(
                    types,
                    ["application/problem+json"],
                    "{method} {path} {status}"
                );
                assert_eq!(
                    content["application/problem+json"]["schema"]["$ref"],
                    "#/components/schemas/Problem",
                    "{method} {path} {status}"
                );
                let sheds = !path.ends_with("z") && path != "/metrics";
                if status == "503" && sheds {
                    assert_eq!(
                        response["headers"]["Retry-After"]["schema"]["type"], "integer",
                        "{method} {path} documents Retry-After"
                    );
                }
            }
            assert!(
                op["responses"]["405"].is_object(),
                "{method} {path} documents 405"
            );
        }
    }
    assert!(errors > 60, "error responses were found ({errors})");
}

/// Every request example in the spec is answered with a 200, so the examples a reader copies
/// (and that schemathesis starts from) work: each named body example of every POST, and for
/// every GET the query made of each parameter's example. The distance examples give the
/// distance their summary states.
#[tokio::test]
async fn every_request_example_is_answered() {
    let app = spawn_app().await;
    let spec = ok_json(app.get("/openapi.json").await).await;
    let expected_distance = [
        ("focal length in px", 105.0),
        ("focal length in mm with sensor width", 1920.0),
        ("focal length in mm with pixel pitch", 2.4),
        ("horizontal field of view", 1300.0),
    ];
    let mut answered = 0;
    for (path, item) in spec["paths"].as_object().unwrap() {
        if let Some(examples) =
            item["post"]["requestBody"]["content"]["application/json"]["examples"].as_object()
        {
            for (name, example) in examples {
                let response = app.post(path, &example["value"]).await;
                assert_eq!(response.status(), 200, "POST {path} example {name:?}");
                answered += 1;
                if let Some((_, distance)) = expected_distance
                    .iter()
                    .find(|(n, _)| path == "/distance" && n == name)
                {
                    let body: Value = response.json().await.unwrap();
                    assert_close(number_at(&body, "distance"), *distance, name);
                }
            }
        }
        if let Some(params) = item["get"]["parameters"].as_array() {
            let query: serde_json::Map<String, Value> = params
                .iter()
                .filter_map(|p| {
                    let example = p["schema"]
                        .get("example")
                        .or(p["schema"]["examples"].get(0))?;
                    // Lists travel comma-separated (`style: form, explode: false`).
                    let value = match example.as_array() {
                        Some(list) => {
                            let items: Vec<String> = list.iter().map(Value::to_string).collect();
                            Value::String(items.join(","))
                        }
                        None => example.clone(),
                    };
                    Some((p["name"].as_str()?.to_owned(), value))
                })
                .collect();
            if !query.is_empty() {
                let response = app.get_with(path, &Value::Object(query)).await;
                assert_eq!(
                    response.status(),
                    200,
                    "GET {path} with the parameter examples"
                );
                answered += 1;
            }
        }
    }
    assert!(answered >= 20, "examples were found ({answered})");
}

/// Each documented error response carries examples of its own status, each with a realistic
/// `errors` array; the 422 example is what the server really answers to its request.
#[tokio::test]
async fn every_error_status_has_its_own_example() {
    // Arrange
    let app = spawn_app().await;
    let spec = ok_json(app.get("/openapi.json").await).await;

    // Act
    let mut seen = std::collections::BTreeSet::new();
    for (path, item) in spec["paths"].as_object().unwrap() {
        for (method, op) in item.as_object().unwrap() {
            for (status, response) in op["responses"].as_object().unwrap() {
                if !status.starts_with('4') && !status.starts_with('5') {
                    continue;
                }
                let examples = response["content"]["application/problem+json"]["examples"]
                    .as_object()
                    .unwrap_or_else(|| panic!("{method} {path} {status} has examples"));

                // Assert
                assert!(!examples.is_empty(), "{method} {path} {status}");
                for example in examples.values() {
                    let value = &example["value"];
                    assert_eq!(value["status"].to_string(), *status, "{method} {path}");
                    assert!(!value["errors"].as_array().unwrap().is_empty());
                    seen.insert(status.clone());
                }
            }
        }
    }
    assert_eq!(
        seen.into_iter().collect::<Vec<_>>(),
        ["400", "401", "405", "408", "413", "415", "422", "503"]
    );
    assert!(
        spec["components"]["schemas"]["Problem"]["example"].is_null(),
        "no one example stands for every status"
    );

    let documented = &spec["paths"]["/distance"]["post"]["responses"]["422"]["content"]["application/problem+json"]
        ["examples"]["three-fields-at-fault"]["value"];
    let real = crate::helpers::problem(
        app.post(
            "/distance",
            &json!({"focal_length_px": 35, "baseline": 0, "unit": "meters", "x_left": 900,
                    "x_right": 750, "image_width": 800, "image_height": 600}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(real["errors"], documented["errors"]);
    assert_eq!(real["detail"], documented["detail"]);
}

/// `/depth-map`'s query parameters state their defaults in the document (Swagger's "Try it
/// out" shows them), and each is the engine's own: what the matcher takes when the parameter
/// is left out. `paths` and `alpha` have none (the preset's choice, the file's own), nor have
/// `min_disparity` and `max_disparity`: left out, the range (its start too) is found from the
/// pair.
#[tokio::test]
async fn the_depth_map_parameters_state_the_engines_defaults() {
    use stereo_core::vision::{Params, Settings, Subpixel};
    let app = spawn_app().await;
    let spec = ok_json(app.get("/openapi.json").await).await;
    let parameters = spec["paths"]["/depth-map"]["post"]["parameters"]
        .as_array()
        .expect("parameters");
    let default = |name: &str| {
        parameters
            .iter()
            .find(|p| p["name"] == name)
            .unwrap_or_else(|| panic!("{name}"))["schema"]["default"]
            .clone()
    };
    let engine = Params::new(&Settings::default()).expect("the defaults are valid");
    let penalties = engine.penalties();
    assert!(engine.range_found() && engine.min_found());
    assert_eq!(default("min_disparity"), Value::Null);
    assert_eq!(default("max_disparity"), Value::Null);
    assert_eq!(default("p1"), json!(penalties.p1));
    assert_eq!(default("p2"), json!(penalties.p2));
    assert_eq!(default("p2_edge"), json!(penalties.edge));
    assert_eq!(default("uniqueness"), json!(engine.uniqueness()));
    assert_eq!(default("lr_check"), json!(engine.lr_tolerance().is_some()));
    assert_eq!(
        default("lr_tolerance"),
        json!(f64::from(engine.lr_tolerance().unwrap()))
    );
    assert_eq!(engine.subpixel(), Subpixel::Equiangular);
    assert_eq!(default("subpixel"), json!("equiangular"));
    assert_eq!(default("speckle_size"), json!(engine.speckle_size()));
    assert_eq!(
        default("speckle_range"),
        json!(f64::from(engine.speckle_range()))
    );
    assert_eq!(
        default("max_disparity_std"),
        json!(engine.max_disparity_std())
    );
    assert_eq!(default("median"), json!(engine.median()));
    assert_eq!(default("fill"), json!(engine.fill()));
    assert_eq!(default("preset"), json!("accurate"));
    assert_eq!(default("output"), json!("summary"));
    assert_eq!(default("rectify"), json!("auto"));
    assert_eq!(default("projection"), json!("pinhole"));
    assert_eq!(parameters.len(), 23);
    let without: Vec<&str> = parameters
        .iter()
        .filter(|p| p["schema"]["default"].is_null())
        .filter_map(|p| p["name"].as_str())
        .collect();
    assert_eq!(
        without,
        [
            "min_disparity",
            "max_disparity",
            "paths",
            "alpha",
            "az_fov",
            "el_fov",
            "pixels_per_degree"
        ]
    );
}
