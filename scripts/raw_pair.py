"""Makes a rectified pair raw, as a stereo camera would deliver it, through a calibration
chosen here and OpenCV's own transforms; writes the raw frames and that calibration as a
stereoCalibrate FileStorage (M1 D1 M2 D2 R T with R1 R2 P1 P2 Q and imageSize).

    python3 scripts/raw_pair.py LEFT RIGHT F CX CY DOFFS BASELINE OUT_DIR

The rectified cameras are the pair's own (f, cx, cy, cx + doffs, the baseline in mm); the raw
cameras have k1 -0.2 (and -0.18), their own principal points and focal lengths, and are
turned 1.2 to 1.8 degrees from the rectified ones. Each raw pixel takes the rectified image
where `cv2.undistortPointsIter` (to convergence) sends it, read with Lanczos.
"""
import sys

import cv2
import numpy as np


def main():
    left_path, right_path = sys.argv[1], sys.argv[2]
    f, cx, cy, doffs, baseline = map(float, sys.argv[3:8])
    out = sys.argv[8]
    left, right = cv2.imread(left_path), cv2.imread(right_path)
    h, w = left.shape[:2]
    # The rectified cameras: the pair's.
    P1 = np.array([[f, 0, cx, 0], [0, f, cy, 0], [0, 0, 1, 0]])
    P2 = np.array([[f, 0, cx + doffs, -f * baseline], [0, f, cy, 0], [0, 0, 1, 0]])
    # The raw cameras, and their rotations to the rectified ones.
    K1 = np.array([[f * 1.02, 0, w / 2 + 7.3], [0, f * 1.021, h / 2 - 4.1], [0, 0, 1]])
    K2 = np.array([[f * 1.015, 0, w / 2 - 5.2], [0, f * 1.014, h / 2 + 3.6], [0, 0, 1]])
    D1 = np.array([-0.2, 0.06, 0.0008, -0.0005, -0.01])
    D2 = np.array([-0.18, 0.05, -0.0006, 0.0007, -0.008])
    R1 = cv2.Rodrigues(np.radians([0.9, -1.2, 0.4]))[0]
    R2 = cv2.Rodrigues(np.radians([-0.7, 1.5, -0.5]))[0]
    # The pose these imply: X_right = R X_left + T.
    R = R2.T @ R1
    T = R2.T @ np.array([-baseline, 0.0, 0.0])
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    grid = np.stack(np.meshgrid(np.arange(w), np.arange(h)), -1).reshape(-1, 1, 2).astype(np.float64)
    for name, img, K, D, Rk, P in (("left", left, K1, D1, R1, P1), ("right", right, K2, D2, R2, P2)):
        rect = cv2.undistortPointsIter(grid, K, D, Rk, P[:, :3], crit).reshape(h, w, 2)
        raw = cv2.remap(img, rect[..., 0].astype(np.float32), rect[..., 1].astype(np.float32),
                        cv2.INTER_LANCZOS4, borderMode=cv2.BORDER_CONSTANT)
        cv2.imwrite(f"{out}/raw_{name}.png", raw)
    Q = np.array([[1, 0, 0, -cx], [0, 1, 0, -cy], [0, 0, 0, f], [0, 0, 1 / baseline, doffs / baseline]])
    fs = cv2.FileStorage(f"{out}/stereo_calibration.yml", cv2.FILE_STORAGE_WRITE)
    for key, value in (("M1", K1), ("D1", D1.reshape(1, 5)), ("M2", K2), ("D2", D2.reshape(1, 5)),
                       ("R", R), ("T", T.reshape(3, 1)), ("R1", R1), ("R2", R2), ("P1", P1),
                       ("P2", P2), ("Q", Q)):
        fs.write(key, value)
    fs.release()
    # FileStorage has no [w, h] list writer; the service reads imageSize as one.
    with open(f"{out}/stereo_calibration.yml", "a") as fh:
        fh.write(f"imageSize: [ {w}, {h} ]\n")


if __name__ == "__main__":
    main()
