"""Issues 56 and 68: real indoor pairs from a consumer stereo camera: how many pixels each
matcher answers (density) and, where both answer, how many agree within 1 px; and, since each
pair holds a photographed board, who is right where the two disagree on it.

The pairs are OpenCV's own 13 stereo photographs (samples/data left01.jpg ... right14.jpg,
640 x 480 grey, a person holding a 9 x 6 board in an office: walls, a desk, a monitor, a
keyboard; from Debian's opencv-doc 4.6.0, Apache-2.0 / BSD-3-Clause, committed under
tests/data/photographs/opencv-stereo/). The service calibrates the rig from them (/calibrate),
rectifies each pair (/rectify), and matches it (/depth-map, defaults); OpenCV 4.14 StereoSGBM
matches the same rectified pair in every mode with blocks 3 and 5 (as scripts/evaluations/stereo.py
sets it). Each pair is searched as its user would search it, past the nearest thing in it: the
board held in front, whose largest disparity board_truth.py's plane gives (plus 8 px, a multiple
of 16; at least 96). A fixed 96 disparities, which falls short of the whole board in every pair
(99-213 px), is printed too: there OpenCV answers what lies past the range and we mostly refuse it.

Printed per pair, with the medians: density (ours, OpenCV HH4's denser block, which the issue
names, and the densest mode), agreement with HH4 (all, off the board, on it) and, where the two
disagree, the share on the board and there who is within 1 px of the board's plane. Then the
keep rule (max_disparity_std, with and without the uniqueness and speckle rules). Reported, not
floored.

    PYTHONPATH=scripts python3 -m evaluations.indoor --url URL [--photographs DIR] [--json FILE]
"""
import argparse
import json
import math
from pathlib import Path

import cv2
import numpy as np

from . import peers, scoring, service, sigma
from .board_truth import board_truth, search_range

NAMES = ["01", "02", "03", "04", "05", "06", "07", "08", "09", "11", "12", "13", "14"]
BOARD = {"columns": 9, "rows": 6, "square_size": 1.0, "unit": "mm"}
DISPARITIES = 96
AGREE_PX = 1.0
# The floors (exit 1 below them): density at least OpenCV HH4's, the issue's goal, met (53.9
# against 47.1 %, docs/matcher.md); agreement with it, not met (goal 90 %), a regression floor a
# little below today's 80.9 %: most disagreements lie on the board, where the plane says we are
# the one right in 72 % of them.
FLOORS = {"density_over_hh4": 1.0, "agreement": 0.78}
MODES = {"SGBM": cv2.STEREO_SGBM_MODE_SGBM, "HH": cv2.STEREO_SGBM_MODE_HH,
         "SGBM_3WAY": cv2.STEREO_SGBM_MODE_SGBM_3WAY, "HH4": cv2.STEREO_SGBM_MODE_HH4}


def calibrated(url, folder):
    """The 13 raw pairs' JPEG bytes by name, and the calibration the service makes from all
    of them (OpenCV's YAML)."""
    files = {n: (Path(folder, f"left{n}.jpg").read_bytes(), Path(folder, f"right{n}.jpg").read_bytes())
             for n in NAMES}
    parts = []
    for n, (l, r) in files.items():
        parts += [("left", (l, f"left{n}.jpg", "image/jpeg")),
                  ("right", (r, f"right{n}.jpg", "image/jpeg"))]
    parts.append(("board", (json.dumps(BOARD).encode(), None, "application/json")))
    return files, service.post_once(url, "/calibrate?output=opencv.yml", parts)


def rectified_pairs(url, folder):
    """The calibration from all 13 pairs, then each pair rectified by the service: (name,
    left, right) as 8-bit grey arrays."""
    files, calibration = calibrated(url, folder)
    for n, (l, r) in files.items():
        images = []
        for side in ("left", "right"):
            png = service.post_once(url, f"/rectify?output={side}.png", {
                "left": (l, "left.jpg", "image/jpeg"), "right": (r, "right.jpg", "image/jpeg"),
                "calibration": (calibration, "opencv.yml", "application/x-yaml")})
            images.append(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_GRAYSCALE))
        yield n, images[0], images[1]


def ours(url, left, right, query="", disparities=DISPARITIES):
    """Our /depth-map's disparity for the pair ([`sigma.ours`])."""
    return sigma.ours(url, left, right, disparities, query)["disparity"]


def agreement(mine, other, where=None):
    """The share of the pixels both maps answer (within `where`, when given) whose disparities
    agree within AGREE_PX."""
    both = np.isfinite(mine) & np.isfinite(other)
    if where is not None:
        both &= where
    return float(np.mean(np.abs(mine[both] - other[both]) <= AGREE_PX)) if both.any() else 0.0


def arbitration(mine, other, board):
    """Where the two maps disagree (both answer, more than AGREE_PX apart): the share of those
    pixels on the board, and, on the board, the shares where ours is right (within 1 px of the
    board's plane), where theirs is, and where neither is. `board` is eval_board's truth."""
    mask, plane = board[0], board[1]
    differ = np.isfinite(mine) & np.isfinite(other) & (np.abs(mine - other) > AGREE_PX)
    on = differ & mask
    n = max(int(on.sum()), 1)
    ours_right = np.abs(mine - plane) <= 1
    theirs_right = np.abs(other - plane) <= 1
    return {"on_board": float(on.sum() / max(int(differ.sum()), 1)),
            "ours_right": float(np.sum(on & ours_right) / n),
            "theirs_right": float(np.sum(on & theirs_right) / n),
            "neither": float(np.sum(on & ~ours_right & ~theirs_right) / n)}


def boards(url, folder, scale=1.0, names=None):
    """Each pair rectified by the service ([`rectified_pairs`]), enlarged `scale` times
    (bicubic) unless 1, with its board's truth (board_truth's, None where the board is not
    found): (name, left, right, truth), for the pairs in `names` (all when None)."""
    for name, left, right in rectified_pairs(url, folder):
        if names is not None and name not in names:
            continue
        if scale != 1:
            left, right = (cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC)
                           for img in (left, right))
        yield name, left, right, board_truth(left, right)


def scene_range(left, right):
    """The disparities a user would search for this pair: past the nearest thing in it, the
    board held in front (eval_board's rule: its largest disparity plus 8 px, a multiple of 16),
    with the board's truth; DISPARITIES and None when the board is not found."""
    truth = board_truth(left, right)
    if truth is None:
        return DISPARITIES, None
    return max(search_range(truth[1], truth[0]), DISPARITIES), truth


def arguments():
    """The command line of this script and of board.py: --url, --photographs, --json."""
    parser = argparse.ArgumentParser()
    parser.add_argument("--url", required=True)
    parser.add_argument("--photographs", default="tests/data/photographs/opencv-stereo")
    parser.add_argument("--json")
    return parser.parse_args()


def density(disp):
    """The share of the pixels with a value."""
    return float(np.mean(np.isfinite(disp)))


def main():
    args = arguments()
    cv2.setNumThreads(2)
    rows = []
    for name, left, right in rectified_pairs(args.url, args.photographs):
        ndisp, truth = scene_range(left, right)
        mine = ours(args.url, left, right, disparities=ndisp)
        theirs = {f"{mode} b{block}": peers.sgbm(left, right, flag, block, ndisp, 1)[0]
                  for mode, flag in MODES.items() for block in (3, 5)}
        kept = {rule: ours(args.url, left, right, "&" + rule, ndisp) for rule in service.KEEP_RULES}
        fixed = (ours(args.url, left, right),
                 peers.sgbm(left, right, MODES["HH4"], 5, DISPARITIES, 1)[0])
        rows.append({"name": name, "ndisp": ndisp, "truth": truth, "mine": mine,
                     "theirs": theirs, "kept": kept, "fixed": fixed})
    modes = list(rows[0]["theirs"])
    by_density = lambda m: np.median([density(r["theirs"][m]) for r in rows])  # noqa: E731
    densest = max(modes, key=by_density)
    hh4 = max(["HH4 b3", "HH4 b5"], key=by_density)
    print(f"Issue 56 / 68: real indoor pairs (OpenCV's samples/data, 13 pairs of 640 x 480 grey, "
          f"calibrated and rectified by the service), each searched past the nearest thing in "
          f"it (the board held in front: its largest disparity + 8 px, a multiple of 16); OpenCV "
          f"{cv2.__version__} in the same run: HH4's denser block {hh4}, the densest mode {densest}")
    header = (f"{'pair':<5} {'range':>5} {'ours':>6} {hh4:>7} {densest:>12} {'agree':>6} "
              f"{'off board':>9} {'on board':>8} | {'on board':>8} {'ours ok':>7} "
              f"{'theirs ok':>9} {'neither':>7}")
    print("density, agreement within 1 px with " + hh4 + " (all, off the board, on it) | where "
          "the two disagree: the share on the board, and there who is right (within 1 px of "
          "the board's plane)")
    print(header)
    print("-" * len(header))
    results = []
    for r in rows:
        mine, other = r["mine"], r["theirs"][hh4]
        row = {"pair": r["name"], "disparities": r["ndisp"], "density": density(mine),
               "hh4_density": density(other), "densest_density": density(r["theirs"][densest]),
               "agreement": agreement(mine, other)}
        if r["truth"] is not None:
            row["agreement_off_board"] = agreement(mine, other, ~r["truth"][0])
            row["agreement_on_board"] = agreement(mine, other, r["truth"][0])
            row.update({f"disagree_{k}": v for k, v in
                        arbitration(mine, other, r["truth"]).items()})
        results.append(row)
        cells = [row.get(k, math.nan) for k in
                 ("agreement_off_board", "agreement_on_board", "disagree_on_board",
                  "disagree_ours_right", "disagree_theirs_right", "disagree_neither")]
        print(f"{r['name']:<5} {r['ndisp']:>5} {100 * row['density']:5.1f}% "
              f"{100 * row['hh4_density']:6.1f}% {100 * row['densest_density']:11.1f}% "
              f"{100 * row['agreement']:5.1f}% {100 * cells[0]:8.1f}% {100 * cells[1]:7.1f}% | "
              f"{100 * cells[2]:7.1f}% {100 * cells[3]:6.1f}% {100 * cells[4]:8.1f}% "
              f"{100 * cells[5]:6.1f}%")
    keys = [k for k in results[0] if k not in ("pair", "disparities")]
    med = {k: float(np.nanmedian([r.get(k, math.nan) for r in results])) for k in keys}
    print(f"{'median':<11} {100 * med['density']:5.1f}% {100 * med['hh4_density']:6.1f}% "
          f"{100 * med['densest_density']:11.1f}% {100 * med['agreement']:5.1f}% "
          f"{100 * med['agreement_off_board']:8.1f}% {100 * med['agreement_on_board']:7.1f}% | "
          f"{100 * med['disagree_on_board']:7.1f}% {100 * med['disagree_ours_right']:6.1f}% "
          f"{100 * med['disagree_theirs_right']:8.1f}% {100 * med['disagree_neither']:6.1f}%")
    dense = med["density"] >= med["hh4_density"]
    agrees = med["agreement"] >= 0.9
    print(f"goals: density at least OpenCV HH4's: {'met' if dense else 'NOT met'}; agreement "
          f"with it at least 90 %: {'met' if agrees else 'NOT met'}")
    failures = []
    ratio = med["density"] / max(med["hh4_density"], 1e-9)
    if ratio < FLOORS["density_over_hh4"]:
        failures.append(f"density {ratio:.2f} x OpenCV HH4's, floor {FLOORS['density_over_hh4']}")
    if med["agreement"] < FLOORS["agreement"]:
        failures.append(f"agreement {100 * med['agreement']:.1f} %, floor "
                        f"{100 * FLOORS['agreement']:.0f} %")
    fixed = {"density": float(np.median([density(r["fixed"][0]) for r in rows])),
             "hh4_b5_density": float(np.median([density(r["fixed"][1]) for r in rows])),
             "agreement": float(np.median([agreement(*r["fixed"]) for r in rows]))}
    print(f"At a fixed {DISPARITIES} disparities (short of the whole board in every pair: OpenCV answers "
          f"what lies past the range, we mostly refuse it): ours {100 * fixed['density']:.1f}%, "
          f"HH4 b5 {100 * fixed['hh4_b5_density']:.1f}%, agreement "
          f"{100 * fixed['agreement']:.1f}%")
    print(f"\nThe keep rule (max_disparity_std; default 4 px with the other rules on), medians "
          f"over the set against {hh4}:")
    header = f"{'settings':<52} {'density':>8} {'agree <= 1 px':>14}"
    print(header)
    print("-" * len(header))
    keep = {}
    for rule in ["defaults"] + service.KEEP_RULES:
        maps = [(r["mine"] if rule == "defaults" else r["kept"][rule], r["theirs"][hh4])
                for r in rows]
        keep[rule] = {"density": float(np.median([density(m) for m, _ in maps])),
                      "agreement": float(np.median([agreement(m, o) for m, o in maps]))}
        print(f"{rule:<52} {100 * keep[rule]['density']:7.1f}% "
              f"{100 * keep[rule]['agreement']:13.1f}%")
    if args.json:
        Path(args.json).write_text(json.dumps(
            {"hh4_mode": hh4, "densest_mode": densest, "pairs": results, "median": med,
             "fixed_range": fixed, "keep_rule": keep}, indent=1))
    scoring.floors(failures, "real indoor pairs")


if __name__ == "__main__":
    main()
