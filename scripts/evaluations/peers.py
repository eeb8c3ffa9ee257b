"""OpenCV's side of every matcher comparison: StereoSGBM in each mode with blocks 3 and 5, set
as the issues set them, its maps in pixels (inf where invalid) and its compute() times.
"""

import statistics
import time

import cv2
import numpy as np

from .service import RUNS


def sgbm_matcher(mode, block, disparities):
    """OpenCV's StereoSGBM in `mode` with `block`, as the issue sets it."""
    return cv2.StereoSGBM_create(
        minDisparity=0,
        numDisparities=disparities,
        blockSize=block,
        P1=8 * 3 * block * block,
        P2=32 * 3 * block * block,
        disp12MaxDiff=1,
        uniquenessRatio=10,
        speckleWindowSize=100,
        speckleRange=2,
        mode=mode,
    )


def sgbm(left, right, mode, block, disparities, runs):
    """OpenCV's StereoSGBM in `mode` with `block` ([`sgbm_matcher`]): its map (inf where
    invalid) and the median time of `compute()` over `runs`."""
    matcher = sgbm_matcher(mode, block, disparities)
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        raw = matcher.compute(left, right)
        times.append(time.perf_counter() - t)
    disp = raw.astype(np.float32) / 16.0
    disp[raw < 0] = np.inf
    return disp, statistics.median(times)


def opencv(left, right, disparities, runs=RUNS):
    """Every StereoSGBM mode with block 3 and 5, as the issue sets them."""
    cv2.setNumThreads(2)
    modes = {
        "SGBM": cv2.STEREO_SGBM_MODE_SGBM,
        "HH": cv2.STEREO_SGBM_MODE_HH,
        "SGBM_3WAY": cv2.STEREO_SGBM_MODE_SGBM_3WAY,
        "HH4": cv2.STEREO_SGBM_MODE_HH4,
    }
    for name, mode in modes.items():
        for block in (3, 5):
            disp, seconds = sgbm(left, right, mode, block, disparities, runs)
            yield f"OpenCV {name} b{block}", disp, seconds
