"""ChArUco corners against OpenCV's CharucoDetector on the same images, in the same run.

The boards are OpenCV's own: `cv2.aruco.CharucoBoard(...).generateImage` prints each one, and
this script photographs the print through a distorted lens (plumb_bob, rational, equidistant)
at known poses, some with the board partly out of the frame, anti-aliased, blurred and noisy.
The truth is each inner corner projected by the same lens. Ours run through
`examples/boards charuco`; OpenCV's `CharucoDetector.detectBoard` with its defaults. Printed:
corners found of those in the frame, the median and 95th percentile error, ids wrong, and the
time per image taking turns (medians). Exits 1 when ours finds fewer corners than OpenCV's on a
set or errs more (median), or reads a wrong id.

With --url, each set is also calibrated as a stereo pair (12 pairs, the last third with the
board's middle on the left image's right edge): ours by POST /calibrate with the ChArUco board,
OpenCV by CharucoDetector + calibrateCamera per camera + stereoCalibrate (CALIB_USE_INTRINSIC_GUESS)
on the corners both cameras saw, as its samples do. Errors in f (%), the principal point (px),
|T| (%) and the rotation (deg) against the truth, and the views each used. Exits 1 when ours is
worse than OpenCV's on any of them, or uses fewer views.

--also NAME=BINARY scores another detector beside them (a binary printing what
`examples/boards charuco` prints; `crates/library-eval`'s `charuco` runs calib-targets), with
no goal of its own.

    PYTHONPATH=scripts python3 -m evaluations.charuco BOARDS_BINARY OUT_DIR [--url URL] [--also NAME=BINARY]
"""
import http.client
import json
import urllib.parse
import statistics
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from . import scoring
from .service import multipart

SIZE = (640, 480)
SETS = [
    # name, dictionary, squares, lens model, distortion, focal length
    ("plumb_bob", "DICT_4X4_50", (8, 6), "plumb_bob", [-0.28, 0.09, 0.001, -0.0005, 0.0], 620.0),
    ("rational", "DICT_5X5_100", (10, 7), "rational_polynomial",
     [0.4, -0.1, 0.0, 0.0, 0.0, 0.7, -0.05, 0.0], 600.0),
    ("equidistant", "DICT_6X6_250", (9, 6), "equidistant", [-0.05, 0.01, -0.004, 0.0], 330.0),
    ("legacy_aruco_original", "DICT_ARUCO_ORIGINAL", (7, 6), "plumb_bob",
     [-0.1, 0.02, 0.0, 0.0, 0.0], 700.0),
]
SQUARE, MARKER, PX = 30.0, 22.0, 60  # mm, mm, pixels of the print per square


def board_of(dictionary, squares, legacy):
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    b = cv2.aruco.CharucoBoard(squares, SQUARE, MARKER, d)
    b.setLegacyPattern(legacy)
    return b


def normalize(model, k, d, pts):
    pts = pts.reshape(-1, 1, 2).astype(np.float64)
    if model == "equidistant":
        return cv2.fisheye.undistortPoints(pts, k, np.array(d)).reshape(-1, 2)
    return cv2.undistortPoints(pts, k, np.array(d)).reshape(-1, 2)


def project(model, k, d, rvec, tvec, points):
    if model == "equidistant":
        p, _ = cv2.fisheye.projectPoints(points.reshape(-1, 1, 3), rvec, tvec, k, np.array(d))
    else:
        p, _ = cv2.projectPoints(points, rvec, tvec, k, np.array(d))
    return p.reshape(-1, 2)


def photograph(board, squares, model, k, d, rvec, tvec, seed):
    """The print at the pose (board to camera), through the lens, 3 x 3 supersampled."""
    sx, sy = squares
    margin = PX
    printed = board.generateImage((sx * PX + 2 * margin, sy * PX + 2 * margin), marginSize=margin)
    n = 3
    w, h = SIZE
    u, v = np.meshgrid((np.arange(w * n) + 0.5) / n - 0.5, (np.arange(h * n) + 0.5) / n - 0.5)
    rays = normalize(model, k, d, np.stack([u.ravel(), v.ravel()], 1))
    r, _ = cv2.Rodrigues(rvec)
    hom = np.column_stack([r[:, 0], r[:, 1], tvec.ravel()])
    plane = np.linalg.solve(hom, np.column_stack([rays, np.ones(len(rays))]).T).T
    front = plane[:, 2] > 0
    bx, by = plane[:, 0] / plane[:, 2], plane[:, 1] / plane[:, 2]
    # Board mm to print pixels (pixel centres at +0.5), the margin around the squares.
    mx = (bx / SQUARE * PX + margin - 0.5).astype(np.float32)
    my = (by / SQUARE * PX + margin - 0.5).astype(np.float32)
    mx[~front] = -1e6
    sampled = cv2.remap(printed, mx.reshape(h * n, w * n), my.reshape(h * n, w * n),
                        cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=90)
    image = cv2.resize(sampled.astype(np.float32), SIZE, interpolation=cv2.INTER_AREA)
    image = 20 + image * 0.82
    image = cv2.GaussianBlur(image, (0, 0), 0.7)
    rng = np.random.default_rng(seed)
    image += rng.normal(0, 1.5, image.shape)
    return np.clip(np.round(image), 0, 255).astype(np.uint8)


def poses(squares, rng, count):
    """Board poses: most whole in the frame, the last third partly out of it."""
    sx, sy = squares
    centre = np.array([sx * SQUARE / 2, sy * SQUARE / 2, 0.0])
    out = []
    for i in range(count):
        partial = i >= 2 * count // 3
        angles = rng.uniform(-0.45, 0.45, 3) * [1, 1, 0.4]
        r, _ = cv2.Rodrigues(angles)
        distance = rng.uniform(480, 620)
        shift = rng.uniform(-60, 60, 2)
        if partial:
            shift[0] = rng.choice([-1, 1]) * rng.uniform(150, 200)
        t = np.array([shift[0], shift[1], distance]) - r @ centre
        out.append((angles.reshape(3, 1), t.reshape(3, 1)))
    return out


RIG_R = np.array([0.01, -0.02, 0.005])
RIG_T = np.array([-120.0, 1.0, -1.5])


def stereo(name, dictionary, squares, model, d, f, s, url, out):
    """Both calibrations of one set against the truth; returns the failures."""
    legacy = name.startswith("legacy")
    board = board_of(dictionary, squares, legacy)
    k1 = np.array([[f, 0, 322.0], [0, f * 1.002, 238.0], [0, 0, 1]])
    k2 = np.array([[f * 0.99, 0, 318.0], [0, f * 0.993, 242.0], [0, 0, 1]])
    d2 = [0.9 * v for v in d]
    r_rig, _ = cv2.Rodrigues(RIG_R.reshape(3, 1))
    rng = np.random.default_rng(200 + s)
    files = []
    for i, (rvec, tvec) in enumerate(poses(squares, rng, 12)):
        if i >= 8:  # the board's middle onto the left image's right edge (x = 600 px)
            r, _ = cv2.Rodrigues(rvec)
            centre = r @ np.array([squares[0] * SQUARE / 2, squares[1] * SQUARE / 2, 0]) + tvec.ravel()
            along = (600 - 322) / f
            if model == "equidistant":
                # A fisheye puts the ray at angle θ at r = f·θ (not f·tan θ), and shrinks what
                # it sees there: the board is brought to 60 % of its distance, or its markers
                # at the edge are too small for any detector to read.
                tvec, centre = 0.6 * tvec, 0.6 * centre
                along = np.tan(along)
            tvec = tvec + np.array([[along * centre[2] - centre[0]], [0], [0]])
        r, _ = cv2.Rodrigues(rvec)
        rvec2, _ = cv2.Rodrigues(r_rig @ r)
        tvec2 = r_rig @ tvec + RIG_T.reshape(3, 1)
        left = photograph(board, squares, model, k1, d, rvec, tvec, seed=5000 + 100 * s + i)
        right = photograph(board, squares, model, k2, d2, rvec2, tvec2, seed=6000 + 100 * s + i)
        files.append((cv2.imencode(".png", left)[1].tobytes(), cv2.imencode(".png", right)[1].tobytes()))
    # Ours: one request.
    parts = []
    for i, (l, r) in enumerate(files):
        parts.append(("left", (l, f"left{i}.png", "image/png")))
        parts.append(("right", (r, f"right{i}.png", "image/png")))
    spec = {"type": "charuco", "squares_x": squares[0], "squares_y": squares[1],
            "square_size": SQUARE, "marker_size": MARKER, "dictionary": dictionary, "legacy": legacy}
    parts.append(("board", (json.dumps(spec).encode(), None, "application/json")))
    body, ctype = multipart(parts)
    target = urllib.parse.urlsplit(url)
    conn = http.client.HTTPConnection(target.hostname, target.port, timeout=300)
    conn.request("POST", f"/calibrate?model={model}", body=body, headers={"Content-Type": ctype})
    response = conn.getresponse()
    answer = response.read()
    conn.close()
    if response.status != 200:
        return [f"{name}: /calibrate answered {response.status}: {answer[:400]!r}"]
    o = json.loads(answer)
    ours = dict(K1=np.array(o["left"]["camera_matrix"]), K2=np.array(o["right"]["camera_matrix"]),
                R=np.array(o["rotation"]), T=np.array(o["translation"]),
                used=sum(v["status"] == "used" for v in o["views"]))
    # OpenCV: CharucoDetector, calibrateCamera per camera, stereoCalibrate on shared ids.
    detector = cv2.aruco.CharucoDetector(board)
    found = []
    for l, r in files:
        views = []
        for data in (l, r):
            image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)
            cc, ci, _, _ = detector.detectBoard(image)
            views.append({} if ci is None else {int(i): c for i, c in zip(ci.ravel(), cc.reshape(-1, 2))})
        found.append(views)
    corners3 = board.getChessboardCorners().astype(np.float32)
    cv = None
    try:
        mono = []
        for side in (0, 1):
            obj, img = [], []
            for v in found:
                ids = sorted(v[side])
                if len(ids) >= 6:
                    obj.append(corners3[ids].reshape(-1, 1, 3))
                    img.append(np.array([v[side][i] for i in ids], np.float32).reshape(-1, 1, 2))
            if model == "equidistant":
                _, k, dd, _, _ = cv2.fisheye.calibrate(obj, img, SIZE, None, None,
                                                       flags=cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC)
            else:
                flags = cv2.CALIB_RATIONAL_MODEL if model == "rational_polynomial" else 0
                _, k, dd, _, _ = cv2.calibrateCamera(obj, img, SIZE, None, None, flags=flags)
            mono.append((k, dd))
        obj, img1, img2 = [], [], []
        for v in found:
            ids = sorted(set(v[0]) & set(v[1]))
            if len(ids) >= 6:
                obj.append(corners3[ids].reshape(-1, 1, 3))
                img1.append(np.array([v[0][i] for i in ids], np.float32).reshape(-1, 1, 2))
                img2.append(np.array([v[1][i] for i in ids], np.float32).reshape(-1, 1, 2))
        if model == "equidistant":
            res = cv2.fisheye.stereoCalibrate(obj, img1, img2, mono[0][0], mono[0][1], mono[1][0],
                                              mono[1][1], SIZE, flags=cv2.fisheye.CALIB_FIX_INTRINSIC)
            k1c, k2c, rc, tc = mono[0][0], mono[1][0], res[5], res[6]
        else:
            flags = cv2.CALIB_USE_INTRINSIC_GUESS | (cv2.CALIB_RATIONAL_MODEL if model == "rational_polynomial" else 0)
            res = cv2.stereoCalibrate(obj, img1, img2, mono[0][0], mono[0][1], mono[1][0], mono[1][1],
                                      SIZE, flags=flags)
            k1c, k2c, rc, tc = res[1], res[3], res[5], res[6]
        cv = dict(K1=k1c, K2=k2c, R=rc, T=tc.ravel(), used=len(obj))
    except cv2.error as e:
        print(f"{name:24} opencv  failed: {str(e).strip().splitlines()[-1]}")
    def errors(got):
        f_err = max(abs(got[k][0, 0] / t[0, 0] - 1) for k, t in (("K1", k1), ("K2", k2))) * 100
        pp = max(float(np.hypot(*(got[k][:2, 2] - t[:2, 2]))) for k, t in (("K1", k1), ("K2", k2)))
        t_err = abs(np.linalg.norm(got["T"]) / np.linalg.norm(RIG_T) - 1) * 100
        rot = float(np.degrees(np.linalg.norm(cv2.Rodrigues(got["R"] @ r_rig.T)[0])))
        return dict(f=f_err, pp=pp, T=t_err, rot=rot)
    failures = []
    e_ours = errors(ours)
    print(f"{name:24} ours    f {e_ours['f']:.4f} %  pp {e_ours['pp']:.3f} px  |T| {e_ours['T']:.4f} %  "
          f"rot {e_ours['rot']:.4f} deg  views {ours['used']}/12")
    if cv is not None:
        e_cv = errors(cv)
        print(f"{name:24} opencv  f {e_cv['f']:.4f} %  pp {e_cv['pp']:.3f} px  |T| {e_cv['T']:.4f} %  "
              f"rot {e_cv['rot']:.4f} deg  views {cv['used']}/12")
        for key in e_ours:
            if e_ours[key] > e_cv[key]:
                failures.append(f"{name}: our {key} error {e_ours[key]:.4f} above OpenCV's {e_cv[key]:.4f}")
        if ours["used"] < cv["used"]:
            failures.append(f"{name}: ours used {ours['used']} views, OpenCV {cv['used']}")
    return failures


def main():
    binary, out = sys.argv[1], Path(sys.argv[2])
    url = sys.argv[sys.argv.index("--url") + 1] if "--url" in sys.argv else None
    also = sys.argv[sys.argv.index("--also") + 1].split("=", 1) if "--also" in sys.argv else None
    binaries = {"ours": binary} | ({also[0]: also[1]} if also else {})
    failures = []
    print("\nChArUco corners: ours against OpenCV's CharucoDetector on OpenCV's printed boards "
          "(generateImage) photographed through each lens; errors in px")
    print(f"{'set':24} {'who':13} {'found':>9} {'median':>7} {'p95':>7} {'wrong id':>8} {'ms/img':>7}")
    for s, (name, dictionary, squares, model, d, f) in enumerate(SETS):
        legacy = name.startswith("legacy")
        board = board_of(dictionary, squares, legacy)
        k = np.array([[f, 0, 322.0], [0, f * 1.002, 238.0], [0, 0, 1]])
        rng = np.random.default_rng(100 + s)
        folder = out / f"charuco-{name}"
        folder.mkdir(parents=True, exist_ok=True)
        for old in folder.glob("*.png"):
            old.unlink()
        truths = {}
        corners = board.getChessboardCorners().astype(np.float64)
        for i, (rvec, tvec) in enumerate(poses(squares, rng, 9)):
            image = photograph(board, squares, model, k, d, rvec, tvec, seed=1000 * s + i)
            file = f"view_{i:02}.png"
            cv2.imwrite(str(folder / file), image)
            p = project(model, k, d, rvec, tvec, corners)
            inside = (p[:, 0] > 6) & (p[:, 1] > 6) & (p[:, 0] < SIZE[0] - 7) & (p[:, 1] < SIZE[1] - 7)
            truths[file] = (p, inside)
        (folder / "board.json").write_text(json.dumps({
            "squares_x": squares[0], "squares_y": squares[1], "square_size": SQUARE,
            "marker_size": MARKER, "dictionary": dictionary, "legacy": legacy}))
        detector = cv2.aruco.CharucoDetector(board)
        results = {who: {} for who in [*binaries, "opencv"]}
        times = {who: [] for who in results}
        for _ in range(3):  # taking turns; the per-image medians over the rounds
            for who, program in binaries.items():
                command = [program, "charuco", str(folder)] if who == "ours" else [program, str(folder)]
                got = json.loads(subprocess.run(command, check=True, capture_output=True).stdout)
                results[who] = {f: (np.array(v["ids"], int), np.array(v["points"]).reshape(-1, 2))
                                for f, v in got.items()}
                times[who].append(sum(v["ms"] for v in got.values()) / max(len(got), 1))
            total = 0.0
            for file in truths:
                image = cv2.imread(str(folder / file), cv2.IMREAD_GRAYSCALE)
                t = time.perf_counter()
                cc, ci, _, _ = detector.detectBoard(image)
                total += time.perf_counter() - t
                results["opencv"][file] = ((ci.ravel() if ci is not None else np.zeros(0, int)),
                                           (cc.reshape(-1, 2) if cc is not None else np.zeros((0, 2))))
            times["opencv"].append(1e3 * total / len(truths))
        summary = {}
        for who in results:
            if not results[who]:
                print(f"{name:24} {who:13} (nothing: this detector does not read this board)")
                continue
            errors, found, shown, wrong = [], 0, 0, 0
            for file, (p, inside) in truths.items():
                ids, points = results[who][file]
                shown += int(inside.sum())
                for i, q in zip(ids, points):
                    e = float(np.hypot(*(q - p[i])))
                    if e > 3.0:
                        wrong += 1
                    else:
                        errors.append(e)
                        found += 1
            med = statistics.median(errors) if errors else float("nan")
            p95 = float(np.percentile(errors, 95)) if errors else float("nan")
            summary[who] = (found, med, wrong)
            print(f"{name:24} {who:13} {found:4}/{shown:<4} {med:7.3f} {p95:7.3f} {wrong:8d} "
                  f"{statistics.median(times[who]):7.1f}")
        (fo, mo, wo), (fc, mc, _) = summary["ours"], summary["opencv"]
        if fo < fc:
            failures.append(f"{name}: ours found {fo} corners, OpenCV {fc}")
        if mo > mc:
            failures.append(f"{name}: our median error {mo:.3f} px above OpenCV's {mc:.3f}")
        if wo:
            failures.append(f"{name}: {wo} corners of ours more than 3 px off (a wrong id)")
    if url:
        print("\nChArUco calibration of a pair, 12 views (the last 4 partial in the left camera): "
              "ours (POST /calibrate) against OpenCV (CharucoDetector + calibrateCamera x2 + "
              "stereoCalibrate on shared ids); errors against the truth")
        for s, (name, dictionary, squares, model, d, f) in enumerate(SETS):
            failures += stereo(name, dictionary, squares, model, d, f, s, url, out)
    scoring.floors(failures, "ChArUco goals", heading="FAILED:")


if __name__ == "__main__":
    main()
