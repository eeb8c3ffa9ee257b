"""The truth a photographed board carries in a rectified pair (issue 68): its inner corners found
in both images (OpenCV's findChessboardCorners + cornerSubPix) and the plane their disparities
fit, d = a*x + b*y + c, over the board's corner grid extended by half a square. Shared by
board.py (scores against it) and indoor.py (each pair's range, and who is right where
two maps disagree)."""
import math

import cv2
import numpy as np

PATTERN = (9, 6)  # inner corners of the photographed board


def corners(image):
    """The board's inner corners in `image` (N x 2, OpenCV's order), or None."""
    found, pts = cv2.findChessboardCorners(
        image, PATTERN, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not found:
        return None
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-3)
    pts = cv2.cornerSubPix(image, pts, (5, 5), (-1, -1), criteria)
    return pts.reshape(-1, 2).astype(np.float64)


def board_truth(left, right):
    """The board's truth in a rectified pair: (mask of the board's pixels, the plane's disparity
    over the image, the fit's RMS over the corners in px, the corners' row disagreement's median
    in px), or None when the board is not found in both images."""
    cl, cr = corners(left), corners(right)
    if cl is None or cr is None:
        return None
    # The order may start from the opposite corner in one image: take the one whose rows agree.
    if np.median(np.abs(cl[:, 1] - cr[::-1, 1])) < np.median(np.abs(cl[:, 1] - cr[:, 1])):
        cr = cr[::-1]
    d = cl[:, 0] - cr[:, 0]
    a = np.column_stack([cl[:, 0], cl[:, 1], np.ones(len(cl))])
    plane, *_ = np.linalg.lstsq(a, d, rcond=None)
    rms = float(np.sqrt(np.mean((a @ plane - d) ** 2)))
    rows = float(np.median(np.abs(cl[:, 1] - cr[:, 1])))
    cols, nrows = PATTERN
    grid = np.array([(i, j) for j in range(nrows) for i in range(cols)], np.float64)
    h, _ = cv2.findHomography(grid, cl, 0)
    outline = np.array([[-0.5, -0.5], [cols - 0.5, -0.5], [cols - 0.5, nrows - 0.5],
                        [-0.5, nrows - 0.5]], np.float64).reshape(-1, 1, 2)
    polygon = cv2.perspectiveTransform(outline, h).reshape(-1, 2)
    mask = np.zeros(left.shape, np.uint8)
    cv2.fillPoly(mask, [np.round(polygon * 16).astype(np.int32)], 1, shift=4)
    ys, xs = np.mgrid[0:left.shape[0], 0:left.shape[1]]
    truth = (plane[0] * xs + plane[1] * ys + plane[2]).astype(np.float32)
    return mask.astype(bool), truth, rms, rows


def search_range(truth, mask):
    """The disparities searched: past the board's largest by at least 8 px, a multiple of 16."""
    return int(math.ceil((float(truth[mask].max()) + 8) / 16) * 16)
