//! `GET /chart.svg`: a self-contained SVG whose curves pass through the computed chart points,
//! with labelled axes in units and the measured point marked.

use roxmltree::{Document, Node};
use serde_json::Value;

use crate::helpers::{fields, ok_json, problem, spawn_app};

const QUERY: &str = "focal_length_px=35&baseline=150&image_width=800&image_height=600&x_left=400&x_right=350&points=50";

fn by_id<'a, 'i>(doc: &'a Document<'i>, id: &str) -> Node<'a, 'i> {
    doc.descendants()
        .find(|n| n.attribute("id") == Some(id))
        .unwrap_or_else(|| panic!("the SVG has #{id}"))
}

fn number(node: Node, attribute: &str) -> f64 {
    node.attribute(attribute)
        .unwrap_or_else(|| panic!("{attribute} is set"))
        .parse()
        .unwrap()
}

fn vertices(node: Node) -> Vec<(f64, f64)> {
    node.attribute("points")
        .expect("a polyline has points")
        .split(' ')
        .map(|pair| {
            let (x, y) = pair.split_once(',').unwrap();
            (x.parse().unwrap(), y.parse().unwrap())
        })
        .collect()
}

/// The SVG's own mapping from data to pixels: plot area and the ranges it declares.
struct Frame {
    left: f64,
    top: f64,
    width: f64,
    height: f64,
    x: (f64, f64),
    y: (f64, f64),
    y2: (f64, f64),
}

impl Frame {
    fn read(doc: &Document) -> Self {
        let area = by_id(doc, "plot-area");
        let plot = by_id(doc, "plot");
        Self {
            left: number(area, "x"),
            top: number(area, "y"),
            width: number(area, "width"),
            height: number(area, "height"),
            x: (number(plot, "data-x-min"), number(plot, "data-x-max")),
            y: (number(plot, "data-y-min"), number(plot, "data-y-max")),
            y2: (number(plot, "data-y2-min"), number(plot, "data-y2-max")),
        }
    }

    fn pixel(&self, x: f64, y: f64, (lo, hi): (f64, f64)) -> (f64, f64) {
        (
            self.left + (x - self.x.0) / (self.x.1 - self.x.0) * self.width,
            self.top + self.height - (y - lo) / (hi - lo) * self.height,
        )
    }
}

/// Both curves pass through every computed /chart-data point (to the SVG's 0.01 px rounding),
/// the measured point is marked where it belongs, and the axes are labelled with units.
#[tokio::test]
async fn curves_pass_through_computed_points() {
    // Arrange
    let app = spawn_app().await;
    let data = ok_json(app.get(&format!("/chart-data?{QUERY}")).await).await;

    // Act
    let response = app.get(&format!("/chart.svg?{QUERY}")).await;

    // Assert
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "image/svg+xml");
    let text = response.text().await.unwrap();
    let doc = Document::parse(&text).expect("the SVG is well-formed XML");
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "svg");
    assert_eq!(
        root.tag_name().namespace(),
        Some("http://www.w3.org/2000/svg")
    );
    let frame = Frame::read(&doc);
    for (id, series, range) in [
        ("distance-curve", 0, frame.y),
        ("depth-error-curve", 1, frame.y2),
    ] {
        let points = data["series"][series]["points"].as_array().unwrap();
        let drawn = vertices(by_id(&doc, id));
        assert_eq!(drawn.len(), points.len(), "{id}: one vertex per point");
        for (p, (px, py)) in points.iter().zip(&drawn) {
            let (ex, ey) = frame.pixel(p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap(), range);
            assert!(
                (px - ex).abs() <= 0.006 && (py - ey).abs() <= 0.006,
                "{id}: vertex ({px}, {py}) is not the point at ({ex}, {ey})"
            );
        }
    }
    // Read back from pixels, the distance curve is Z = f·B/d to within a pixel's rounding.
    for (px, py) in vertices(by_id(&doc, "distance-curve")) {
        let d = frame.x.0 + (px - frame.left) / frame.width * (frame.x.1 - frame.x.0);
        let z =
            frame.y.0 + (frame.top + frame.height - py) / frame.height * (frame.y.1 - frame.y.0);
        let per_px = (frame.y.1 - frame.y.0) / frame.height;
        let slope = 5250.0 / (d * d) * (frame.x.1 - frame.x.0) / frame.width;
        assert!(
            (z - 5250.0 / d).abs() <= 0.006 * (per_px + slope),
            "({d}, {z}) lies on Z = f·B/d"
        );
    }
    let marker = by_id(&doc, "measured-point");
    let (mx, my) = frame.pixel(50.0, 105.0, frame.y);
    assert!((number(marker, "cx") - mx).abs() <= 0.006);
    assert!((number(marker, "cy") - my).abs() <= 0.006);
    let label = |id: &str| by_id(&doc, id).text().unwrap().to_owned();
    assert_eq!(label("x-label"), "Disparity d (px)");
    assert_eq!(label("y-label"), "Distance Z (mm)");
    assert_eq!(label("y2-label"), "Depth error ΔZ (mm)");
    assert!(
        doc.descendants()
            .any(|n| n.text() == Some("d = 50 px, Z = 105 mm")),
        "the marker is labelled"
    );
}

/// The SVG is self-contained: no scripts, no links, no external resources, and it has a title
/// for screen readers.
#[tokio::test]
async fn svg_is_self_contained() {
    let app = spawn_app().await;
    let text = app
        .get("/chart.svg?focal_length_px=35&baseline=0.15&unit=m&image_width=800&image_height=600&x_left=400&x_right=350")
        .await
        .text()
        .await
        .unwrap();
    let doc = Document::parse(&text).unwrap();
    for node in doc.descendants().filter(Node::is_element) {
        let name = node.tag_name().name();
        assert!(
            !["script", "image", "foreignObject", "a", "style", "use"].contains(&name),
            "<{name}>"
        );
        for attribute in node.attributes() {
            assert!(
                !attribute.name().contains("href"),
                "{} links out",
                attribute.name()
            );
            assert!(
                !attribute.name().starts_with("on"),
                "{} is a script",
                attribute.name()
            );
        }
    }
    assert!(
        !text
            .replace("http://www.w3.org/2000/svg", "")
            .contains("http")
    );
    assert_eq!(by_id(&doc, "chart-title").tag_name().name(), "title");
    assert_eq!(by_id(&doc, "y-label").text(), Some("Distance Z (m)"));
}

/// A measured point outside an explicit range is noted, not drawn off the plot.
#[tokio::test]
async fn marker_outside_the_range_is_noted() {
    let app = spawn_app().await;
    let text = app
        .get(&format!(
            "/chart.svg?{QUERY}&disparity_min=100&disparity_max=200"
        ))
        .await
        .text()
        .await
        .unwrap();
    let doc = Document::parse(&text).unwrap();
    assert!(
        doc.descendants()
            .all(|n| n.attribute("id") != Some("measured-point"))
    );
    assert!(
        by_id(&doc, "marker-note")
            .text()
            .unwrap()
            .contains("outside the plotted range")
    );
}

/// Bad queries get the same problem+json as /chart-data.
#[tokio::test]
async fn bad_svg_query_is_422() {
    let app = spawn_app().await;
    let body: Value = problem(
        app.get("/chart.svg?focal_length_mm=4&baseline=150").await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["focal_length_mm"]);
}
