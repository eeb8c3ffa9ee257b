"""Issue 69: is the projection uncertainty true on real photographs? OpenCV's 13 stereo pairs are
split into disjoint parts, each part is calibrated by POST /calibrate, and the two parts' cameras
are compared as mrcal's projection_diff compares them (points at `--distance` on each cell's ray,
the rigid motion between the two frames fitted near the centre) over the map's 16 x 12 grid. The
difference over what the two parts' maps predict for it, sqrt(sigma_a^2 + sigma_b^2), is the
ratio: 1 when the map is true, below when it is cautious, above when it is optimistic.

mrcal 2.2 (Debian's mrcal / python3-mrcal) runs on the same corners (ours, from /calibrate with
corners=true) and the same parts, LENSMODEL_OPENCV5 like ours, with its own projection
uncertainty, in the same run.

Splits: the two halves 01-07 / 08-14, alternate views, seeded random halves, and seeded 3-fold
partitions (each pair of folds compared). Printed per split and camera: the observed median
difference and the ratio over the grid, its centre and its edges; then the medians over all
comparisons, and whether the issue's goal (0.7-1.4 at the centre and at the edges) is met.
Fails (exit 1) when our median ratio at the centre or at the edges leaves --floor (default the
goal; the medians move by up to 0.1 from run to run, since the rigid motion fitted at one
distance is poorly conditioned in mrcal's projection_diff, and ours lie at 0.9-1.0).

    /usr/bin/PYTHONPATH=scripts python3 -m evaluations.uncertainty --url URL [--photographs DIR] [--json FILE]
"""
import argparse
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import urllib.error
import urllib.request

import numpy as np
import mrcal

from . import scoring
from .service import multipart

NAMES = ["01", "02", "03", "04", "05", "06", "07", "08", "09", "11", "12", "13", "14"]
# ViSP's copy of these photographs (visp-tools 3.7, data-chessboard.cfg) gives the squares' size.
BOARD = {"columns": 9, "rows": 6, "square_size": 25.0, "unit": "mm"}
GRID = (16, 12)


def calibrate(url, folder, names, distance, query=""):
    parts = []
    for n in names:
        for side in ("left", "right"):
            with open(f"{folder}/{side}{n}.jpg", "rb") as f:
                parts.append((side, (f.read(), f"{side}{n}.jpg", "image/jpeg")))
    parts.append(("board", (json.dumps(BOARD).encode(), None, "application/json")))
    body, ctype = multipart(parts)
    request = urllib.request.Request(f"{url}/calibrate?uncertainty_distance={distance}{query}",
                                     data=body, headers={"Content-Type": ctype})
    try:
        return json.loads(urllib.request.urlopen(request, timeout=300).read())
    except urllib.error.HTTPError as e:
        sys.exit(f"/calibrate answered {e.code}: {e.read()[:600]!r}")


def cells(w, h):
    return np.array([[(i + .5) * w / GRID[0] - .5, (j + .5) * h / GRID[1] - .5]
                     for j in range(GRID[1]) for i in range(GRID[0])])


def central(w, h):
    """The grid's centre: within half the way to each edge (an ellipse), as the service splits it."""
    q = cells(w, h)
    r = np.hypot((q[:, 0] - (w - 1) / 2) / (w / 2), (q[:, 1] - (h - 1) / 2) / (h / 2))
    return r < 0.5


def our_model(summary, side):
    k = np.array(summary[side]["camera_matrix"], float)
    d = np.array(summary[side]["distortion"], float)[:5]
    return mrcal.cameramodel(intrinsics=("LENSMODEL_OPENCV5", np.r_[k[0, 0], k[1, 1], k[0, 2], k[1, 2], d]),
                             imagersize=(summary["image_width"], summary["image_height"]))


def our_sigma(summary, side):
    grid = summary["projection_uncertainty"][side]["grid"]
    return np.array([[np.nan if v is None else v for v in row] for row in grid], float).ravel()


def mrcal_calibrate(work, folder, names, corners):
    """mrcal-calibrate-cameras on our corners of `names`: the two cameras' models."""
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    with open(f"{work}/corners.vnl", "w") as f:
        f.write("# filename x y\n")
        for n in names:
            for side in ("left", "right"):
                path = f"{work}/{side}{n}.jpg"
                os.symlink(os.path.abspath(f"{folder}/{side}{n}.jpg"), path)
                seen = corners[n][side]
                if seen is None:
                    f.write(f"{path} - -\n")
                for x, y in seen or []:
                    f.write(f"{path} {x} {y}\n")
    run = subprocess.run(["mrcal-calibrate-cameras", "--corners-cache", f"{work}/corners.vnl",
                          "--lensmodel", "LENSMODEL_OPENCV5", "--focal", "530",
                          "--object-spacing", str(BOARD["square_size"]),
                          "--object-width-n", str(BOARD["columns"]),
                          "--object-height-n", str(BOARD["rows"]), "--outdir", work,
                          f"{work}/left*.jpg", f"{work}/right*.jpg"], capture_output=True, text=True)
    if run.returncode:
        sys.exit(f"mrcal-calibrate-cameras failed: {run.stderr[-1500:]}")
    return [mrcal.cameramodel(f"{work}/camera-{i}.cameramodel") for i in (0, 1)]


def mrcal_sigma(model, w, h, distance):
    v = mrcal.unproject(cells(w, h), *model.intrinsics(), normalize=True)
    return np.asarray(mrcal.projection_uncertainty(v * distance, model, what="worstdirection-stdev"))


def difference(m0, m1, distance):
    return mrcal.projection_diff([m0, m1], gridn_width=GRID[0], gridn_height=GRID[1],
                                 distance=distance, use_uncertainties=False)[0].ravel()


def ratios(d, sigma, centre):
    r = d / sigma
    return float(np.nanmedian(r)), float(np.nanmedian(r[centre])), float(np.nanmedian(r[~centre]))


def splits(seed):
    out = [("halves 01-07 / 08-14", [(NAMES[:7], NAMES[7:])]),
           ("alternate", [(NAMES[0::2], NAMES[1::2])])]
    rng = random.Random(seed)
    for k in range(8):
        s = NAMES[:]
        rng.shuffle(s)
        out.append((f"random halves {k + 1}", [(sorted(s[:7]), sorted(s[7:]))]))
    for k in range(4):
        s = NAMES[:]
        rng.shuffle(s)
        folds = [sorted(s[0:5]), sorted(s[5:9]), sorted(s[9:])]
        out.append((f"3-fold {k + 1}", [(folds[a], folds[b]) for a, b in ((0, 1), (0, 2), (1, 2))]))
    return out


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--url", required=True)
    parser.add_argument("--photographs", default="tests/data/photographs/opencv-stereo")
    parser.add_argument("--distance", type=float, default=350.0)
    parser.add_argument("--seed", type=int, default=69)
    parser.add_argument("--floor", type=float, nargs=2, default=(0.7, 1.4))
    parser.add_argument("--json")
    args = parser.parse_args()
    folder, distance = args.photographs, args.distance
    full = calibrate(args.url, folder, NAMES, distance, "&corners=true")
    corners = {n: {s: v.get(f"corners_{s}") for s in ("left", "right")}
               for n, v in zip(NAMES, full["views"])}
    w, h = full["image_width"], full["image_height"]
    centre = central(w, h)
    work = tempfile.mkdtemp(prefix="eval-uncertainty-")
    pu = full["projection_uncertainty"]["left"]
    print(f"real photographs: OpenCV's samples/data (Debian opencv-doc 4.6.0, Apache-2.0 / BSD-3-Clause), "
          f"13 pairs of {w} x {h}, 9 x 6 board of 25 mm squares; points at {distance:g} mm")
    print(f"  all 13 pairs, left camera: our sigma median {pu['median_px']:.3f} px, of which the "
          f"corners' noise {pu['noise_median_px']:.3f} and the model {pu['model_median_px']:.3f}; "
          f"model_error_dominates {full['projection_uncertainty']['model_error_dominates']}")
    print(f"\n  {'split':22} {'camera':6} {'parts':24} {'observed':>8}   "
          f"{'ours: all / centre / edge':>26}   {'mrcal: all / centre / edge':>26}")
    rows = []
    for name, pairs in splits(args.seed):
        for a, b in pairs:
            ours = (calibrate(args.url, folder, a, distance), calibrate(args.url, folder, b, distance))
            theirs = (mrcal_calibrate(f"{work}/a", folder, a, corners),
                      mrcal_calibrate(f"{work}/b", folder, b, corners))
            for i, side in enumerate(("left", "right")):
                d = difference(our_model(ours[0], side), our_model(ours[1], side), distance)
                r = ratios(d, np.hypot(our_sigma(ours[0], side), our_sigma(ours[1], side)), centre)
                dm = difference(theirs[0][i], theirs[1][i], distance)
                rm = ratios(dm, np.hypot(mrcal_sigma(theirs[0][i], w, h, distance),
                                         mrcal_sigma(theirs[1][i], w, h, distance)), centre)
                rows.append(dict(split=name, camera=side, a=a, b=b, observed=float(np.median(d)),
                                 ours=r, mrcal=rm, mrcal_observed=float(np.median(dm))))
                print(f"  {name:22} {side:6} {','.join(a) + ' | ' + ','.join(b):24.24} "
                      f"{np.median(d):8.3f}   {r[0]:8.2f} {r[1]:8.2f} {r[2]:8.2f}   "
                      f"{rm[0]:8.2f} {rm[1]:8.2f} {rm[2]:8.2f}")
    shutil.rmtree(work, ignore_errors=True)
    summary = {}
    print(f"\n  observed over predicted, medians over {len(rows)} comparisons (goal 0.7-1.4 at the "
          f"centre and at the edges):")
    for who in ("ours", "mrcal"):
        m = np.median(np.array([r[who] for r in rows]), axis=0)
        summary[who] = dict(all=float(m[0]), centre=float(m[1]), edge=float(m[2]))
        print(f"    {who:6} all {m[0]:.2f}  centre {m[1]:.2f}  edge {m[2]:.2f}")
    for kind in ("halves", "3-fold"):
        sel = [r for r in rows if (kind == "3-fold") == r["split"].startswith("3-fold")]
        m, mm = (np.median(np.array([r[who] for r in sel]), axis=0) for who in ("ours", "mrcal"))
        print(f"    {kind:6} ({len(sel)}): ours {m[0]:.2f} / {m[1]:.2f} / {m[2]:.2f}; "
              f"mrcal {mm[0]:.2f} / {mm[1]:.2f} / {mm[2]:.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(dict(rows=rows, summary=summary), f, indent=1)
    met = all(0.7 <= summary["ours"][w] <= 1.4 for w in ("centre", "edge"))
    print(f"\n  goal 0.7-1.4 at the centre and at the edges: {'met' if met else 'NOT met'}; "
          f"mrcal's edges {summary['mrcal']['edge']:.2f}")
    low, high = args.floor
    failures = [f"our median ratio at the {where} is {summary['ours'][where]:.2f}, outside {low}-{high}"
                for where in ("centre", "edge") if not low <= summary["ours"][where] <= high]
    scoring.floors(failures, f"ours within the floor {low}-{high} on the real photographs", heading="FAILED:")


if __name__ == "__main__":
    main()
