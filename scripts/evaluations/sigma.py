"""Issue 56: is each disparity's σ_d true, and does it tell good pixels from bad better than
OpenCV's WLS confidence map? On pairs with exact truth, in one run:

- calibration: the share of valid pixels with |d - d_true| <= σ_d (goal 68 % ± 5 %), and, in
  each tenth of the pixels sorted by σ_d, the RMS of the errors (those beyond 3 px left out and
  counted apart) over the tenth's mean σ_d (goal 0.7-1.4);
- sparsification: remove pixels from the least to the most trusted and take bad-1.0 of what is
  left (0 %, 5 %, ... 95 % removed); the area under that curve for our σ_d against OpenCV's WLS
  confidence map (SGBM_3WAY with ximgproc's WLS filter as OpenCV's disparity-filtering
  tutorial sets it up) on the same pair (goal <= 0.8 x), and the optimal area (sorted by the
  true error) beside each;
- with fill=true: the filled map's bad-1.0 and bad-2.0 against OpenCV's best SGBM + WLS (modes,
  blocks 3 and 5, λ and σ_color searched on the truth), the filled pixels' share within
  their σ_d, apart, and what fill=true adds to a whole Motorcycle request (the two in turns,
  medians; reported, never asserted).

Pairs: Middlebury 2014 Motorcycle (quarter size, from the scikit-image wheel) with a gain change,
noise sigma 4 (the variant's seed and three more draws), at half size and upscaled 2 x;
Middlebury 2006 Aloe (from Debian's opencv-doc, nothing fitted on it) at half and quarter size;
and the rendered slanted scene, clean, noisy and faint (scripts/evaluations/stereo.py's). Fails (exit 1)
when the coverage leaves 63-73 % or the area ratio exceeds 0.8 on Motorcycle, its gain change, a
noise draw or Aloe at half size; the rest are reported, not floored (docs/matcher.md: σ_d is
fitted to real images, whose error floor renders do not have).

    PYTHONPATH=scripts python3 -m evaluations.sigma --data target/eval-stereo --url URL --wls-python PY [--json F]
"""
import argparse
import io
import json
import statistics
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

from . import scenes, scoring, service

COVERAGE = (0.63, 0.73)
RATIOS = (0.7, 1.4)
AREA_RATIO = 0.8
MISMATCH_PX = 3.0
FRACTIONS = np.arange(0.0, 1.0, 0.05)
EXTRA_NOISE_SEEDS = (1, 2, 3)
# The pairs whose calibration and area CI holds to the goals: the real pair and its variants.
FLOORED = ("motorcycle", "gain", "noise", "noise draw 1", "noise draw 2", "noise draw 3",
           "aloe")
# The pairs whose filled maps are compared with OpenCV's best SGBM + WLS.
FILL_PAIRS = ("motorcycle", "gain", "noise", "aloe")


def pairs(data):
    """(name, left, right, truth, disparities) of every pair measured."""
    left = cv2.imread(f"{data}/motorcycle_left.png")
    right = cv2.imread(f"{data}/motorcycle_right.png")
    truth = np.load(f"{data}/motorcycle_disp.npz")["arr_0"].astype(np.float32)
    for name, l, r in scenes.variants(left, right):
        yield name, l, r, truth, scenes.NUM_DISPARITIES
    for seed in EXTRA_NOISE_SEEDS:
        rng = np.random.default_rng(seed)
        l, r = [np.clip(img.astype(np.float32) + rng.normal(0, 4, img.shape), 0, 255)
                .astype(np.uint8) for img in (left, right)]
        yield f"noise draw {seed}", l, r, truth, scenes.NUM_DISPARITIES
    half = lambda img: cv2.resize(img, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    hl, hr = half(left), half(right)
    h, w = hl.shape[:2]
    yield "half size", hl, hr, truth[: 2 * h : 2, : 2 * w : 2] / 2, scenes.NUM_DISPARITIES // 2
    up = lambda img: cv2.resize(img, None, fx=2, fy=2, interpolation=cv2.INTER_CUBIC)
    yield "upscaled 2 x", up(left), up(right), np.repeat(np.repeat(truth, 2, 0), 2, 1) * 2, \
        2 * scenes.NUM_DISPARITIES
    # A second real scene nothing was fitted on (scripts/data/fetch-aloe), at half and quarter size.
    for scale, name in ((2, "aloe"), (4, "aloe quarter size")):
        yield (name, *scenes.aloe(data, scale))
    sl, sr, st = scenes.slanted_scene()
    rng = np.random.default_rng(5)
    u8 = lambda img: np.clip(img, 0, 255).astype(np.uint8)
    yield "render", u8(sl), u8(sr), st, 64
    yield "render + noise 3", u8(sl + rng.normal(0, 3, sl.shape)), \
        u8(sr + rng.normal(0, 3, sr.shape)), st, 64
    yield "render faint + noise", u8(128 + (sl - 128) / 5 + rng.normal(0, 3, sl.shape)), \
        u8(128 + (sr - 128) / 5 + rng.normal(0, 3, sr.shape)), st, 64


def ours(url, left, right, ndisp, query=""):
    """One /depth-map request's NPZ: `disparity`, `disparity_std` and, with `&fill=true` in
    `query`, `filled`. `ndisp` None sends no range: the service finds it from the pair."""
    given = "" if ndisp is None else f"max_disparity={ndisp}&"
    answer = service.post_once(url, f"/depth-map?{given}output=arrays.npz{query}", {
        "left": (cv2.imencode(".png", left)[1].tobytes(), "left.png", "image/png"),
        "right": (cv2.imencode(".png", right)[1].tobytes(), "right.png", "image/png")})
    return np.load(io.BytesIO(answer))


def calibration(disp, std, truth):
    """Coverage within 1 σ, each tenth's RMS (mismatches beyond 3 px out) over its mean σ, and
    the share of mismatches."""
    valid = np.isfinite(disp) & np.isfinite(truth)
    err = np.abs(disp - truth)[valid]
    sigma = std[valid]
    coverage = float(np.mean(err <= sigma))
    ratios = []
    for tenth in np.array_split(np.argsort(sigma, kind="stable"), 10):
        e = err[tenth]
        kept = e <= MISMATCH_PX
        ratios.append(float(np.sqrt(np.mean(e[kept] ** 2)) / np.mean(sigma[tenth])))
    return coverage, ratios, float(np.mean(err > MISMATCH_PX))


def sparsification(err, most_trusted_first):
    """bad-1.0 (%) of what is left after removing each fraction of the least trusted pixels,
    and the area under that curve (its mean over the fractions)."""
    bad = err[most_trusted_first] > 1.0
    n = len(bad)
    curve = [100.0 * float(np.mean(bad[: max(1, int(round(n * (1 - f))))])) for f in FRACTIONS]
    return curve, float(np.mean(curve))


def areas(disp, trust, truth):
    """(area sorted by `trust`, most trusted first; optimal area) over the valid pixels."""
    valid = np.isfinite(disp) & np.isfinite(truth)
    err = np.abs(disp - truth)[valid]
    _, area = sparsification(err, np.argsort(-trust[valid], kind="stable"))
    _, best = sparsification(err, np.argsort(err, kind="stable"))
    return area, best


def wls(python, work, cases, search=False):
    """OpenCV's WLS-filtered maps and confidence for each case, from its own venv; with
    `search`, also its best filtered map over modes, blocks, λ and σ_color."""
    out = f"{work}/wls{'-search' if search else ''}.npz"
    args = [python, str(Path(__file__).with_name("wls_confidence.py")), "--out", out]
    if search:
        args.append("--search")
    for name, left, right, truth, ndisp in cases:
        stem = f"{work}/{name.replace(' ', '_')}"
        cv2.imwrite(f"{stem}_left.png", left)
        cv2.imwrite(f"{stem}_right.png", right)
        args += [name, f"{stem}_left.png", f"{stem}_right.png", str(ndisp)]
        if search:
            np.save(f"{stem}_truth.npy", truth)
            args.append(f"{stem}_truth.npy")
    subprocess.run(args, check=True)
    return np.load(out)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--data", required=True)
    parser.add_argument("--url", required=True)
    parser.add_argument("--wls-python", required=True)
    parser.add_argument("--json")
    args = parser.parse_args()
    work = Path(args.data) / "sigma"
    work.mkdir(parents=True, exist_ok=True)
    cases = list(pairs(args.data))
    theirs = wls(args.wls_python, work, cases)
    print("Issue 56: sigma_d of every disparity on pairs with exact truth; OpenCV "
          f"{cv2.__version__} SGBM_3WAY + WLS confidence (its tutorial's setup) on the same pairs")
    header = (f"{'pair':<21} {'valid':>6} {'within 1 sigma':>14} {'tenths RMS/sigma':>17} "
              f"{'>3 px':>6} {'area ours':>9} {'WLS':>6} {'ratio':>6} {'opt ours':>8} "
              f"{'opt WLS':>7}")
    print(header)
    print("-" * len(header))
    results, failures = {}, []
    for name, left, right, truth, ndisp in cases:
        arrays = ours(args.url, left, right, ndisp)
        disp, std = arrays["disparity"], arrays["disparity_std"]
        coverage, ratios, mismatches = calibration(disp, std, truth)
        area, best = areas(disp, -std, truth)
        w_disp, w_conf = theirs[f"{name}/disparity"], theirs[f"{name}/confidence"]
        w_area, w_best = areas(w_disp, w_conf, truth)
        ratio = area / w_area if w_area > 0 else float("inf")
        results[name] = {"valid": float(np.mean(np.isfinite(disp))), "coverage": coverage,
                         "tenths": ratios, "mismatches": mismatches, "area": area,
                         "area_wls": w_area, "area_ratio": ratio, "area_optimal": best,
                         "area_optimal_wls": w_best, "median_sigma": float(np.nanmedian(std))}
        print(f"{name:<21} {100 * np.mean(np.isfinite(disp)):5.1f}% {100 * coverage:13.1f}% "
              f"{min(ratios):8.2f}-{max(ratios):<8.2f} {100 * mismatches:5.2f}% {area:9.3f} "
              f"{w_area:6.2f} {ratio:6.2f} {best:8.3f} {w_best:7.3f}")
        if name in FLOORED:
            if not COVERAGE[0] <= coverage <= COVERAGE[1]:
                failures.append(f"{name}: {100 * coverage:.1f} % within 1 sigma, outside "
                                f"{100 * COVERAGE[0]:.0f}-{100 * COVERAGE[1]:.0f} %")
            if ratio > AREA_RATIO:
                failures.append(f"{name}: sparsification area {ratio:.2f} x WLS's, above "
                                f"{AREA_RATIO}")
    print()
    print("Each tenth's RMS over its mean sigma (tenths from the surest):")
    for name, r in results.items():
        met = all(RATIOS[0] <= v <= RATIOS[1] for v in r["tenths"])
        print(f"  {name:<21} {' '.join(f'{v:.2f}' for v in r['tenths'])}  "
              f"{'met' if met else 'NOT met'}")
    filled_results = filled_maps(args, work, cases)
    keep_results = keep_rule(args, cases)
    if args.json:
        Path(args.json).write_text(json.dumps({"sigma": results, "filled": filled_results,
                                               "keep_rule": keep_results}, indent=1))
    scoring.floors(failures, "sigma_d")


def filled_maps(args, work, cases):
    """`fill=true` on the real pairs: the filled map's bad-1.0 and bad-2.0 against OpenCV's
    best SGBM + WLS (modes, blocks 3 and 5, λ and σ_color searched on the truth), and whether
    the filled pixels' σ_d holds (the share within 1 σ, apart from the matched pixels')."""
    chosen = [c for c in cases if c[0] in FILL_PAIRS]
    best = wls(args.wls_python, work, chosen, search=True)
    print()
    print("fill=true (each hole from its row's background) against OpenCV's best SGBM + WLS "
          "(modes, blocks 3 and 5, lambda and sigma_color searched on the truth):")
    header = (f"{'pair':<12} {'ours bad-1.0':>12} {'bad-2.0':>8} {'WLS bad-1.0':>11} "
              f"{'bad-2.0':>8} {'ratio 2.0':>9} {'filled':>7} {'within 1 sigma':>14}  WLS setting")
    print(header)
    print("-" * len(header))
    out = {}
    for name, left, right, truth, ndisp in chosen:
        arrays = ours(args.url, left, right, ndisp, "&fill=true")
        disp, std, filled = arrays["disparity"], arrays["disparity_std"], arrays["filled"]
        mine = scoring.score(np.where(np.isfinite(disp), disp, np.inf), truth)
        theirs = scoring.score(np.where(np.isfinite(best[f"{name}/best"]), best[f"{name}/best"],
                                       np.inf), truth)
        known = filled & np.isfinite(truth)
        within = float(np.mean(np.abs(disp - truth)[known] <= std[known])) if known.any() else 0.0
        ratio = mine["bad2"] / theirs["bad2"]
        out[name] = {"ours": mine, "wls": theirs, "ratio_bad2": ratio,
                     "filled": float(np.mean(filled)), "filled_within_sigma": within,
                     "wls_setting": str(best[f"{name}/best_setting"])}
        print(f"{name:<12} {mine['bad1']:11.2f}% {mine['bad2']:7.2f}% {theirs['bad1']:10.2f}% "
              f"{theirs['bad2']:7.2f}% {ratio:9.2f} {100 * np.mean(filled):6.1f}% "
              f"{100 * within:13.1f}%  {best[f'{name}/best_setting']}")
    print(f"goal: bad-2.0 at most 0.6 x OpenCV + WLS's on Motorcycle: "
          f"{'met' if out['motorcycle']['ratio_bad2'] <= 0.6 else 'NOT met'} "
          f"({out['motorcycle']['ratio_bad2']:.2f} x)")
    _, left, right, _, ndisp = chosen[0]
    plain, filling = fill_time(args.url, left, right, ndisp)
    out["time_ms"] = {"plain": plain, "fill": filling, "rounds": service.TURNS}
    print(f"time (reported, never asserted): a whole Motorcycle request {plain:.1f} ms, with "
          f"fill=true {filling:.1f} ms (taking turns, {service.TURNS} rounds, medians): "
          f"+{100 * (filling / plain - 1):.1f} %, goal <= 15 %: "
          f"{'met' if filling <= 1.15 * plain else 'NOT met'}")
    return out


def fill_time(url, left, right, ndisp, rounds=service.TURNS):
    """What fill=true adds to a whole /depth-map request: one request without it and one with
    it in turns, each on its own kept-alive connection, after one round unmeasured. Medians in
    ms: (without, with)."""
    png = lambda img: cv2.imencode(".png", img)[1].tobytes()
    parts = {"left": (png(left), "left.png", "image/png"),
             "right": (png(right), "right.png", "image/png")}
    queries = ("", "&fill=true")
    conns = [service.connect(url, parts, scenes.RIG) for _ in queries]
    times = [[] for _ in queries]
    for round_ in range(rounds + 1):
        for query, (conn, body, ctype), spent in zip(queries, conns, times):
            path = f"/depth-map?max_disparity={ndisp}&output=disparity.npy{query}"
            seconds = service.timed(conn, path, body, ctype)[1]
            if round_:
                spent.append(1e3 * seconds)
    for conn, _, _ in conns:
        conn.close()
    return statistics.median(times[0]), statistics.median(times[1])


def keep_rule(args, cases):
    """The keep rule on the real pairs with truth: density and bad-1.0 / bad-2.0 (holes taking
    their row's background, as Middlebury's tables and scripts/evaluations/stereo.py score) at each
    of service.KEEP_RULES."""
    chosen = [c for c in cases if c[0] in FILL_PAIRS]
    print()
    print("The keep rule (max_disparity_std): density, bad-1.0 / bad-2.0 (holes filled from "
          "their row's background)")
    header = f"{'settings':<50}" + "".join(f" {name:>22}" for name, *_ in chosen)
    print(header)
    print("-" * len(header))
    out = {}
    for rule in [""] + service.KEEP_RULES:
        label = rule or "defaults (max_disparity_std=4)"
        cells, out[label] = [], {}
        for name, left, right, truth, ndisp in chosen:
            disp = ours(args.url, left, right, ndisp, "&" + rule if rule else "")["disparity"]
            score = scoring.score(np.where(np.isfinite(disp), disp, np.inf), truth)
            out[label][name] = score
            cells.append(f"{score['density']:5.1f}% {score['bad1']:5.2f}/{score['bad2']:5.2f}")
        print(f"{label:<50}" + "".join(f" {c:>22}" for c in cells))
    return out


if __name__ == "__main__":
    sys.exit(main())
