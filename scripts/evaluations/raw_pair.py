"""Makes a rectified pair raw, as a stereo camera would deliver it, through a calibration
chosen here and OpenCV's own transforms; writes the raw frames and that calibration as a
stereoCalibrate FileStorage (M1 D1 M2 D2 R T with R1 R2 P1 P2 Q and imageSize).

    PYTHONPATH=scripts python3 -m evaluations.raw_pair LEFT RIGHT F CX CY DOFFS BASELINE OUT_DIR [RIG]

The rectified cameras are the pair's own (f, cx, cy, cx + doffs, the baseline in mm). The raw
cameras (RIG 0, the default, to 3) have k1 around -0.2, their own principal points a few
pixels off the rectified ones, focal lengths 3 % shorter (so that the raw frames see all of
the rectified view, as stereoRectify with alpha 0 would make sure) and are turned 1 to 2
degrees from the rectified ones. Each raw pixel takes the rectified image where
`cv2.undistortPointsIter` (to convergence) sends it, read with Lanczos.
"""
import sys

import cv2
import numpy as np


RIGS = [
    # (left dx, dy, fx, fy scale, D1, rotation in degrees), then the right camera's.
    ((7.3, -4.1, 0.97, 0.971, [-0.2, 0.06, 0.0008, -0.0005, -0.01], [0.9, -1.2, 0.4]),
     (-5.2, 3.6, 0.965, 0.964, [-0.18, 0.05, -0.0006, 0.0007, -0.008], [-0.7, 1.5, -0.5])),
    ((-4.6, 6.2, 0.968, 0.9675, [-0.23, 0.08, -0.0011, 0.0004, -0.02], [-1.1, 0.8, -0.6]),
     (3.9, -5.5, 0.972, 0.9718, [-0.21, 0.07, 0.0009, -0.0008, -0.015], [1.3, -1.0, 0.7])),
    ((2.8, 3.3, 0.966, 0.9662, [-0.19, 0.045, 0.0004, 0.0009, -0.005], [0.3, 1.4, -0.9]),
     (-6.1, -2.4, 0.969, 0.9695, [-0.22, 0.075, -0.0007, -0.0003, -0.018], [-1.2, -0.6, 0.8])),
    ((-3.5, -5.8, 0.971, 0.9705, [-0.21, 0.055, -0.0005, 0.0006, -0.012], [1.6, 0.2, -0.3]),
     (5.6, 4.7, 0.967, 0.9664, [-0.2, 0.065, 0.0008, 0.0005, -0.009], [-0.4, -1.7, 0.5])),
]


def rig_maps(w, h, f, cx, cy, doffs, baseline, rig=0):
    """Where each raw pixel of RIGS[rig]'s two cameras (w x h) looks in the rectified pair
    (f, cx, cy, cx + doffs, baseline in mm): float32 maps for `cv2.remap`, one (x, y) pair per
    camera, and the calibration as the text of a stereoCalibrate FileStorage with imageSize."""
    # The rectified cameras: the pair's.
    P1 = np.array([[f, 0, cx, 0], [0, f, cy, 0], [0, 0, 1, 0]])
    P2 = np.array([[f, 0, cx + doffs, -f * baseline], [0, f, cy, 0], [0, 0, 1, 0]])
    # The raw cameras, and their rotations to the rectified ones.
    (l_dx, l_dy, l_fx, l_fy, D1, l_rot), (r_dx, r_dy, r_fx, r_fy, D2, r_rot) = RIGS[rig]
    K1 = np.array([[f * l_fx, 0, cx + l_dx], [0, f * l_fy, cy + l_dy], [0, 0, 1]])
    K2 = np.array([[f * r_fx, 0, cx + doffs + r_dx], [0, f * r_fy, cy + r_dy], [0, 0, 1]])
    D1, D2 = np.array(D1), np.array(D2)
    R1 = cv2.Rodrigues(np.radians(l_rot))[0]
    R2 = cv2.Rodrigues(np.radians(r_rot))[0]
    # The pose these imply: X_right = R X_left + T.
    R = R2.T @ R1
    T = R2.T @ np.array([-baseline, 0.0, 0.0])
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    grid = np.stack(np.meshgrid(np.arange(w), np.arange(h)), -1).reshape(-1, 1, 2).astype(np.float64)
    maps = []
    for K, D, Rk, P in ((K1, D1, R1, P1), (K2, D2, R2, P2)):
        rect = cv2.undistortPointsIter(grid, K, D, Rk, P[:, :3], crit).reshape(h, w, 2)
        maps.append((rect[..., 0].astype(np.float32), rect[..., 1].astype(np.float32)))
    Q = np.array([[1, 0, 0, -cx], [0, 1, 0, -cy], [0, 0, 0, f], [0, 0, 1 / baseline, doffs / baseline]])
    fs = cv2.FileStorage(".yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    for key, value in (("M1", K1), ("D1", D1.reshape(1, 5)), ("M2", K2), ("D2", D2.reshape(1, 5)),
                       ("R", R), ("T", T.reshape(3, 1)), ("R1", R1), ("R2", R2), ("P1", P1),
                       ("P2", P2), ("Q", Q)):
        fs.write(key, value)
    # FileStorage has no [w, h] list writer; the service reads imageSize as one.
    text = fs.releaseAndGetString() + f"imageSize: [ {w}, {h} ]\n"
    return maps[0], maps[1], text


def to_raw(image, rig_map):
    """A rectified image as the raw camera of `rig_map` (from `rig_maps`) sees it."""
    return cv2.remap(image, rig_map[0], rig_map[1], cv2.INTER_LANCZOS4,
                     borderMode=cv2.BORDER_CONSTANT)


def make_raw(left, right, f, cx, cy, doffs, baseline, rig=0):
    """The raw frames of the rectified pair (left, right) through RIGS[rig] and their
    calibration as the text of a stereoCalibrate FileStorage, with imageSize."""
    h, w = left.shape[:2]
    left_map, right_map, text = rig_maps(w, h, f, cx, cy, doffs, baseline, rig)
    return to_raw(left, left_map), to_raw(right, right_map), text


def main():
    left_path, right_path = sys.argv[1], sys.argv[2]
    f, cx, cy, doffs, baseline = map(float, sys.argv[3:8])
    out = sys.argv[8]
    rig = int(sys.argv[9]) if len(sys.argv) > 9 else 0
    raw_left, raw_right, text = make_raw(cv2.imread(left_path), cv2.imread(right_path),
                                         f, cx, cy, doffs, baseline, rig)
    cv2.imwrite(f"{out}/raw_left.png", raw_left)
    cv2.imwrite(f"{out}/raw_right.png", raw_right)
    with open(f"{out}/stereo_calibration.yml", "w") as fh:
        fh.write(text)


if __name__ == "__main__":
    main()
