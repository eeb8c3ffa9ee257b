"""The evaluation behind scripts/evaluate/matcher: our /depth-map against OpenCV's StereoSGBM on
Middlebury 2014 Motorcycle (quarter size) and two variants of it, with Middlebury's metric.

Run it through scripts/evaluate/matcher, which fetches the data and OpenCV and starts the service.
"""

import argparse
import json
import statistics
import time

import cv2
import numpy as np

from . import service
from .peers import opencv as opencv_modes, sgbm, sgbm_matcher
from .scenes import NUM_DISPARITIES, RIG, aloe, slanted_scene, variants
from .scoring import floors, method_row, score
from .service import RUNS, TURNS, load_npy, timed

# Goal 2: the 4 x upscaled pair (5.9 MP) searched over this many disparities.
LARGE_DISPARITIES = 400
# /match: how many random ground-truth pixels and 60 x 60 boxes, and the seed that picks them.
MATCH_POINTS = 1000
MATCH_BOXES = 10
MATCH_SEED = 19
# Issue 55: noise sigma 4 drawn with these seeds (the variant's is 7), reported as mean and spread.
NOISE_SEEDS = (1, 2, 3, 4, 5)
# /match floors: the goals themselves (measured: 81.9 % ok, median 0.113 px, 1.59 % off
# by more than 2 px, 30 x among the others, worst box 0.31 %).
MATCH_FLOORS = {"ok_share": 0.80, "ok_median_error": 0.20, "ok_off_2px": 0.02,
                "not_ok_ratio": 3.0, "box_error": 0.02}

# Accuracy floors (percent of ground-truth pixels), set from this script's results with a
# little room. Motorcycle's are the goal itself, 0.75 x OpenCV's best (11.02 % bad-1.0 and
# 8.69 % bad-2.0, so 8.27 and 6.52; measured 7.94 and 6.03). The variants' are OpenCV's best
# on them (measured: gain 7.85 / 5.94 against 11.18 / 8.74; noise 16.44 / 10.39 against
# 17.13 / 11.44), so that we never fall behind it where nothing was tuned.
FLOORS = {
    "motorcycle": {"bad1": 8.27, "bad2": 6.52},
    "gain": {"bad1": 11.18, "bad2": 8.74},
    "noise": {"bad1": 17.13, "bad2": 11.44},
}
# Goal 3 (noise): 0.8 x OpenCV's best (13.70 / 9.15), the floor itself since the census's
# Lee-filtered centres and the P2 guide built on them (measured 13.33 / 8.15).
FLOORS["noise"] = {"bad1": 13.70, "bad2": 9.15}
# The unseen scenes allowed some slack over OpenCV's best: worse than it is printed as NOT MET,
# and fails beyond this multiple of it. At a tenth of the contrast the texture is far weaker
# than the noise (docs/matcher.md): 69.6 / 61.2 % before the census compared with
# Lee-filtered centres, 9.37 / 4.44 % since, 7.65 / 2.81 % since such a pair is matched coarse
# to fine, against OpenCV's 7.68 / 2.84 %: met by under 1 %, which a few pixels' change in the
# scene's rendering (numpy's sine, whose last bits differ between its CPU builds) could undo.
UNSEEN_SLACK = {"  faint (1/10 contrast) + noise": 1.05}
# Goal 2 (5.9 MP, 400 disparities): 0.85 x OpenCV's best on it, since the census spreads its
# samples over the scale the images are smooth at (measured 0.77 x and 0.71 x at stride 4; 0.94 x
# and 0.80 x with them one pixel apart); the goal itself, 0.75 x, is printed and not yet met for
# bad-1.0.
LARGE_FLOOR_RATIO = 0.85
# Issue 92: Motorcycle at the defaults (no range: the range found from the pair) may be this
# much worse than with its covering range given, in the same run.
DEFAULTS_SLACK = 1.10



def opencv(left, right, disparities=NUM_DISPARITIES):
    """OpenCV's every mode on a pair ([`peers.opencv`]), Motorcycle's range by default."""
    return opencv_modes(left, right, disparities)


def connect(url, parts):
    """[`service.connect`] with Motorcycle's rig."""
    return service.connect(url, parts, RIG)


def post(url, path, parts):
    """[`service.post`] with Motorcycle's rig."""
    return service.post(url, path, parts, RIG)

def ours(url, left_png, right_png, output="disparity.npy", query="",
         disparities=NUM_DISPARITIES):
    """Whole /depth-map requests on one kept-alive connection: the median of RUNS."""
    path = f"/depth-map?max_disparity={disparities}&output={output}{query}"
    return post(url, path, {"left": (left_png, "left.png", "image/png"),
                            "right": (right_png, "right.png", "image/png")})


def taking_turns(url, left, right, rounds=TURNS, query=""):
    """Goal 1's (and 2's, with `query` "&preset=fast") times taken in turns, so that what the
    machine is doing meanwhile weighs on both alike: each round one OpenCV SGBM_3WAY b3
    `compute()` on the pair, then one whole /depth-map request of ours on a kept-alive
    connection. Medians and (min, max) over `rounds`, after one round unmeasured, in ms:
    (ours, OpenCV's, ours' spread, OpenCV's spread, the median of each round's ratio)."""
    cv2.setNumThreads(2)
    matcher = sgbm_matcher(cv2.STEREO_SGBM_MODE_SGBM_3WAY, 3, NUM_DISPARITIES)
    conn, body, ctype = connect(url, {
        "left": (cv2.imencode(".png", left)[1].tobytes(), "left.png", "image/png"),
        "right": (cv2.imencode(".png", right)[1].tobytes(), "right.png", "image/png")})
    path = f"/depth-map?max_disparity={NUM_DISPARITIES}&output=disparity.npy{query}"
    mine, theirs = [], []
    for _ in range(rounds + 1):
        t = time.perf_counter()
        matcher.compute(left, right)
        theirs.append(time.perf_counter() - t)
        mine.append(timed(conn, path, body, ctype)[1])
    conn.close()
    spread = lambda t: (1e3 * min(t[1:]), 1e3 * max(t[1:]))
    paired = statistics.median(m / t for m, t in zip(mine[1:], theirs[1:]))
    return (1e3 * statistics.median(mine[1:]), 1e3 * statistics.median(theirs[1:]),
            spread(mine), spread(theirs), paired)


def range_turns(url, left, right, truth, rounds=TURNS):
    """Issue 92's cost of finding the range: Motorcycle at the defaults (no range: the service
    surveys the pair and searches what it found) beside the same pair with the range it found
    given (no survey) and with 0..128 given (the default before the range was found), in
    turns, the order rotating each round, on one kept-alive connection: medians over `rounds`
    after one round unmeasured, in ms, the range found, and the defaults' bad-1.0 / bad-2.0
    beside the covering range's."""
    parts = {"left": (cv2.imencode(".png", left)[1].tobytes(), "left.png", "image/png"),
             "right": (cv2.imencode(".png", right)[1].tobytes(), "right.png", "image/png")}
    conn, body, ctype = connect(url, parts)
    said = json.loads(timed(conn, "/depth-map?output=summary", body, ctype)[0])
    found = said["max_disparity"]
    paths = {"defaults": "/depth-map?output=disparity.npy",
             "found given": f"/depth-map?max_disparity={found}&output=disparity.npy",
             "0..128 given": "/depth-map?max_disparity=128&output=disparity.npy"}
    times = {k: [] for k in paths}
    names = list(paths)
    for i in range(rounds + 1):
        for name in names[i % 3:] + names[:i % 3]:
            times[name].append(timed(conn, paths[name], body, ctype)[1])
    defaults = score(load_npy(timed(conn, paths["defaults"], body, ctype)[0]), truth)
    conn.close()
    return {"found": [said["min_disparity"], found], "chosen": said["disparity_range"]["chosen"],
            "why": said["disparity_range"]["why"], "rounds": rounds,
            "ms": {k: 1e3 * statistics.median(v[1:]) for k, v in times.items()},
            "defaults": {m: defaults[m] for m in ("bad1", "bad2")}}


def match_points(url, left_png, right_png, truth, seed=MATCH_SEED):
    """/match on Motorcycle: MATCH_POINTS random pixels with ground truth (x >= 70, a fixed
    seed) in one request, and MATCH_BOXES 60 x 60 boxes on surfaces (every pixel with ground
    truth, its disparities within 3 px). Returns the figures and the times of one point and of
    all points, each the median of RUNS."""
    rng = np.random.default_rng(seed)
    ys, xs = np.nonzero(np.isfinite(truth))
    keep = xs >= 70
    ys, xs = ys[keep], xs[keep]
    pick = rng.choice(len(xs), MATCH_POINTS, replace=False)
    ys, xs = ys[pick], xs[pick]
    points = [{"x": int(x), "y": int(y)} for x, y in zip(xs, ys)]
    boxes = []
    h, w = truth.shape
    while len(boxes) < MATCH_BOXES:
        x, y = int(rng.integers(0, w - 60)), int(rng.integers(0, h - 60))
        patch = truth[y:y + 60, x:x + 60]
        if np.isfinite(patch).all() and patch.max() - patch.min() <= 3:
            boxes.append({"x": x, "y": y, "width": 60, "height": 60})
    images = {"left": (left_png, "left.png", "image/png"),
              "right": (right_png, "right.png", "image/png")}
    path = f"/match?max_disparity={NUM_DISPARITIES}"
    answer, seconds, timing = post(url, path, {
        **images,
        "points": (json.dumps(points).encode(), None, "application/json"),
        "regions": (json.dumps(boxes).encode(), None, "application/json"),
    })
    _, one, _ = post(url, path, {
        **images, "points": (json.dumps(points[:1]).encode(), None, "application/json")})
    answer = json.loads(answer)
    status = np.array([m["status"] for m in answer["matches"]])
    disp = np.array([m.get("disparity_px", np.nan) for m in answer["matches"]], dtype=float)
    conf = np.array([m["confidence"] for m in answer["matches"]])
    err = np.abs(disp - truth[ys, xs])
    ok = status == "ok"
    off = err > 2
    not_ok = ~ok & np.isfinite(disp)
    fb, doffs = RIG["focal_length_px"] * RIG["baseline"], RIG["doffs"]
    box_errors = []
    for box, region in zip(boxes, answer["regions"]):
        patch = truth[box["y"]:box["y"] + 60, box["x"]:box["x"] + 60]
        true_depth = float(np.median(fb / (patch + doffs)))
        box_errors.append(abs(region["distance"] - true_depth) / true_depth)
    by_status = {str(s): int((status == s).sum()) for s in sorted(set(status))}
    return {
        "ok_share": float(ok.mean()),
        "ok_median_error": float(np.median(err[ok])),
        "ok_off_2px": float(off[ok].mean()),
        "not_ok_off_2px": float(off[not_ok].mean()) if not_ok.any() else float("nan"),
        "not_ok_without_disparity": int((~ok & ~np.isfinite(disp)).sum()),
        "box_worst_error": max(box_errors),
        "box_median_error": float(np.median(box_errors)),
        "statuses": by_status,
        "confidence_off_2px": {
            f"{lo:.2f}-{min(hi, 1):.2f}": [int(((conf >= lo) & (conf < hi) & np.isfinite(disp)).sum()),
                                   float(off[(conf >= lo) & (conf < hi) & np.isfinite(disp)].mean())
                                   if ((conf >= lo) & (conf < hi) & np.isfinite(disp)).any() else None]
            for lo, hi in ((0, 0.25), (0.25, 0.5), (0.5, 0.75), (0.75, 1.01))},
        "ms_all": seconds * 1e3,
        "ms_one": one * 1e3,
        "server_timing": timing,
        "rows_matched": answer["rows_matched"],
    }


def large(url, left, right, truth):
    """Goal 2: Motorcycle upscaled 4 x (2964 x 2000, 5.9 MP) with OpenCV's cubic resize and
    its ground truth scaled with it, at LARGE_DISPARITIES. OpenCV SGBM_3WAY is timed (median of
    RUNS); its most accurate modes run once each for accuracy (they are deterministic, and HH4
    takes 6-17 s here); ours is a whole request, median of RUNS."""
    up = lambda img: cv2.resize(img, None, fx=4, fy=4, interpolation=cv2.INTER_CUBIC)
    l, r = up(left), up(right)
    t = np.repeat(np.repeat(truth, 4, 0), 4, 1) * 4
    rows = []
    for name, mode, block, runs in (("SGBM_3WAY b3", cv2.STEREO_SGBM_MODE_SGBM_3WAY, 3, RUNS),
                                    ("SGBM_3WAY b5", cv2.STEREO_SGBM_MODE_SGBM_3WAY, 5, RUNS),
                                    ("HH4 b3", cv2.STEREO_SGBM_MODE_HH4, 3, 1),
                                    ("HH4 b5", cv2.STEREO_SGBM_MODE_HH4, 5, 1)):
        disp, seconds = sgbm(l, r, mode, block, LARGE_DISPARITIES, runs)
        rows.append((f"OpenCV {name}", score(disp, t), seconds))
    path = f"/depth-map?max_disparity={LARGE_DISPARITIES}&output=disparity.npy"
    answer, seconds, timing = post(url, path, {
        "left": (cv2.imencode(".png", l)[1].tobytes(), "left.png", "image/png"),
        "right": (cv2.imencode(".png", r)[1].tobytes(), "right.png", "image/png")})
    disp = load_npy(answer)
    return rows, score(np.where(np.isnan(disp), np.inf, disp), t), seconds, timing


def unseen(url):
    """The slanted colour scene, clean, with a gain change, and with noise: ours (defaults)
    against OpenCV's best mode on each. Returns rows of (name, ours, best)."""
    left, right, truth = slanted_scene()
    rng = np.random.default_rng(5)
    cases = {
        "slanted colour": (left, right),
        "  + right gain 0.8, +10": (left, right * 0.8 + 10),
        "  + noise sigma 3": (left + rng.normal(0, 3, left.shape), right + rng.normal(0, 3, right.shape)),
        # A fifth and a tenth of the contrast, with the same noise: weak texture, as on a
        # painted wall. At a tenth the texture is fainter than the noise.
        "  faint (1/5 contrast) + noise": (
            128 + (left - 128) / 5 + rng.normal(0, 3, left.shape),
            128 + (right - 128) / 5 + rng.normal(0, 3, right.shape)),
        "  faint (1/10 contrast) + noise": (
            128 + (left - 128) / 10 + rng.normal(0, 3, left.shape),
            128 + (right - 128) / 10 + rng.normal(0, 3, right.shape)),
    }
    rows = []
    for name, (l, r) in cases.items():
        l8 = np.clip(l, 0, 255).astype(np.uint8)
        r8 = np.clip(r, 0, 255).astype(np.uint8)
        best = {m: min(sc[m] for sc in (score(d, truth) for _, d, _ in opencv(l8, r8)))
                for m in ("bad1", "bad2")}
        answer, _, _ = post(url, f"/depth-map?max_disparity={NUM_DISPARITIES}&output=disparity.npy",
                            {"left": (cv2.imencode(".png", l8)[1].tobytes(), "left.png", "image/png"),
                             "right": (cv2.imencode(".png", r8)[1].tobytes(), "right.png", "image/png")})
        disp = load_npy(answer)
        rows.append((name, score(np.where(np.isnan(disp), np.inf, disp), truth), best))
    return rows


def noise_draws(url, left, right, truth, seeds=NOISE_SEEDS):
    """Motorcycle with noise sigma 4 drawn with other seeds than the variant's: for each, our
    bad-1.0 and bad-2.0 over OpenCV's best mode's on the same draw (accuracy only: one
    `compute()` a mode)."""
    ratios = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        l, r = [np.clip(img.astype(np.float32) + rng.normal(0, 4, img.shape), 0, 255)
                .astype(np.uint8) for img in (left, right)]
        cv2.setNumThreads(2)
        best = {"bad1": np.inf, "bad2": np.inf}
        for mode in (cv2.STEREO_SGBM_MODE_SGBM, cv2.STEREO_SGBM_MODE_HH,
                     cv2.STEREO_SGBM_MODE_SGBM_3WAY, cv2.STEREO_SGBM_MODE_HH4):
            for block in (3, 5):
                disp, _ = sgbm(l, r, mode, block, NUM_DISPARITIES, 1)
                s = score(disp, truth)
                best = {m: min(best[m], s[m]) for m in best}
        answer, _, _ = ours(url, cv2.imencode(".png", l)[1].tobytes(),
                            cv2.imencode(".png", r)[1].tobytes())
        disp = load_npy(answer)
        mine = score(np.where(np.isnan(disp), np.inf, disp), truth)
        ratios.append({"seed": seed, "ours": mine, "opencv_best": best,
                       "bad1": mine["bad1"] / best["bad1"], "bad2": mine["bad2"] / best["bad2"]})
    return ratios


def second_scene(data, url):
    """Aloe at half size ([`aloe`]): every OpenCV mode and ours (default and preset=fast),
    Middlebury's metric. Returns (rows of (method, score, seconds)), ours, fast, disparities,
    shape, and (ours, OpenCV's best) scored beyond the first `disparities` columns, where
    OpenCV's search leaves no value."""
    left, right, truth, disparities = aloe(data)
    inner = truth.copy()
    inner[:, :disparities] = np.inf
    maps = list(opencv(left, right, disparities))
    rows = [(name, score(disp, truth), seconds) for name, disp, seconds in maps]
    png = [cv2.imencode(".png", img)[1].tobytes() for img in (left, right)]
    out = []
    for query in ("", "&preset=fast"):
        answer, seconds, _ = ours(url, *png, query=query, disparities=disparities)
        out.append((load_npy(answer), seconds))
    beyond = {m: min(score(disp, inner)[m] for _, disp, _ in maps) for m in ("bad1", "bad2")}
    return (rows, (score(out[0][0], truth), out[0][1]), (score(out[1][0], truth), out[1][1]),
            disparities, left.shape, (score(out[0][0], inner), beyond))


def colour(disp, lo, hi):
    d = np.where(np.isfinite(disp), disp, np.nan)
    scaled = np.clip((d - lo) / (hi - lo) * 255, 0, 255)
    img = cv2.applyColorMap(np.nan_to_num(scaled).astype(np.uint8), cv2.COLORMAP_TURBO)
    img[~np.isfinite(d)] = 0
    return img


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--data", required=True)
    parser.add_argument("--url", required=True)
    parser.add_argument("--figure")
    parser.add_argument("--json")
    args = parser.parse_args()

    left = cv2.imread(f"{args.data}/motorcycle_left.png")
    right = cv2.imread(f"{args.data}/motorcycle_right.png")
    truth = np.load(f"{args.data}/motorcycle_disp.npz")["arr_0"]
    print(f"Motorcycle (quarter size) {left.shape[1]} x {left.shape[0]}, "
          f"{NUM_DISPARITIES} disparities; OpenCV {cv2.__version__}, 2 threads; "
          f"median of {RUNS} runs")
    results, failures, maps = {}, [], {}
    header = f"{'scene':<11} {'method':<22} {'bad-0.5':>8} {'bad-1.0':>8} {'bad-2.0':>8} " \
             f"{'density':>8} {'time ms':>8}"
    print(header)
    print("-" * len(header))
    for scene, l, r in variants(left, right):
        rows = []
        for name, disp, seconds in opencv(l, r):
            rows.append((name, score(disp, truth), seconds))
            maps.setdefault(scene, {})[name] = disp
        ok_l = cv2.imencode(".png", l)[1].tobytes()
        ok_r = cv2.imencode(".png", r)[1].tobytes()
        answer, seconds, timing = ours(args.url, ok_l, ok_r)
        disp = load_npy(answer)
        disp = np.where(np.isnan(disp), np.inf, disp)
        maps[scene]["ours"] = disp
        mine = score(disp, truth)
        answer, fast_seconds, fast_timing = ours(args.url, ok_l, ok_r, query="&preset=fast")
        fast_disp = load_npy(answer)
        fast = score(np.where(np.isnan(fast_disp), np.inf, fast_disp), truth)
        best1 = min(rows, key=lambda row: row[1]["bad1"])
        best2 = min(rows, key=lambda row: row[1]["bad2"])
        for name, s, secs in rows + [("ours (/depth-map)", mine, seconds),
                                     ("ours preset=fast", fast, fast_seconds)]:
            print(method_row(scene, name, s, secs))
        print(f"{scene:<11} {'  OpenCV best':<22} {'':8} {best1[1]['bad1']:8.2f} "
              f"{best2[1]['bad2']:8.2f}   ours/best: bad-1.0 "
              f"{mine['bad1'] / best1[1]['bad1']:.2f}, bad-2.0 {mine['bad2'] / best2[1]['bad2']:.2f}")
        print(f"{scene:<11}   our stages: {timing}")
        print(f"{scene:<11}   fast stages: {fast_timing}")
        results[scene] = {
            "ours": {**mine, "ms": seconds * 1e3, "server_timing": timing},
            "fast": {**fast, "ms": fast_seconds * 1e3, "server_timing": fast_timing},
            "opencv": {name: {**s, "ms": secs * 1e3} for name, s, secs in rows},
        }
        for metric, floor in FLOORS[scene].items():
            if mine[metric] > floor:
                failures.append(f"{scene}: {metric} {mine[metric]:.2f} % is above the floor {floor} %")
        # The fast preset: never worse than OpenCV's best mode on the pair (issue 55's goal 2).
        for metric, best in (("bad1", best1[1]["bad1"]), ("bad2", best2[1]["bad2"])):
            if fast[metric] > best:
                failures.append(f"{scene} preset=fast: {metric} {fast[metric]:.2f} % is above "
                                f"OpenCV's best {best:.2f} %")
        print()
    m = match_points(args.url, cv2.imencode(".png", left)[1].tobytes(),
                     cv2.imencode(".png", right)[1].tobytes(), truth)
    results["match"] = m
    print(f"/match on Motorcycle, {MATCH_POINTS} random ground-truth pixels (x >= 70, seed "
          f"{MATCH_SEED}) in one request:")
    print(f"  ok: {100 * m['ok_share']:.1f} % (goal >= 80 %); statuses {m['statuses']}")
    print(f"  among ok: median |d - truth| {m['ok_median_error']:.3f} px (goal <= 0.20), "
          f"off by > 2 px {100 * m['ok_off_2px']:.2f} % (goal <= 2 %)")
    print(f"  among not ok (with a disparity): off by > 2 px {100 * m['not_ok_off_2px']:.1f} % "
          f"= {m['not_ok_off_2px'] / max(m['ok_off_2px'], 1e-9):.1f} x the ok share (goal >= 3 x)")
    print(f"  confidence bins [points, share off by > 2 px]: {m['confidence_off_2px']}")
    print(f"  {MATCH_BOXES} boxes of 60 x 60 on surfaces: median distance off the truth's by "
          f"{100 * m['box_median_error']:.2f} % (worst {100 * m['box_worst_error']:.2f} %, goal "
          f"<= 2 %)")
    print(f"  time: one point {m['ms_one']:.1f} ms, {MATCH_POINTS} points {m['ms_all']:.1f} ms, "
          f"a full /depth-map {results['motorcycle']['ours']['ms']:.1f} ms "
          f"(whole requests, medians of {RUNS}; reported, never asserted)")
    for name, value, bad in [
        ("ok share", m["ok_share"], m["ok_share"] < MATCH_FLOORS["ok_share"]),
        ("ok median error", m["ok_median_error"],
         m["ok_median_error"] > MATCH_FLOORS["ok_median_error"]),
        ("ok off by > 2 px", m["ok_off_2px"], m["ok_off_2px"] > MATCH_FLOORS["ok_off_2px"]),
        ("not-ok over ok share off by > 2 px", m["not_ok_off_2px"] / max(m["ok_off_2px"], 1e-9),
         m["not_ok_off_2px"] < MATCH_FLOORS["not_ok_ratio"] * m["ok_off_2px"]),
        ("worst box error", m["box_worst_error"],
         m["box_worst_error"] > MATCH_FLOORS["box_error"]),
    ]:
        if bad:
            failures.append(f"match: {name} {value:.4f} is beyond its floor")
    print()
    rows, mine, seconds, timing = large(args.url, left, right, truth)
    print(f"Goal 2: Motorcycle upscaled 4 x (2964 x 2000, 5.9 MP), {LARGE_DISPARITIES} "
          f"disparities, ground truth scaled with it")
    for name, s, secs in rows + [("ours (/depth-map)", mine, seconds)]:
        print(f"{'large':<11} {name:<22} {s['bad0.5']:8.2f} {s['bad1']:8.2f} "
              f"{s['bad2']:8.2f} {s['density']:8.1f} {secs * 1e3:8.1f}")
    print(f"{'large':<11}   our stages: {timing}")
    large_best = {m: min(s[m] for _, s, _ in rows) for m in ("bad1", "bad2")}
    results["large"] = {"ours": {**mine, "ms": seconds * 1e3, "server_timing": timing},
                        "opencv": {name: {**s, "ms": secs * 1e3} for name, s, secs in rows}}
    for metric in ("bad1", "bad2"):
        if mine[metric] > LARGE_FLOOR_RATIO * large_best[metric]:
            failures.append(f"large: {metric} {mine[metric]:.2f} % is above "
                            f"{LARGE_FLOOR_RATIO} x OpenCV's best {large_best[metric]:.2f} %")
    print()
    print("Unseen scenes (rendered here, nothing tuned on them), 640 x 480, 64 disparities: ours "
          "against OpenCV's best mode; floor: never worse")
    for name, mine, best in unseen(args.url):
        print(f"  {name:<32} ours bad-1.0 {mine['bad1']:6.2f} bad-2.0 {mine['bad2']:6.2f}   "
              f"OpenCV best {best['bad1']:6.2f} {best['bad2']:6.2f}   ratio "
              f"{mine['bad1'] / best['bad1']:.2f} {mine['bad2'] / best['bad2']:.2f}")
        worse = [m for m in ("bad1", "bad2") if mine[m] > best[m]]
        allowed = UNSEEN_SLACK.get(name)
        if worse and allowed is None:
            failures.append(f"unseen {name.strip()}: {', '.join(worse)} above OpenCV's best")
        elif worse:
            print(f"  {'':<32} NOT MET: worse than OpenCV's best (known; floored at "
                  f"{allowed} x OpenCV's best)")
            beyond = [m for m in ("bad1", "bad2") if mine[m] > allowed * best[m]]
            if beyond:
                failures.append(f"unseen {name.strip()}: {', '.join(beyond)} above {allowed} x "
                                "OpenCV's best")
    print()
    rows, (mine, seconds), (fast, fast_seconds), count, shape, (inner, inner_best) = \
        second_scene(args.data, args.url)
    print(f"A second real scene nothing was tuned on: Middlebury 2006 Aloe (Debian's opencv-doc, "
          f"scripts/data/fetch-aloe) at half size, {shape[1]} x {shape[0]}, {count} disparities; "
          f"floor: never worse than OpenCV's best")
    print(header)
    print("-" * len(header))
    for name, s, secs in rows + [("ours (/depth-map)", mine, seconds),
                                 ("ours preset=fast", fast, fast_seconds)]:
        print(method_row("aloe", name, s, secs))
    best = {m: min(s[m] for _, s, _ in rows) for m in ("bad1", "bad2")}
    print(f"{'aloe':<11} {'  OpenCV best':<22} {'':8} {best['bad1']:8.2f} {best['bad2']:8.2f}   "
          f"ours/best: bad-1.0 {mine['bad1'] / best['bad1']:.2f}, bad-2.0 "
          f"{mine['bad2'] / best['bad2']:.2f}; preset=fast {fast['bad1'] / best['bad1']:.2f}, "
          f"{fast['bad2'] / best['bad2']:.2f}")
    print(f"{'aloe':<11}   beyond the first {count} columns (where OpenCV's search leaves no "
          f"value): ours {inner['bad1']:.2f} / {inner['bad2']:.2f} %, OpenCV's best "
          f"{inner_best['bad1']:.2f} / {inner_best['bad2']:.2f} %: "
          f"{inner['bad1'] / inner_best['bad1']:.2f} x, {inner['bad2'] / inner_best['bad2']:.2f} x")
    results["aloe"] = {"beyond_search_band": {"ours": inner, "opencv_best": inner_best},
                       "ours": {**mine, "ms": seconds * 1e3},
                       "fast": {**fast, "ms": fast_seconds * 1e3},
                       "opencv": {name: {**s, "ms": secs * 1e3} for name, s, secs in rows}}
    for which, s in (("default", mine), ("preset=fast", fast)):
        worse = [m for m in ("bad1", "bad2") if s[m] > best[m]]
        if worse:
            failures.append(f"aloe ({which}): {', '.join(worse)} above OpenCV's best")
    print()

    def ratio(scene, metric):
        best = min(s[metric] for s in results[scene]["opencv"].values())
        return results[scene]["ours"][metric] / best

    sgbm3 = results["motorcycle"]["opencv"]["OpenCV SGBM_3WAY b3"]["ms"]
    large3 = min(results["large"]["opencv"][f"OpenCV SGBM_3WAY b{b}"]["ms"] for b in (3, 5))
    verdict = lambda ok: "met" if ok else "NOT MET"
    ours_ms, large_ms = results["motorcycle"]["ours"]["ms"], results["large"]["ours"]["ms"]
    mine_ms, theirs_ms, mine_spread, theirs_spread, paired = taking_turns(args.url, left, right)
    results["goal1_taking_turns"] = {"ours_ms": mine_ms, "opencv_sgbm_3way_b3_ms": theirs_ms,
                                     "rounds": TURNS, "paired_ratio": paired}
    fast_ms, theirs_fast_ms, fast_spread, theirs_fast_spread, fast_paired = taking_turns(
        args.url, left, right, query="&preset=fast")
    results["fast_taking_turns"] = {"ours_ms": fast_ms, "opencv_sgbm_3way_b3_ms": theirs_fast_ms,
                                    "rounds": TURNS, "paired_ratio": fast_paired}
    ranged = range_turns(args.url, left, right, truth)
    results["range_turns"] = ranged
    # The defaults' floor: within DEFAULTS_SLACK of the covering range given, in the same run
    # (a found range past 64 is matched coarse to fine: 0..80 measured 8.35 / 6.44 % against
    # 0..64's 7.94 / 6.47 %), and never above OpenCV's best.
    worse = [m for m in ("bad1", "bad2") if ranged["defaults"][m] > min(
        DEFAULTS_SLACK * results["motorcycle"]["ours"][m],
        min(o[m] for o in results["motorcycle"]["opencv"].values()))]
    if worse:
        failures.append(f"motorcycle at the defaults (range found): {', '.join(worse)} above "
                        f"{DEFAULTS_SLACK} x the range given or OpenCV's best")
    draws = noise_draws(args.url, left, right, truth)
    results["noise_draws"] = draws
    print("Noise sigma 4 on fresh draws (seeds " + ", ".join(str(d["seed"]) for d in draws) +
          "): ours / OpenCV's best, bad-1.0 and bad-2.0:")
    for d in draws:
        print(f"  seed {d['seed']}: ours {d['ours']['bad1']:.2f} / {d['ours']['bad2']:.2f} %, "
              f"OpenCV best {d['opencv_best']['bad1']:.2f} / {d['opencv_best']['bad2']:.2f} %: "
              f"{d['bad1']:.2f} x, {d['bad2']:.2f} x")
    print()
    mean = lambda key: statistics.mean(d[key] for d in draws)
    lo_hi = lambda key: f"{min(d[key] for d in draws):.2f}-{max(d[key] for d in draws):.2f}"
    fast_ratio = lambda scene, metric: results[scene]["fast"][metric] / min(
        s[metric] for s in results[scene]["opencv"].values())
    print("Goals (issue 55), same run; times are reported, never asserted:")
    print(f"  1. default: whole request taking turns with OpenCV SGBM_3WAY b3's compute() "
          f"({TURNS} rounds, medians [min-max]) {mine_ms:.1f} [{mine_spread[0]:.1f}-"
          f"{mine_spread[1]:.1f}] against {theirs_ms:.1f} [{theirs_spread[0]:.1f}-"
          f"{theirs_spread[1]:.1f}] ms = {mine_ms / theirs_ms:.2f} x (the median of the "
          f"rounds' ratios {paired:.2f} x), goal <= 1.0: {verdict(paired <= 1.0)}; "
          f"noise sigma 4 over {len(draws)} fresh draws: "
          f"bad-1.0 {mean('bad1'):.2f} x ({lo_hi('bad1')}), bad-2.0 {mean('bad2'):.2f} x "
          f"({lo_hi('bad2')}) OpenCV's best, goal <= 0.8: "
          f"{verdict(max(mean('bad1'), mean('bad2')) <= 0.8)}")
    print(f"  2. preset=fast: whole request taking turns {fast_ms:.1f} [{fast_spread[0]:.1f}-"
          f"{fast_spread[1]:.1f}] against {theirs_fast_ms:.1f} [{theirs_fast_spread[0]:.1f}-"
          f"{theirs_fast_spread[1]:.1f}] ms = {fast_ms / theirs_fast_ms:.2f} x (the median of "
          f"the rounds' ratios {fast_paired:.2f} x), goal <= 0.6: "
          f"{verdict(fast_paired <= 0.6)}; bad-1.0 / bad-2.0 against OpenCV's "
          f"best: " + ", ".join(f"{scene} {fast_ratio(scene, 'bad1'):.2f} x / "
                                f"{fast_ratio(scene, 'bad2'):.2f} x"
                                for scene in ("motorcycle", "gain", "noise")) +
          ", goal <= 1.0: " + verdict(all(fast_ratio(sc, m) <= 1.0 for sc in
                                          ("motorcycle", "gain", "noise")
                                          for m in ("bad1", "bad2"))))
    print()
    ms = ranged["ms"]
    survey_share = (ms["defaults"] - ms["found given"]) / ms["defaults"]
    print(f"Goals (issue 92), same run, whole requests in turns ({ranged['rounds']} rounds, "
          f"medians); times are reported, never asserted: at the defaults the range found is "
          f"{ranged['found'][0]}..{ranged['found'][1]} ({ranged['chosen']}), bad-1.0 / bad-2.0 "
          f"{ranged['defaults']['bad1']:.2f} / {ranged['defaults']['bad2']:.2f} % (the range "
          f"{NUM_DISPARITIES} given: {results['motorcycle']['ours']['bad1']:.2f} / "
          f"{results['motorcycle']['ours']['bad2']:.2f} %)")
    print(f"  the defaults {ms['defaults']:.1f} ms, the range found given (no survey) "
          f"{ms['found given']:.1f} ms: finding it costs {100 * survey_share:.1f} % of the "
          f"request, goal <= 10 %: {verdict(survey_share <= 0.10)}")
    print(f"  against 0..128 given (the default before) {ms['0..128 given']:.1f} ms: "
          f"{ms['defaults'] / ms['0..128 given']:.2f} x, goal < 1 where the scene needs fewer "
          f"than 128: {verdict(ms['defaults'] < ms['0..128 given'])}")
    print()
    print("Goals (issue 32), same run; times are reported, never asserted:")
    print(f"  1. Motorcycle, {NUM_DISPARITIES} disparities: our whole request {ours_ms:.1f} ms = "
          f"{ours_ms / sgbm3:.2f} x OpenCV SGBM_3WAY's compute alone ({sgbm3:.1f} ms); taking "
          f"turns ({TURNS} rounds, medians) {mine_ms:.1f} against {theirs_ms:.1f} ms = "
          f"{mine_ms / theirs_ms:.2f} x, goal <= 1.0: "
          f"{verdict(mine_ms <= theirs_ms)}; bad-1.0 {ratio('motorcycle', 'bad1'):.2f} x and bad-2.0 "
          f"{ratio('motorcycle', 'bad2'):.2f} x OpenCV's best, goal <= 0.75: "
          f"{verdict(max(ratio('motorcycle', 'bad1'), ratio('motorcycle', 'bad2')) <= 0.75)}")
    print(f"  2. 5.9 MP, {LARGE_DISPARITIES} disparities: our whole request {large_ms:.0f} ms = "
          f"{large_ms / large3:.2f} x OpenCV SGBM_3WAY's compute ({large3:.0f} ms), goal <= 1.0: "
          f"{verdict(large_ms <= large3)}; bad-1.0 {ratio('large', 'bad1'):.2f} x and bad-2.0 "
          f"{ratio('large', 'bad2'):.2f} x OpenCV's best, goal <= 0.75: "
          f"{verdict(max(ratio('large', 'bad1'), ratio('large', 'bad2')) <= 0.75)}")
    print(f"  3. noise sigma 4: bad-1.0 {ratio('noise', 'bad1'):.2f} x and bad-2.0 "
          f"{ratio('noise', 'bad2'):.2f} x OpenCV's best, goal <= 0.8: "
          f"{verdict(max(ratio('noise', 'bad1'), ratio('noise', 'bad2')) <= 0.8)}; gain change "
          f"{ratio('gain', 'bad1'):.2f} x and {ratio('gain', 'bad2'):.2f} x (never above 1)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)
    if args.figure:
        lo, hi = 0, NUM_DISPARITIES
        best = min(results["motorcycle"]["opencv"].items(), key=lambda kv: kv[1]["bad1"])[0]
        panels = [left, colour(truth, lo, hi), colour(maps["motorcycle"][best], lo, hi),
                  colour(maps["motorcycle"]["ours"], lo, hi)]
        labels = ["left image", "ground truth", best, "ours"]
        for img, label in zip(panels, labels):
            cv2.putText(img, label, (10, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.9, (255, 255, 255), 2)
        top = np.hstack(panels[:2])
        bottom = np.hstack(panels[2:])
        figure = cv2.resize(np.vstack([top, bottom]), None, fx=0.6, fy=0.6,
                            interpolation=cv2.INTER_AREA)
        cv2.imwrite(args.figure, figure, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        print(f"figure: {args.figure}")
    floors(failures, "accuracy floors")


if __name__ == "__main__":
    main()
