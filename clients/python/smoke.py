"""Uses the Python client that openapi-python-client generates from the served /openapi.json to
reach every kind of answer the service gives, and checks the numbers.

    python3 clients/python/smoke.py http://127.0.0.1:8080 [TOKEN]

With a TOKEN (a service started with API_TOKENS), every call goes through the generated
AuthenticatedClient, and a client without the token is checked to get the 401 problem.

scripts/contract/clients generates the client (with clients/python/openapi-python-client.yaml) into
target/clients/python and puts it on the path before running this. Exits non-zero on the first
answer that is not what the service promises.
"""

import csv
import io
import math
import sys

from stereo_distance_client import AuthenticatedClient, Client
from stereo_distance_client.api.calibration import post_calibration
from stereo_distance_client.api.chart import get_chart_data_csv, get_chart_svg
from stereo_distance_client.api.distance import get_distance, post_distance
from stereo_distance_client.api.images import post_depth_map, post_match
from stereo_distance_client.api.planning import get_rig
from stereo_distance_client.api.table import post_table, post_table_csv
from stereo_distance_client.models import (
    BatchDistanceRequest,
    BatchDistanceResponse,
    BatchPoint,
    CalibrationResponse,
    DepthMapForm,
    DepthMapSummary,
    DistanceResponse,
    FormatChoice,
    MatchForm,
    MatchPoint,
    MatchResponse,
    Problem,
    RigResponse,
    StereoRig,
    TableRequest,
    TableResponse,
    Unit,
)
from stereo_distance_client.types import File

# KITTI's rectified colour pair (calib_cam_to_cam.txt, 2011_09_26), in metres.
F, B, CX, CY = 721.5377, 0.54, 609.5593, 172.854


def check(condition, what):
    if not condition:
        raise SystemExit(f"check failed: {what}")


def close(actual, expected, what):
    check(math.isclose(actual, expected, rel_tol=1e-9), f"{what}: {actual} is not {expected}")


def main(base, token=None):
    if token:
        client = AuthenticatedClient(base_url=base, token=token, raise_on_unexpected_status=True)
        # Without the token: the documented 401, read as the client's Problem.
        bare = Client(base_url=base, raise_on_unexpected_status=True)
        refused = get_distance.sync_detailed(
            client=bare, focal_length_px=F, baseline=B, unit=Unit.M, x_left=620, x_right=610
        )
        check(refused.status_code == 401, f"no token answered {refused.status_code}")
        check(isinstance(refused.parsed, Problem), f"the 401 parsed as {refused.parsed!r}")
        check(refused.headers.get("www-authenticate", "").startswith("Bearer"), "WWW-Authenticate")
        print(f"without a token: 401 {refused.parsed.errors[0].field}: {refused.parsed.errors[0].message}")
    else:
        client = Client(base_url=base, raise_on_unexpected_status=True)

    # One distance, GET with the query built by the client: Z = f·B / d.
    one = get_distance.sync(
        client=client, focal_length_px=F, baseline=B, unit=Unit.M, cx=CX, cy=CY, x_left=620, x_right=610
    )
    check(isinstance(one, DistanceResponse), f"GET /distance answered {one!r}")
    close(one.distance, F * B / 10, "distance")
    print(f"distance: {one.distance:.4f} {one.unit.value} ± {one.depth_error:.4f}, range {one.range_:.4f}")

    # A batch: each point answered in order, one given as a disparity.
    rig = StereoRig(focal_length_px=F, baseline=B, unit=Unit.M, cx=CX, cy=CY)
    batch = post_distance.sync(
        client=client,
        body=BatchDistanceRequest(
            rig=rig, points=[BatchPoint(x_left=620, x_right=610), BatchPoint(disparity_px=20)]
        ),
    )
    check(isinstance(batch, BatchDistanceResponse), f"batch answered {batch!r}")
    check(batch.count == 2 and batch.failed == 0, "two points, none failed")
    distances = [result.distance for result in batch.results]
    for got, d in zip(distances, [10, 20]):
        close(got, F * B / d, f"batch point at {d} px")
    print(f"batch: {batch.count} points, distances {[round(z, 4) for z in distances]}")

    # The table as JSON and as CSV: the same rows.
    request = TableRequest(
        focal_length_px=F, baseline=B, unit=Unit.M, cx=CX, cy=CY, disparity_min=1, disparity_max=100, steps=4
    )
    table = post_table.sync(client=client, body=request)
    check(isinstance(table, TableResponse), f"POST /table answered {table!r}")
    check(len(table.rows) == 4, "four rows")
    text = post_table_csv.sync(client=client, body=request)
    check(isinstance(text, str), f"POST /table.csv answered {text!r}")
    rows = list(csv.DictReader(io.StringIO(text)))
    check(len(rows) == 4, "four CSV lines")
    for row, line in zip(table.rows, rows):
        close(float(line["distance_m"]), row.distance, "CSV distance = JSON distance")
        close(row.distance * row.disparity_px, F * B, "Z·d = f·B")
    print(f"table: {len(table.rows)} rows as JSON; CSV columns {list(rows[0])}")

    chart_csv = get_chart_data_csv.sync(
        client=client, focal_length_px=F, baseline=B, unit=Unit.M, cx=CX, cy=CY, disparity_min=1,
        disparity_max=128, points=3,
    )
    check(isinstance(chart_csv, str) and chart_csv.startswith("disparity_px,distance_m"), "chart CSV")

    # The chart as SVG text.
    svg = get_chart_svg.sync(
        client=client, focal_length_px=F, baseline=B, unit=Unit.M, cx=CX, cy=CY, disparity_px=38.5,
        disparity_min=1, disparity_max=128,
    )
    check(isinstance(svg, str) and "<svg" in svg and svg.rstrip().endswith("</svg>"), f"SVG, got {svg!r}")
    print(f"chart.svg: {len(svg)} characters of SVG")

    # A list parameter, sent the way this client sends lists (repeated).
    planned = get_rig.sync(
        client=client, focal_length_px=424, baseline=50, image_width=848, image_height=480,
        disparity_error_px=0.08, max_disparity_px=126, at_distances=[500, 2000],
    )
    check(isinstance(planned, RigResponse), f"GET /rig answered {planned!r}")
    check([at.distance for at in planned.at_distances] == [500, 2000], "both distances, in order")
    print(f"rig: error at 2 m = {planned.at_distances[1].depth_error:.2f} mm")

    # A calibration file sent as the raw body.
    middlebury = (
        b"cam0=[3979.911 0 1244.772; 0 3979.911 1019.507; 0 0 1]\n"
        b"cam1=[3979.911 0 1369.115; 0 3979.911 1019.507; 0 0 1]\n"
        b"doffs=124.343\nbaseline=193.001\nwidth=2964\nheight=1988\nndisp=270\n"
    )
    calibration = post_calibration.sync(
        client=client, body=File(payload=io.BytesIO(middlebury), file_name="calib.txt"),
        format_=FormatChoice.AUTO,
    )
    check(isinstance(calibration, CalibrationResponse), f"POST /calibration answered {calibration!r}")
    close(calibration.rig.focal_length_px, 3979.911, "calibrated focal length")
    print(f"calibration: {calibration.format_.value}, f = {calibration.rig.focal_length_px} px")

    # A depth map of the page's sample pair with its Middlebury file: the summary's σ of the
    # disparities and depths (each pixel's standard deviation), then a point's match with its σ.
    sample = {name: client.get_httpx_client().get(f"/sample/{name}").content
              for name in ("left.png", "right.png", "calib.txt")}
    files = lambda: dict(  # noqa: E731
        left=File(payload=io.BytesIO(sample["left.png"]), file_name="left.png", mime_type="image/png"),
        right=File(payload=io.BytesIO(sample["right.png"]), file_name="right.png", mime_type="image/png"),
        calibration=File(payload=io.BytesIO(sample["calib.txt"]), file_name="calib.txt"),
    )
    summary = post_depth_map.sync(client=client, body=DepthMapForm(**files()))
    check(isinstance(summary, DepthMapSummary), f"POST /depth-map answered {summary!r}")
    sd, sz = summary.disparity_std_px, summary.distance_std
    check(0 < sd.min_ <= sd.median <= sd.max_ and 0 < sz.median, f"sigma spreads {sd!r} {sz!r}")
    print(f"depth map: {summary.valid_fraction:.1%} valid, median sigma_d {sd.median} px, "
          f"median sigma_Z {sz.median} mm")
    strict = post_depth_map.sync(client=client, body=DepthMapForm(**files()), max_disparity_std=0.3)
    check(isinstance(strict, DepthMapSummary) and strict.parameters.max_disparity_std == 0.3
          and strict.disparity_std_px.max_ <= 0.3 < sd.max_
          and strict.valid_fraction < summary.valid_fraction,
          f"max_disparity_std=0.3 kept {strict!r}")
    print(f"max_disparity_std=0.3: {strict.valid_fraction:.1%} valid")
    matched = post_match.sync(client=client, body=MatchForm(**files(), points=[MatchPoint(x=100, y=100)]))
    check(isinstance(matched, MatchResponse), f"POST /match answered {matched!r}")
    point = matched.matches[0]
    check(point.disparity_std_px > 0 and point.distance_std > 0, f"the point's sigma: {point!r}")
    print(f"match: d = {point.disparity_px} ± {point.disparity_std_px} px, "
          f"Z = {point.distance:.1f} ± {point.distance_std:.1f} mm")

    # A refused request: the problem+json, parsed, naming the field.
    response = get_distance.sync_detailed(
        client=client, focal_length_px=F, baseline=0, unit=Unit.M, cx=CX, cy=CY, x_left=620, x_right=610
    )
    problem = response.parsed
    check(response.status_code == 422 and isinstance(problem, Problem), f"a 422 problem, got {response!r}")
    check([e.field for e in problem.errors] == ["baseline"], f"names baseline: {problem.errors}")
    print(f"refused: {problem.status} {problem.detail}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "http://127.0.0.1:8080", *sys.argv[2:3])
