"""Issue 68: depth on real photographs scored against the truth a photographed board carries.

In a rectified pair, a chessboard's inner corners are found in both images to about a tenth of a
pixel (OpenCV's findChessboardCorners + cornerSubPix), and a plane's disparity is affine in the
image, d = a*x + b*y + c. Fitted to the corners' disparities, it gives the true disparity over
the whole board: the corner grid extended by half a square on every side (a homography from the
grid to the left image draws that outline; the rectified image has no lens distortion left).

The pairs are OpenCV's own 13 stereo photographs (tests/data/photographs/opencv-stereo/, its
LICENCE.md: Apache-2.0 / BSD-3-Clause), calibrated by /calibrate and rectified by /rectify
(indoor.rectified_pairs). Each pair is searched past its board's largest disparity (the
next multiple of 16 above it plus 8 px), by our /depth-map with its defaults and by OpenCV
4.14's StereoSGBM in its four modes with blocks 3 and 5 (as scripts/evaluations/stereo.py sets them),
on the same rectified images in the same run. Over the board's pixels, per pair:

- answered: the share of the board with a value;
- wrong > 1 px and > 2 px: of those answered;
- right: answered and within 1 px, of the board;
- ours only: the errors within 1, 2 and 3 sigma_d (pooled over the pairs), and the confident
  wrong pixels (sigma_d < 1 px, error > 2 px) of those answered;
- ours with max_disparity_std=1: wrong > 2 px of those answered.

Issue 92, the user as they are, on the same pairs: the defaults (no range given: the service
finds it from the pair) against the covering range; a range that stops short of the board
(80 % of its least disparity, rounded down to 16): its confident wrong pixels (sigma_d < 1 px,
error > 2 px) as a share of the board, and whether the summary's warnings name max_disparity;
and the pair sent swapped (left as right): named as swapped, and the right way round not.

Then the issue's goals (medians over the pairs, each OpenCV figure its best mode's for that
figure), each met or not, and the floors this run must keep (exit 1 below them): accuracy only,
never a time. The goals not yet met are floored at today's level so that nothing slides back.

    PYTHONPATH=scripts python3 -m evaluations.board --url URL [--photographs DIR] [--json FILE]
"""
import json
import sys
from pathlib import Path

import cv2
import numpy as np

from . import indoor, peers, scoring, service, sigma
from .board_truth import board_truth, search_range

MODES = indoor.MODES
# The floors (exit 1 below them). The goals met are floored at the goal itself: answered-right,
# wrong > 1 px, the 1 and 2 sigma goals and max_disparity_std=1's wrong > 2 px (docs/matcher.md,
# "Real photographs: truth from the board's plane"). The 3 sigma goal, not met, is a regression
# floor a little below today's 95.3 %. The last checks the truth itself.
FLOORS = {
    "right_over_opencv": 1.20,      # our median answered-right over OpenCV's best mode's
    "wrong1_over_opencv": 0.60,     # our median wrong > 1 px over OpenCV's least
    "within_1sigma": (0.60, 0.76),  # pooled, 68 +- 8 %
    "within_2sigma": 0.90,          # pooled, the goal
    "within_3sigma": 0.94,          # pooled, lower bound (goal 97 %)
    "std1_wrong2": 0.05,            # max_disparity_std=1: wrong > 2 px of answered, median
    "plane_rms": 0.35,              # px: the board's corners off their fitted plane (truth check)
    # Issue 92: the defaults' answered-right over the covering range's (median), a short
    # range's confident wrong share of the board (every pair), the pairs whose short range
    # is warned of and the pairs named swapped (all of them), and the right way round (none).
    "defaults_over_covering": 0.90,
    "short_confident_wrong": 0.02,  # the goal, on every pair (today's worst 0.2 %)
}


def summary(url, left, right, query=""):
    """/depth-map's summary (JSON) of a pair."""
    answer = service.post_once(url, f"/depth-map?output=summary{query}", {
        "left": (cv2.imencode(".png", left)[1].tobytes(), "left.png", "image/png"),
        "right": (cv2.imencode(".png", right)[1].tobytes(), "right.png", "image/png")})
    return json.loads(answer)


def slips(url, left, right, plane, mask, ndisp):
    """Issue 92's passes on one pair: the defaults' score and the range they chose, a short
    range's confident wrong share of the board and its warning, the swapped pair's naming."""
    arrays = sigma.ours(url, left, right, None)
    defaults = score(arrays["disparity"], plane, mask)
    said = summary(url, left, right)
    short = max(16, int(0.8 * float(np.min(plane[mask]))) // 16 * 16)
    arrays = sigma.ours(url, left, right, short)
    d, s, t = arrays["disparity"][mask], arrays["disparity_std"][mask], plane[mask]
    answered = np.isfinite(d)
    confident_wrong = float(np.sum(answered & (s < 1) & (np.abs(d - t) > 2)) / mask.sum())
    short_said = summary(url, left, right, f"&max_disparity={short}")["warnings"]
    swapped_said = summary(url, right, left)["warnings"]
    named = lambda ws: any("look swapped" in w for w in ws)  # noqa: E731
    return {"defaults": defaults, "range": [said["min_disparity"], said["max_disparity"]],
            "chosen": said["disparity_range"]["chosen"], "short": short,
            "short_confident_wrong": confident_wrong,
            "short_warned": any(w.startswith(f"max_disparity {short} stops short") for w in short_said),
            # The short range's refusals are not a raw pair's sign.
            "short_called_raw": any("need rectifying" in w for w in short_said),
            "swapped_named": named(swapped_said), "right_way_named": named(said["warnings"])}


def raw_swaps(url, folder):
    """Issue 92's raw pass: each raw pair with the calibration, as sent and swapped: whether
    /depth-map names it swapped. (name, swapped named, the right way round named)."""
    files, calibration = indoor.calibrated(url, folder)
    named = lambda ws: any("look swapped" in w for w in ws)  # noqa: E731
    for n, (l, r) in files.items():
        said = []
        for a, b in ((r, l), (l, r)):
            said.append(named(json.loads(service.post_once(url, "/depth-map?output=summary", {
                "left": (a, "left.jpg", "image/jpeg"), "right": (b, "right.jpg", "image/jpeg"),
                "calibration": (calibration, "opencv.yml", "application/x-yaml")}))["warnings"]))
        yield n, said[0], said[1]


def score(disp, truth, mask):
    """answered, wrong > 1 and > 2 px of those answered, and right of the board."""
    d, t = disp[mask], truth[mask]
    answered = np.isfinite(d)
    err = np.abs(d - t)
    n = max(int(answered.sum()), 1)
    return {
        "answered": float(answered.mean()),
        "wrong1": float(np.sum(answered & (err > 1)) / n),
        "wrong2": float(np.sum(answered & (err > 2)) / n),
        "right": float(np.mean(answered & (err <= 1))),
    }


def main():
    args = indoor.arguments()
    cv2.setNumThreads(2)
    pairs, skipped = [], []
    pooled = {"err": [], "std": []}
    for name, left, right in indoor.rectified_pairs(args.url, args.photographs):
        truth = board_truth(left, right)
        if truth is None:
            skipped.append(name)
            continue
        mask, plane, rms, rows = truth
        ndisp = search_range(plane, mask)
        arrays = sigma.ours(args.url, left, right, ndisp)
        disp, std = arrays["disparity"], arrays["disparity_std"]
        kept = sigma.ours(args.url, left, right, ndisp, "&max_disparity_std=1")["disparity"]
        row = {"pair": name, "disparities": ndisp, "board_pixels": int(mask.sum()),
               "plane_rms": rms, "row_disagreement": rows, "ours": score(disp, plane, mask)}
        d, s, t = disp[mask], std[mask], plane[mask]
        answered = np.isfinite(d)
        err = np.abs(d - t)[answered]
        row["ours"]["confident_wrong"] = float(np.sum((s[answered] < 1) & (err > 2))
                                               / max(len(err), 1))
        row["ours_std1"] = score(kept, plane, mask)
        pooled["err"].append(err)
        pooled["std"].append(s[answered])
        row["slips"] = slips(args.url, left, right, plane, mask, ndisp)
        row["opencv"] = {f"{mode} b{block}": score(
            peers.sgbm(left, right, flag, block, ndisp, 1)[0], plane, mask)
            for mode, flag in MODES.items() for block in (3, 5)}
        pairs.append(row)
    if not pairs:
        sys.exit("no board found in any pair")
    err, std = np.concatenate(pooled["err"]), np.concatenate(pooled["std"])
    within = {k: float(np.mean(err <= k * std)) for k in (1, 2, 3)}

    med = lambda f: float(np.median([f(r) for r in pairs]))  # noqa: E731
    modes = list(pairs[0]["opencv"])
    ours_med = {k: med(lambda r, k=k: r["ours"][k]) for k in pairs[0]["ours"]}
    std1_med = {k: med(lambda r, k=k: r["ours_std1"][k]) for k in pairs[0]["ours_std1"]}
    opencv_med = {m: {k: med(lambda r, m=m, k=k: r["opencv"][m][k]) for k in pairs[0]["opencv"][m]}
                  for m in modes}
    best_right = max(modes, key=lambda m: opencv_med[m]["right"])
    best_wrong = min(modes, key=lambda m: opencv_med[m]["wrong1"])

    print(f"Issue 68: real photographs, truth from the board's plane (OpenCV's 13 stereo "
          f"photographs, 640 x 480, calibrated and rectified by the service; OpenCV "
          f"{cv2.__version__} in the same run). Percentages of the board's pixels (answered, "
          f"right) or of those answered (wrong).")
    if skipped:
        print(f"board not found in both images of: {', '.join(skipped)}")
    header = (f"{'pair':<5} {'ndisp':>5} {'plane':>6} {'method':<14} {'answered':>8} "
              f"{'wrong>1':>8} {'wrong>2':>8} {'right':>7} {'conf.wrong':>10}")
    print(header)
    print("-" * len(header))
    for r in pairs:
        lead = f"{r['pair']:<5} {r['disparities']:>5} {r['plane_rms']:5.2f}p"
        for label, s in [("ours", r["ours"]), ("ours, std<=1", r["ours_std1"]),
                         (best_right, r["opencv"][best_right])]:
            extra = f"{100 * s['confident_wrong']:9.1f}%" if "confident_wrong" in s else ""
            print(f"{lead} {label:<14} {100 * s['answered']:7.1f}% {100 * s['wrong1']:7.1f}% "
                  f"{100 * s['wrong2']:7.1f}% {100 * s['right']:6.1f}% {extra}")
            lead = " " * 18
    print("\nMedians over the pairs, every method:")
    header = f"{'method':<20} {'answered':>8} {'wrong>1':>8} {'wrong>2':>8} {'right':>7}"
    print(header)
    print("-" * len(header))
    for label, s in [("ours", ours_med), ("ours, std<=1", std1_med)] + [
            (f"OpenCV {m}", opencv_med[m]) for m in modes]:
        print(f"{label:<20} {100 * s['answered']:7.1f}% {100 * s['wrong1']:7.1f}% "
              f"{100 * s['wrong2']:7.1f}% {100 * s['right']:6.1f}%")
    print(f"ours: confident wrong (sigma_d < 1 px, error > 2 px) {100 * ours_med['confident_wrong']:.1f} % "
          f"of answered (median); errors within 1 / 2 / 3 sigma_d, pooled over "
          f"{len(err)} pixels: {100 * within[1]:.1f} / {100 * within[2]:.1f} / "
          f"{100 * within[3]:.1f} %")
    plane_rms = max(r["plane_rms"] for r in pairs)
    print(f"truth: the corners' RMS off their plane {min(r['plane_rms'] for r in pairs):.3f}-"
          f"{plane_rms:.3f} px, their rows' median disagreement "
          f"{np.median([r['row_disagreement'] for r in pairs]):.3f} px")

    print("\nIssue 92, the user as they are (no range given; a range short of the board; the pair "
          "swapped):")
    header = (f"{'pair':<5} {'cover':>5} {'found':>9} {'right':>7} {'default':>8} "
              f"{'short':>5} {'conf.wrong':>10} {'warned':>6} {'swapped':>7} {'as sent':>7}")
    print(header)
    print("-" * len(header))
    for r in pairs:
        k = r["slips"]
        print(f"{r['pair']:<5} {r['disparities']:>5} {k['range'][0]:>3}..{k['range'][1]:<4} "
              f"{100 * r['ours']['right']:6.1f}% {100 * k['defaults']['right']:7.1f}% "
              f"{k['short']:>5} {100 * k['short_confident_wrong']:9.1f}% "
              f"{'yes' if k['short_warned'] else 'NO':>6} {'named' if k['swapped_named'] else 'NOT':>7} "
              f"{'NAMED' if k['right_way_named'] else 'quiet':>7}")
    ratios = [r["slips"]["defaults"]["right"] / max(r["ours"]["right"], 1e-9) for r in pairs]
    defaults_ratio = float(np.median(ratios))
    worst_short = max(r["slips"]["short_confident_wrong"] for r in pairs)
    warned = sum(r["slips"]["short_warned"] for r in pairs)
    called_raw = sum(r["slips"]["short_called_raw"] for r in pairs)
    named = sum(r["slips"]["swapped_named"] for r in pairs)
    false_named = sum(r["slips"]["right_way_named"] for r in pairs)
    slips_goals = [
        (f"defaults: answered-right >= 0.9 x the covering range's (median over the pairs): "
         f"{defaults_ratio:.2f} x (pairs {min(ratios):.2f}-{max(ratios):.2f})",
         defaults_ratio >= FLOORS["defaults_over_covering"]),
        (f"short range: confident wrong <= 2 % of the board on every pair: worst "
         f"{100 * worst_short:.1f} %, median "
         f"{100 * float(np.median([r['slips']['short_confident_wrong'] for r in pairs])):.1f} %",
         worst_short <= FLOORS["short_confident_wrong"]),
        (f"short range: max_disparity named on every pair: {warned} of {len(pairs)}",
         warned == len(pairs)),
        (f"short range: the rectified pair called raw ('need rectifying'): {called_raw} of "
         f"{len(pairs)}", called_raw == 0),
        (f"swapped pairs named: {named} of {len(pairs)}", named == len(pairs)),
        (f"the right way round named swapped: {false_named} of {len(pairs)}", false_named == 0),
    ]
    raw = list(raw_swaps(args.url, args.photographs))
    raw_named, raw_false = sum(r[1] for r in raw), sum(r[2] for r in raw)
    slips_goals += [
        (f"raw pairs swapped (with the calibration), named: {raw_named} of {len(raw)}",
         raw_named == len(raw)),
        (f"raw pairs the right way round named swapped: {raw_false} of {len(raw)}",
         raw_false == 0),
    ]
    for text, met in slips_goals:
        print(f"  {'met    ' if met else 'NOT met'}  {text}")

    right_ratio = ours_med["right"] / max(opencv_med[best_right]["right"], 1e-9)
    wrong_ratio = ours_med["wrong1"] / max(opencv_med[best_wrong]["wrong1"], 1e-9)
    goals = [
        (f"answered-right >= 1.2 x OpenCV's best ({best_right}): {100 * ours_med['right']:.1f} "
         f"against {100 * opencv_med[best_right]['right']:.1f} %, {right_ratio:.2f} x",
         right_ratio >= 1.2),
        (f"wrong > 1 px of answered <= 0.6 x OpenCV's least ({best_wrong}): "
         f"{100 * ours_med['wrong1']:.1f} against {100 * opencv_med[best_wrong]['wrong1']:.1f} %, "
         f"{wrong_ratio:.2f} x", wrong_ratio <= 0.6),
        (f"sigma_d within 1 sigma 68 +- 8 %: {100 * within[1]:.1f} %", abs(within[1] - 0.68) <= 0.08),
        (f"sigma_d within 2 sigma >= 90 %: {100 * within[2]:.1f} %", within[2] >= 0.90),
        (f"sigma_d within 3 sigma >= 97 %: {100 * within[3]:.1f} %", within[3] >= 0.97),
        (f"max_disparity_std=1: wrong > 2 px of answered <= 5 %: {100 * std1_med['wrong2']:.1f} %",
         std1_med["wrong2"] <= 0.05),
    ]
    print("\nIssue 68's goals on board-plane truth:")
    for text, met in goals:
        print(f"  {'met    ' if met else 'NOT met'}  {text}")

    failures = []
    if right_ratio < FLOORS["right_over_opencv"]:
        failures.append(f"answered-right {right_ratio:.2f} x OpenCV's best, floor "
                        f"{FLOORS['right_over_opencv']}")
    if wrong_ratio > FLOORS["wrong1_over_opencv"]:
        failures.append(f"wrong > 1 px {wrong_ratio:.2f} x OpenCV's least, floor "
                        f"{FLOORS['wrong1_over_opencv']}")
    lo, hi = FLOORS["within_1sigma"]
    if not lo <= within[1] <= hi:
        failures.append(f"within 1 sigma {100 * within[1]:.1f} %, outside "
                        f"{100 * lo:.0f}-{100 * hi:.0f} %")
    for k in (2, 3):
        if within[k] < FLOORS[f"within_{k}sigma"]:
            failures.append(f"within {k} sigma {100 * within[k]:.1f} %, floor "
                            f"{100 * FLOORS[f'within_{k}sigma']:.0f} %")
    if std1_med["wrong2"] > FLOORS["std1_wrong2"]:
        failures.append(f"max_disparity_std=1: wrong > 2 px {100 * std1_med['wrong2']:.1f} % of "
                        f"answered, floor {100 * FLOORS['std1_wrong2']:.0f} %")
    # The floors: every issue-92 goal, the goal itself.
    failures.extend(f"issue 92: {text}" for text, met in slips_goals if not met)
    if plane_rms > FLOORS["plane_rms"]:
        failures.append(f"a board's corners lie {plane_rms:.2f} px off their plane: the truth "
                        f"(calibration or rectification) is off")
    if args.json:
        Path(args.json).write_text(json.dumps({
            "pairs": pairs, "skipped": skipped, "median": {"ours": ours_med, "ours_std1": std1_med,
                                                           "opencv": opencv_med},
            "within_sigma": within,
            "goals": [{"goal": t, "met": m} for t, m in goals + slips_goals]}, indent=1))
    scoring.floors(failures, "board-plane truth")


if __name__ == "__main__":
    main()
