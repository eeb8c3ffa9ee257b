"""OpenCV's SGBM with ximgproc's WLS filter, as OpenCV's disparity-filtering tutorial sets it up
(a left matcher, `createRightMatcher`, `createDisparityWLSFilter`, λ 8000, σ_color 1.5), on each
pair given: the filtered disparity and `getConfidenceMap()` (0-255). With `--search`, also the
best filtered map over modes, blocks 3 and 5, λ, σ_color, and the matcher with and without
the usual checks (uniqueness, speckles, disp12MaxDiff), scored against each pair's truth
(Middlebury's bad-2.0, the filtered maps being dense).

Runs in its own venv (opencv-contrib-python-headless cannot share one with
opencv-python-headless); scripts/evaluate/matcher makes it.

    python wls_confidence.py --out OUT.npz [--search] NAME LEFT RIGHT NDISP [TRUTH.npy] ...
"""
import argparse
import itertools

import cv2
import numpy as np

MODES = {"SGBM": cv2.STEREO_SGBM_MODE_SGBM, "HH": cv2.STEREO_SGBM_MODE_HH,
         "SGBM_3WAY": cv2.STEREO_SGBM_MODE_SGBM_3WAY, "HH4": cv2.STEREO_SGBM_MODE_HH4}
LAMBDAS = (2000.0, 8000.0, 32000.0)
SIGMAS = (0.8, 1.5, 3.0)


def filtered(left, right, ndisp, mode="SGBM_3WAY", block=3, lam=8000.0, sigma=1.5,
             checks=False):
    """The tutorial's pipeline (its SGBM: P1 = 24 w², P2 = 96 w² on colour, preFilterCap 63,
    3WAY, the rest OpenCV's defaults; with `checks`, also scripts/evaluations/stereo.py's uniqueness
    10, speckles of 100 within 2 and disp12MaxDiff 1): returns (the filtered disparity in
    pixels, NaN where it has none; the confidence, 0-255)."""
    channels = 1 if left.ndim == 2 else 3
    extra = {"uniquenessRatio": 10, "speckleWindowSize": 100, "speckleRange": 2,
             "disp12MaxDiff": 1} if checks else {}
    matcher = cv2.StereoSGBM_create(
        minDisparity=0, numDisparities=ndisp, blockSize=block,
        P1=8 * channels * block * block, P2=32 * channels * block * block,
        preFilterCap=63, mode=MODES[mode], **extra)
    right_matcher = cv2.ximgproc.createRightMatcher(matcher)
    wls = cv2.ximgproc.createDisparityWLSFilter(matcher)
    wls.setLambda(lam)
    wls.setSigmaColor(sigma)
    d_left = matcher.compute(left, right)
    d_right = right_matcher.compute(right, left)
    out = wls.filter(d_left, left, disparity_map_right=d_right).astype(np.float32) / 16.0
    confidence = wls.getConfidenceMap().astype(np.float32)
    out[out < 0] = np.nan
    return out, confidence


def bad(disp, truth, threshold):
    known = np.isfinite(truth)
    err = np.abs(np.where(np.isfinite(disp), disp, 0.0)[known] - truth[known])
    return 100.0 * float(np.mean(err > threshold))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", required=True)
    parser.add_argument("--search", action="store_true")
    parser.add_argument("pairs", nargs="+")
    args = parser.parse_args()
    arrays = {}
    items = args.pairs
    step = 5 if args.search else 4
    for i in range(0, len(items), step):
        name, left_path, right_path, ndisp = items[i:i + 4]
        left, right = cv2.imread(left_path), cv2.imread(right_path)
        disp, confidence = filtered(left, right, int(ndisp))
        arrays[f"{name}/disparity"] = disp
        arrays[f"{name}/confidence"] = confidence
        if args.search:
            truth = np.load(items[i + 4])
            best = None
            for mode, block, lam, sigma, checks in itertools.product(
                    MODES, (3, 5), LAMBDAS, SIGMAS, (False, True)):
                d, _ = filtered(left, right, int(ndisp), mode, block, lam, sigma, checks)
                score = (bad(d, truth, 2.0), bad(d, truth, 1.0))
                if best is None or score < best[0]:
                    best = (score, d, f"{mode} b{block} lambda {lam:g} sigma {sigma:g}"
                                      f"{' with checks' if checks else ''}")
            arrays[f"{name}/best"] = best[1]
            arrays[f"{name}/best_setting"] = np.array(best[2])
    np.savez(args.out, **arrays)


if __name__ == "__main__":
    main()
