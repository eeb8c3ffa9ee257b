"""OpenCV 4.14 on the images examples/corner_sizes.rs wrote: findChessboardCorners (adaptive
threshold, normalisation) + cornerSubPix 11 x 11 on each left_NN.png, errors against
truth_NN.json and the time per image, printed like the example's line. Not in CI: at 4000 x 3000
OpenCV takes over a minute per image.

    PYTHONPATH=scripts python3 -m evaluations.corner_sizes DIR [DIR ...]
"""
import glob
import json
import sys
import time

import cv2
import numpy as np

for d in sys.argv[1:]:
    errs, found, n, t = [], 0, 0, 0.0
    for f in sorted(glob.glob(d + "/left_*.png")):
        n += 1
        img = cv2.imread(f, cv2.IMREAD_GRAYSCALE)
        with open(f.replace("left_", "truth_").replace(".png", ".json")) as fh:
            truth = np.array(json.load(fh))
        t0 = time.perf_counter()
        flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        ok, c = cv2.findChessboardCorners(img, (9, 6), flags=flags)
        if ok:
            crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.01)
            c = cv2.cornerSubPix(img, c, (11, 11), (-1, -1), crit)
        t += time.perf_counter() - t0
        if not ok:
            continue
        found += 1
        c = c.reshape(-1, 2)
        # OpenCV may number the board from either end.
        if np.linalg.norm(c[0] - truth[0]) > np.linalg.norm(c[0] - truth[-1]):
            c = c[::-1]
        errs += list(np.linalg.norm(c - truth, axis=1))
    med = np.median(errs) if errs else float("nan")
    p95 = np.percentile(errs, 95) if errs else float("nan")
    print(f"{d}: opencv found {found}/{n} median {med:.4f} p95 {p95:.4f} px, {1e3 * t / max(n, 1):.1f} ms/image")
