"""ChArUco corners against OpenCV's CharucoDetector on the same images, in the same run.

The boards are OpenCV's own: `cv2.aruco.CharucoBoard(...).generateImage` prints each one, and
this script photographs the print through a distorted lens (plumb_bob, rational, equidistant)
at known poses, some with the board partly out of the frame, anti-aliased, blurred and noisy.
The truth is each inner corner projected by the same lens. Ours run through
`examples/boards charuco`; OpenCV's `CharucoDetector.detectBoard` with its defaults. Printed:
corners found of those in the frame, the median and 95th percentile error, ids wrong, and the
time per image taking turns (medians). Exits 1 when ours finds fewer corners than OpenCV's on a
set or errs more (median), or reads a wrong id.

    python3 scripts/eval_charuco.py BOARDS_BINARY OUT_DIR
"""
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np

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


def main():
    binary, out = sys.argv[1], Path(sys.argv[2])
    failures = []
    print("\nChArUco corners: ours against OpenCV's CharucoDetector on OpenCV's printed boards "
          "(generateImage) photographed through each lens; errors in px")
    print(f"{'set':24} {'who':7} {'found':>9} {'median':>7} {'p95':>7} {'wrong id':>8} {'ms/img':>7}")
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
        results = {"ours": {}, "opencv": {}}
        times = {"ours": [], "opencv": []}
        for _ in range(3):  # taking turns; the per-image medians over the rounds
            run = subprocess.run([binary, "charuco", str(folder)], check=True, capture_output=True)
            got = json.loads(run.stdout)
            results["ours"] = {f: (np.array(v["ids"], int), np.array(v["points"]).reshape(-1, 2))
                               for f, v in got.items()}
            times["ours"].append(sum(v["ms"] for v in got.values()) / len(got))
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
        for who in ("ours", "opencv"):
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
            print(f"{name:24} {who:7} {found:4}/{shown:<4} {med:7.3f} {p95:7.3f} {wrong:8d} "
                  f"{statistics.median(times[who]):7.1f}")
        (fo, mo, wo), (fc, mc, _) = summary["ours"], summary["opencv"]
        if fo < fc:
            failures.append(f"{name}: ours found {fo} corners, OpenCV {fc}")
        if mo > mc:
            failures.append(f"{name}: our median error {mo:.3f} px above OpenCV's {mc:.3f}")
        if wo:
            failures.append(f"{name}: {wo} corners of ours more than 3 px off (a wrong id)")
    if failures:
        print("\nFAILED:\n  " + "\n  ".join(failures))
        sys.exit(1)
    print("ChArUco goals met")


if __name__ == "__main__":
    main()
