"""Shared scoring: Middlebury's bad-0.5/1.0/2.0 with holes filled from the row's background,
the density, the methods' table row, and an evaluation's floors checked (exit 1 below them).
"""

import sys

import numpy as np


def fill(disp):
    """Middlebury's filling: each hole takes the smaller of the nearest valid disparities to
    its left and right on the row."""
    out = disp.copy()
    h, w = disp.shape
    idx = np.arange(w)
    for y in range(h):
        row = disp[y]
        valid = np.isfinite(row)
        if not valid.any():
            out[y] = 0
            continue
        left = np.maximum.accumulate(np.where(valid, idx, -1))
        right = np.minimum.accumulate(np.where(valid, idx, w)[::-1])[::-1]
        lv = np.where(left >= 0, row[np.clip(left, 0, w - 1)], np.inf)
        rv = np.where(right < w, row[np.clip(right, 0, w - 1)], np.inf)
        out[y] = np.where(valid, row, np.minimum(lv, rv))
    return out


def score(disp, truth):
    known = np.isfinite(truth)
    err = np.abs(fill(disp)[known] - truth[known])
    bad = {f"bad{t:g}": 100.0 * float(np.mean(err > t)) for t in (0.5, 1.0, 2.0)}
    bad["density"] = 100.0 * float(np.mean(np.isfinite(disp)))
    return bad


def floors(failures, what, heading="ACCURACY BELOW THE FLOOR:"):
    """Ends an evaluation's checks: `heading` and each of `failures` printed and exit 1, or
    `what` met."""
    if failures:
        print("\n".join(["", heading] + ["  " + f for f in failures]))
        sys.exit(1)
    print(f"{what}: met")


def method_row(scene, name, s, seconds):
    """One line of the methods' table: bad-0.5/1.0/2.0, density and time of `s`, a [`score`]."""
    return (f"{scene:<11} {name:<22} {s['bad0.5']:8.2f} {s['bad1']:8.2f} {s['bad2']:8.2f} "
            f"{s['density']:8.1f} {seconds * 1e3:8.1f}")
