"""The evaluation behind scripts/evaluate/corners: OpenCV's findChessboardCorners + cornerSubPix
(11 x 11) against our refinement started from the same findChessboardCorners corners, on
rendered boards whose exact corners are in each set's truth.json.
"""

import argparse
import json
import subprocess
import sys

import cv2
import numpy as np

# The goal, and no worse than OpenCV on the same images.
MEDIAN_FLOOR = 0.05


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--boards", required=True, help="the boards example binary")
    ap.add_argument("--data", required=True)
    ap.add_argument("--sets", nargs="+", required=True, help="MODEL:SEED, rendered under --data")
    ap.add_argument("--json", help="write the figures here too")
    args = ap.parse_args()

    rows = []
    failed = False
    for s in args.sets:
        model, seed = s.split(":")
        d = f"{args.data}/{model}-{seed}"
        truth = json.load(open(f"{d}/truth.json"))
        pattern = (truth["board"]["columns"], truth["board"]["rows"])
        starts, theirs, exact = {}, {}, {}
        missed = 0
        for i, view in enumerate(truth["views"]):
            for side in ("left", "right"):
                name = f"{side}_{i:02d}.png"
                img = cv2.imread(f"{d}/{name}", cv2.IMREAD_GRAYSCALE)
                ok, found = cv2.findChessboardCorners(
                    img, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
                if not ok:
                    missed += 1
                    continue
                found = found.reshape(-1, 2).astype(np.float64)
                t = np.array(view[side])
                # A symmetric-looking board may come back in the reverse order.
                if np.median(np.linalg.norm(found - t, axis=1)) > np.median(np.linalg.norm(found[::-1] - t, axis=1)):
                    t = t[::-1]
                starts[name] = found.tolist()
                exact[name] = t
                sub = cv2.cornerSubPix(img, found.astype(np.float32).reshape(-1, 1, 2), (11, 11), (-1, -1),
                                       (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001))
                theirs[name] = sub.reshape(-1, 2).astype(np.float64)
        json.dump(starts, open(f"{d}/starts.json", "w"))
        subprocess.run([args.boards, "refine", d], check=True)
        ours_raw = json.load(open(f"{d}/refined.json"))
        e_ours, e_theirs, e_start, lost = [], [], [], 0
        for name, t in exact.items():
            e_theirs.append(np.linalg.norm(theirs[name] - t, axis=1))
            e_start.append(np.linalg.norm(np.array(starts[name]) - t, axis=1))
            for p, q in zip(ours_raw[name], t):
                if p is None:
                    lost += 1
                else:
                    e_ours.append(np.hypot(p[0] - q[0], p[1] - q[1]))
        e_theirs = np.concatenate(e_theirs)
        e_start = np.concatenate(e_start)
        e_ours = np.array(e_ours)

        def stats(e):
            return {"median": float(np.median(e)), "p95": float(np.percentile(e, 95)), "max": float(e.max())}

        row = {"set": f"{model} seed {seed}", "images": len(exact), "boards_missed_by_opencv": missed,
               "start": stats(e_start), "opencv": stats(e_theirs), "ours": stats(e_ours),
               "ours_lost": lost}
        rows.append(row)
        if row["ours"]["median"] > MEDIAN_FLOOR or row["ours"]["median"] > row["opencv"]["median"] or lost:
            failed = True

    print(f"{'set':<26} {'images':>6}  {'findChessboardCorners':>22}  {'cornerSubPix 11x11':>22}  {'ours':>22}")
    print(f"{'':<26} {'':>6}  {'median / p95 / max px':>22}  {'median / p95 / max px':>22}  {'median / p95 / max px':>22}")
    fmt = lambda s: f"{s['median']:.4f} / {s['p95']:.3f} / {s['max']:.2f}"
    for r in rows:
        lost = f"  ({r['ours_lost']} lost)" if r["ours_lost"] else ""
        print(f"{r['set']:<26} {r['images']:>6}  {fmt(r['start']):>22}  {fmt(r['opencv']):>22}  {fmt(r['ours']):>22}{lost}")
    if args.json:
        json.dump(rows, open(args.json, "w"), indent=2)
    if failed:
        print(f"FAIL: our median must be at most {MEDIAN_FLOOR} px and at most OpenCV's, with no corner lost",
              file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
