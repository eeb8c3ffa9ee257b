//! The OpenAPI document: served, committed, complete, and the Swagger UI is served offline.

use serde_json::Value;

use crate::helpers::{ok_json, spawn_app};

const COMMITTED: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/openapi/openapi.json");

/// The committed `openapi/openapi.json` is exactly the served one. Regenerate it with
/// `UPDATE_OPENAPI=1 cargo test --test api openapi`.
#[tokio::test]
async fn committed_spec_matches_generated() {
    let app = spawn_app().await;
    let served = ok_json(app.get("/openapi.json").await).await;
    let generated: Value =
        serde_json::from_str(&stereo_distance::api::openapi().to_json().unwrap()).unwrap();
    assert_eq!(served, generated, "the served spec is the generated one");
    if std::env::var_os("UPDATE_OPENAPI").is_some() {
        let text = serde_json::to_string_pretty(&served).unwrap() + "\n";
        std::fs::write(COMMITTED, text).expect("openapi/openapi.json is writable");
    }
    let committed: Value = serde_json::from_str(
        &std::fs::read_to_string(COMMITTED).expect("openapi/openapi.json is committed"),
    )
    .expect("the committed spec is JSON");
    assert!(
        committed == served,
        "openapi/openapi.json is stale: run UPDATE_OPENAPI=1 cargo test --test api openapi"
    );
}

/// Every operation is documented: GET and POST on each path, a request example, query
/// parameters on GET, and problem+json error responses.
#[tokio::test]
async fn every_operation_is_documented() {
    let app = spawn_app().await;
    let spec = ok_json(app.get("/openapi.json").await).await;
    for path in ["/distance", "/table", "/chart-data"] {
        let post = &spec["paths"][path]["post"];
        let get = &spec["paths"][path]["get"];
        let body_ref = post["requestBody"]["content"]["application/json"]["schema"]["$ref"]
            .as_str()
            .unwrap_or_else(|| panic!("{path} POST has a body schema"));
        let name = body_ref.rsplit('/').next().unwrap();
        let schema = &spec["components"]["schemas"][name];
        assert!(schema["example"].is_object(), "{name} has an example");
        assert_eq!(
            schema["additionalProperties"], false,
            "{name} refuses unknown members"
        );
        let properties = schema["properties"].as_object().unwrap();
        let params = get["parameters"].as_array().unwrap();
        assert_eq!(
            params.len(),
            properties.len(),
            "GET {path} takes every member"
        );
        for op in [post, get] {
            assert!(op["responses"]["200"]["content"]["application/json"]["schema"].is_object());
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
}

/// Optional request members are optional, not nullable.
#[tokio::test]
async fn optional_members_are_not_nullable() {
    let spec = serde_json::to_value(stereo_distance::api::openapi()).unwrap();
    let text = spec["components"]["schemas"].to_string();
    assert!(!text.contains("\"null\""), "a schema admits null");
    let required = &spec["components"]["schemas"]["DistanceRequest"]["required"];
    for member in [
        "baseline",
        "image_width",
        "image_height",
        "x_left",
        "x_right",
    ] {
        assert!(
            required.as_array().unwrap().iter().any(|r| r == member),
            "{member} is required"
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
