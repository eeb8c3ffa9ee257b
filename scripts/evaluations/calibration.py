"""POST /calibrate against OpenCV 4.14 on the same rendered stereo checkerboards (see
scripts/evaluate/calibration): the errors against the truth in f, cx, cy, k1, |T| and the rotation,
the RMS and the time, for both, per set; and our per-corner residuals (what the page draws as
arrows) against OpenCV's projectPoints; accuracy floors only."""

import argparse
import http.client
import json
import statistics
import sys
import time
import urllib.parse

import cv2
import numpy as np

from . import scoring
from .service import RUNS, multipart

GOALS = {"f_%": 0.1, "pp_px": 1.0, "T_%": 0.2, "rot_deg": 0.05}
COLUMNS = ["f_%", "cx_px", "cy_px", "pp_px", "k1", "T_%", "rot_deg"]


def load(path, truth):
    n = len(truth["views"])
    files = [(open(f"{path}/left_{i:02}.png", "rb").read(), open(f"{path}/right_{i:02}.png", "rb").read())
             for i in range(n)]
    return files


class Calibrate:
    """One keep-alive connection to /calibrate with one form of pairs: `names` are the files'
    stems after left/right, `mime` their type."""

    def __init__(self, url, files, names, board, mime):
        parts = []
        ext = "png" if mime == "image/png" else "jpg"
        for n, (l, r) in zip(names, files):
            parts.append(("left", (l, f"left{n}.{ext}", mime)))
            parts.append(("right", (r, f"right{n}.{ext}", mime)))
        parts.append(("board", (json.dumps(board).encode(), None, "application/json")))
        self.body, self.ctype = multipart(parts)
        target = urllib.parse.urlsplit(url)
        self.conn = http.client.HTTPConnection(target.hostname, target.port, timeout=120)

    def post(self, query=""):
        """(seconds, the summary); exits on any answer but 200."""
        t = time.perf_counter()
        self.conn.request("POST", f"/calibrate{query}", body=self.body,
                          headers={"Content-Type": self.ctype})
        response = self.conn.getresponse()
        answer = response.read()
        elapsed = time.perf_counter() - t
        if response.status != 200:
            sys.exit(f"/calibrate answered {response.status}: {answer[:800]!r}")
        return elapsed, json.loads(answer)

    def close(self):
        self.conn.close()


def ours(url, truth, files, runs):
    names = [f"_{i:02}" for i in range(len(files))]
    session = Calibrate(url, files, names, dict(truth["board"]), "image/png")
    times, s = [], None
    for _ in range(runs + 1):  # the first warms the connection and the allocator
        elapsed, s = session.post(f"?model={truth['model']}&corners=true")
        times.append(elapsed)
    session.close()
    used = sum(v["status"] == "used" for v in s["views"])
    return dict(K1=np.array(s["left"]["camera_matrix"]), D1=np.array(s["left"]["distortion"]),
                K2=np.array(s["right"]["camera_matrix"]), D2=np.array(s["right"]["distortion"]),
                R=np.array(s["rotation"]), T=np.array(s["translation"]), rms=s["rms"], used=used,
                ms=1e3 * statistics.median(times[1:] if runs > 0 else times), summary=s)


def residuals_against_opencv(truth, s):
    """Our per-corner residuals (corners=true, the model's projection minus the corner) against
    OpenCV's projectPoints of the same corners with our K and D and a pose from solvePnP: the
    largest difference in a view's RMS and in one corner's residual, px. OpenCV's pose is each
    camera's own, ours the joint one (the right camera's through R, T), so they differ by
    what the joint fit moves. None for equidistant lenses (cv2.fisheye has no solvePnP)."""
    if truth["model"] == "equidistant":
        return None
    cols, rows = truth["board"]["columns"], truth["board"]["rows"]
    obj = np.zeros((cols * rows, 3))
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * truth["board"]["square_size"]
    worst_rms, worst_corner = 0.0, 0.0
    for side in ("left", "right"):
        k, d = np.array(s[side]["camera_matrix"]), np.array(s[side]["distortion"])
        for v in s["views"]:
            if v["status"] != "used":
                continue
            c, r = np.array(v[f"corners_{side}"]), np.array(v[f"residuals_{side}"])
            _, rvec, tvec = cv2.solvePnP(obj, c, k, d)
            p, _ = cv2.projectPoints(obj, rvec, tvec, k, d)
            r_cv = p.reshape(-1, 2) - c
            rms = lambda e: float(np.sqrt((e ** 2).sum(1).mean()))
            worst_rms = max(worst_rms, abs(rms(r) - rms(r_cv)))
            worst_corner = max(worst_corner, float(np.abs(r - r_cv).max()))
    return worst_rms, worst_corner


def opencv_once(truth, files, found=False):
    model = truth["model"]
    cols, rows = truth["board"]["columns"], truth["board"]["rows"]
    square = truth["board"]["square_size"]
    obj = np.zeros((cols * rows, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square
    t0 = time.perf_counter()
    imgs = [(cv2.imdecode(np.frombuffer(l, np.uint8), 0), cv2.imdecode(np.frombuffer(r, np.uint8), 0))
            for l, r in files]
    left, right, seen = [], [], []
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.01)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    for a, b in imgs:
        ok1, c1 = cv2.findChessboardCorners(a, (cols, rows), flags=flags)
        ok2, c2 = cv2.findChessboardCorners(b, (cols, rows), flags=flags)
        seen.append((ok1, ok2))
        if ok1 and ok2:
            left.append(cv2.cornerSubPix(a, c1, (11, 11), (-1, -1), crit))
            right.append(cv2.cornerSubPix(b, c2, (11, 11), (-1, -1), crit))
    size = imgs[0][0].shape[::-1]
    if model == "equidistant":
        o = [obj.reshape(-1, 1, 3).astype(np.float64)] * len(left)
        lf = [c.astype(np.float64) for c in left]
        rf = [c.astype(np.float64) for c in right]
        fl = cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
        _, k1, d1, _, _ = cv2.fisheye.calibrate(o, lf, size, None, None, flags=fl)
        _, k2, d2, _, _ = cv2.fisheye.calibrate(o, rf, size, None, None, flags=fl)
        rms, k1, d1, k2, d2, r, t, *_ = cv2.fisheye.stereoCalibrate(
            o, lf, rf, k1, d1, k2, d2, size, flags=cv2.fisheye.CALIB_USE_INTRINSIC_GUESS | fl)
    else:
        o = [obj] * len(left)
        fl = cv2.CALIB_RATIONAL_MODEL if model == "rational_polynomial" else 0
        _, k1, d1, _, _ = cv2.calibrateCamera(o, left, size, None, None, flags=fl)
        _, k2, d2, _, _ = cv2.calibrateCamera(o, right, size, None, None, flags=fl)
        rms, k1, d1, k2, d2, r, t, _, _ = cv2.stereoCalibrate(
            o, left, right, k1, d1, k2, d2, size, flags=cv2.CALIB_USE_INTRINSIC_GUESS | fl)
    ms = 1e3 * (time.perf_counter() - t0)
    out = dict(K1=k1, D1=d1.ravel(), K2=k2, D2=d2.ravel(), R=r, T=t.ravel(), rms=rms,
               used=len(left), ms=ms)
    if found:
        out["found"] = seen
        out["corners"] = list(zip(left, right))
    return out


def opencv_on_truth(truth):
    """cv2.fisheye's calibrate + stereoCalibrate given the rendered corners themselves (no
    detection): whether its fit converges on a wide lens when the corners are exact. A
    sentence."""
    cols, rows = truth["board"]["columns"], truth["board"]["rows"]
    obj = np.zeros((cols * rows, 1, 3))
    obj[:, 0, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * truth["board"]["square_size"]
    sides = [[np.array(v[side], np.float64).reshape(-1, 1, 2) for v in truth["views"]]
             for side in ("left", "right")]
    o, size = [obj] * len(truth["views"]), (truth["image_width"], truth["image_height"])
    fl = cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
    try:
        k1, d1 = cv2.fisheye.calibrate(o, sides[0], size, None, None, flags=fl)[1:3]
        k2, d2 = cv2.fisheye.calibrate(o, sides[1], size, None, None, flags=fl)[1:3]
        rms, k1, *_ = cv2.fisheye.stereoCalibrate(
            o, *sides, k1, d1, k2, d2, size, flags=cv2.fisheye.CALIB_USE_INTRINSIC_GUESS | fl)
    except cv2.error as e:
        return f"fails ({str(e).strip().splitlines()[-1]})"
    f = truth["left"]["fx"]
    return f"converges: RMS {rms:.4f} px, f within {100 * abs(k1[0, 0] - f) / f:.4f} %"


def opencv(truth, files, runs):
    results = [opencv_once(truth, files) for _ in range(max(runs, 1))]
    out = results[-1]
    out["ms"] = statistics.median(r["ms"] for r in results)
    return out


def errors(truth, got):
    e = {k: 0.0 for k in COLUMNS}
    for side, k, d in (("left", got["K1"], got["D1"]), ("right", got["K2"], got["D2"])):
        t = truth[side]
        e["f_%"] = max(e["f_%"], 100 * abs(k[0][0] / t["fx"] - 1), 100 * abs(k[1][1] / t["fy"] - 1))
        e["cx_px"] = max(e["cx_px"], abs(k[0][2] - t["cx"]))
        e["cy_px"] = max(e["cy_px"], abs(k[1][2] - t["cy"]))
        e["pp_px"] = max(e["pp_px"], float(np.hypot(k[0][2] - t["cx"], k[1][2] - t["cy"])))
        e["k1"] = max(e["k1"], abs(d[0] - t["distortion"][0]))
    tt = np.array(truth["translation"])
    rt = np.array(truth["rotation"]).reshape(3, 3)
    e["T_%"] = 100 * abs(np.linalg.norm(got["T"]) / np.linalg.norm(tt) - 1)
    dr = np.asarray(got["R"]) @ rt.T
    e["rot_deg"] = float(np.degrees(np.arccos(np.clip((np.trace(dr) - 1) / 2, -1, 1))))
    return e


PHOTO_NAMES = ["01", "02", "03", "04", "05", "06", "07", "08", "09", "11", "12", "13", "14"]
PHOTO_BOARD = {"columns": 9, "rows": 6, "square_size": 1.0, "unit": "mm"}


def photographs(url, path, runs):
    """OpenCV's 13 real stereo pairs (640 x 480, a 9 x 6 board whose square size is not
    published, so lengths are in squares): the boards each finds, the RMS and the parameters
    side by side with our sigma, and the time taking turns (medians of `runs`). Returns the
    failures: a board OpenCV finds that we miss."""
    files = [(open(f"{path}/left{n}.jpg", "rb").read(), open(f"{path}/right{n}.jpg", "rb").read())
             for n in PHOTO_NAMES]
    session = Calibrate(url, files, PHOTO_NAMES, PHOTO_BOARD, "image/jpeg")
    truth = {"model": "plumb_bob", "board": PHOTO_BOARD}
    ours_ms, cv_ms, summary, cv = [], [], None, None
    for k in range(runs + 1):  # taking turns; the first of each warms up and is not counted
        elapsed, summary = session.post()
        cv = opencv_once(truth, files, found=True)
        if k > 0:
            ours_ms.append(1e3 * elapsed)
            cv_ms.append(cv["ms"])
    # Once more with the corners, to calibrate OpenCV on ours: which corners make the difference.
    _, with_corners = session.post("?corners=true")
    session.close()
    ours_found = []
    for v in summary["views"]:
        failed = v.get("failed", []) if v["status"] == "board_not_found" else []
        ours_found.append(("left" not in failed, "right" not in failed))
    count = lambda found, i: sum(f[i] for f in found)
    print("\nreal photographs: OpenCV's samples/data (Debian opencv-doc 4.6.0, Apache-2.0 / "
          "BSD-3-Clause), 13 pairs of 640 x 480, 9 x 6 board, lengths in squares")
    print(f"  boards found, left / right / pairs used: ours {count(ours_found, 0)} / "
          f"{count(ours_found, 1)} / {sum(v['status'] == 'used' for v in summary['views'])}; "
          f"OpenCV {count(cv['found'], 0)} / {count(cv['found'], 1)} / {cv['used']}")
    print(f"  RMS: ours {summary['rms']:.4f} px, OpenCV {cv['rms']:.4f} px")
    # Each camera calibrated by OpenCV on its own corners (with its sigma, from
    # calibrateCameraExtended) and on ours, from the same views.
    cols, rows = PHOTO_BOARD["columns"], PHOTO_BOARD["rows"]
    obj = np.zeros((cols * rows, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2)
    size = (summary["image_width"], summary["image_height"])
    print(f"  {'parameter':12} {'ours':>10} {'sigma':>8} {'OpenCV':>10} {'sigma':>8} "
          f"{'difference/sigma':>16} {'OpenCV on our corners':>22}")
    for i, (side, k, d) in enumerate((("left", cv["K1"], cv["D1"]), ("right", cv["K2"], cv["D2"]))):
        o = summary[side]
        std = o["std"]
        theirs = [c[i] for c in cv["corners"]]
        _, _, _, _, _, cv_std, _, _ = cv2.calibrateCameraExtended([obj] * len(theirs), theirs, size,
                                                                  None, None)
        cv_std = cv_std.ravel()
        mine = [np.array(v[f"corners_{side}"], np.float32).reshape(-1, 1, 2)
                for v in with_corners["views"] if v["status"] == "used"]
        rms_on_ours, k_on_ours, d_on_ours, _, _ = cv2.calibrateCamera([obj] * len(mine), mine, size,
                                                                      None, None)
        d_on_ours = d_on_ours.ravel()
        for j, (name, ours_v, sd, cv_v, on_ours) in enumerate((
                ("fx", o["camera_matrix"][0][0], std["fx"], k[0][0], k_on_ours[0][0]),
                ("fy", o["camera_matrix"][1][1], std["fy"], k[1][1], k_on_ours[1][1]),
                ("cx", o["camera_matrix"][0][2], std["cx"], k[0][2], k_on_ours[0][2]),
                ("cy", o["camera_matrix"][1][2], std["cy"], k[1][2], k_on_ours[1][2]),
                ("k1", o["distortion"][0], std["distortion"][0], d[0], d_on_ours[0]),
                ("k2", o["distortion"][1], std["distortion"][1], d[1], d_on_ours[1]))):
            both = float(np.hypot(sd, cv_std[j]))
            print(f"  {side + ' ' + name:12} {ours_v:10.4f} {sd:8.4f} {cv_v:10.4f} {cv_std[j]:8.4f} "
                  f"{(cv_v - ours_v) / both:16.2f} {on_ours:22.4f}")
        print(f"  {side + ' RMS':12} OpenCV's calibrateCamera on our corners {rms_on_ours:.4f} px")
    t_ours, t_cv = np.array(summary["translation"]), np.asarray(cv["T"])
    t_sd = float(np.linalg.norm(np.array(summary["translation_std"]) * t_ours) / np.linalg.norm(t_ours))
    print(f"  {'|T|':12} {np.linalg.norm(t_ours):10.4f} {t_sd:8.4f} {np.linalg.norm(t_cv):10.4f} "
          f"{(np.linalg.norm(t_cv) - np.linalg.norm(t_ours)) / t_sd:16.2f}")
    dr = np.asarray(cv["R"]) @ np.array(summary["rotation"]).T
    angle = float(np.degrees(np.arccos(np.clip((np.trace(dr) - 1) / 2, -1, 1))))
    print(f"  rotation between the two estimates {angle:.4f} deg (our sigma "
          f"{' / '.join(f'{v:.4f}' for v in summary['rotation_std_deg'])} deg)")
    print(f"  time, taking turns, median of {runs}: the whole /calibrate request "
          f"{statistics.median(ours_ms):.0f} ms; OpenCV findChessboardCorners + cornerSubPix + "
          f"calibrateCamera x2 + stereoCalibrate {statistics.median(cv_ms):.0f} ms")
    failures = []
    for n, (o, c) in zip(PHOTO_NAMES, zip(ours_found, cv["found"])):
        for i, side in enumerate(("left", "right")):
            if c[i] and not o[i]:
                failures.append(f"real photographs: OpenCV finds the board in {side}{n}.jpg, we do not")
    return failures


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--url", required=True)
    parser.add_argument("--data", required=True)
    parser.add_argument("--sets", nargs="+", required=True)
    parser.add_argument("--photographs", help="OpenCV's real stereo set (left01.jpg ...)")
    parser.add_argument("--json")
    args = parser.parse_args()
    rows, failures = [], []
    print(f"{'set':24} {'who':7} " + " ".join(f"{c:>8}" for c in COLUMNS)
          + f" {'rms':>7} {'used':>5} {'ms':>7}")
    for k, name in enumerate(args.sets):
        model, seed = name.split(":")
        path = f"{args.data}/{model}-{seed}"
        truth = json.load(open(f"{path}/truth.json"))
        files = load(path, truth)
        runs = RUNS if k == 0 else 0
        results = {"ours": ours(args.url, truth, files, runs)}
        try:
            results["opencv"] = opencv(truth, files, runs)
        except cv2.error as e:
            print(f"{name:24} opencv  failed: {str(e).strip().splitlines()[-1]}")
        if name.startswith("fisheye"):
            print(f"{name:24} opencv on the rendered corners themselves (no detection): "
                  f"{opencv_on_truth(truth)}")
        for who, got in results.items():
            e = errors(truth, got)
            rows.append(dict(set=name, who=who, **e, rms=float(got["rms"]), used=got["used"],
                             ms=got["ms"], timed=runs > 0))
            print(f"{name:24} {who:7} " + " ".join(f"{e[c]:8.4f}" for c in COLUMNS)
                  + f" {got['rms']:7.4f} {got['used']:5d} {got['ms']:7.0f}")
            if who == "ours":
                check = residuals_against_opencv(truth, got["summary"])
                if check is not None:
                    print(f"{name:24} residuals against OpenCV projectPoints (solvePnP pose): view RMS "
                          f"within {check[0]:.4f} px, each corner within {check[1]:.4f} px")
                    if check[0] > 0.02 or check[1] > 0.2:
                        failures.append(f"{name}: residuals {check} differ from OpenCV's by more than "
                                        "0.02 px (view RMS) or 0.2 px (a corner)")
                for goal, limit in GOALS.items():
                    if e[goal] > limit:
                        failures.append(f"{name}: our {goal} {e[goal]:.4f} above the goal {limit}")
    print("\nmean over the sets (OpenCV's over those it calibrated):")
    for who in ("ours", "opencv"):
        mine = [r for r in rows if r["who"] == who]
        print(f"  {who:7} " + " ".join(f"{c} {statistics.mean(r[c] for r in mine):.4f}" for c in COLUMNS))
    # Compared on the sets where both calibrated.
    both = {r["set"] for r in rows if r["who"] == "opencv"}
    for c in ("f_%", "pp_px", "T_%", "rot_deg"):
        o = statistics.mean(r[c] for r in rows if r["who"] == "ours" and r["set"] in both)
        v = statistics.mean(r[c] for r in rows if r["who"] == "opencv")
        if o > v:
            failures.append(f"our mean {c} {o:.4f} is above OpenCV's {v:.4f}")
    timed = [r for r in rows if r["timed"]]
    print(f"\ntime for {timed[0]['set']} (15 pairs, 640 x 480, median of {RUNS}): the whole "
          f"/calibrate request {timed[0]['ms']:.0f} ms; OpenCV detection + calibration "
          f"{timed[1]['ms']:.0f} ms")
    if args.photographs:
        failures += photographs(args.url, args.photographs, RUNS)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    scoring.floors(failures, "calibration goals", heading="FAILED:")


if __name__ == "__main__":
    main()
