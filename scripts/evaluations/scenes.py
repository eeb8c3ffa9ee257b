"""The scenes the matcher evaluations share: Middlebury 2014 Motorcycle's rig at quarter size and
its disparity count, its radiometric variants, a rendered slanted scene with exact truth, and
Middlebury 2006 Aloe (data/fetch-aloe).
"""

import cv2
import numpy as np


# Motorcycle at quarter size: the rig of its calib.txt with f, cx, cy and doffs divided by 4.
RIG = {
    "focal_length_px": 3979.911 / 4,
    "baseline": 193.001,
    "unit": "mm",
    "cx": 1244.772 / 4,
    "cy": 1019.507 / 4,
    "doffs": 124.343 / 4,
}


NUM_DISPARITIES = 64


def variants(left, right):
    """The pair, and two radiometric changes nothing was tuned on."""
    yield "motorcycle", left, right
    darker = np.clip(right.astype(np.float32) * 0.75 + 18, 0, 255).astype(np.uint8)
    yield "gain", left, darker
    rng = np.random.default_rng(7)
    noisy = [
        np.clip(img.astype(np.float32) + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)
        for img in (left, right)
    ]
    yield "noise", noisy[0], noisy[1]


def texture(u, v, seed):
    """A band-limited colour texture at surface coordinates (u, v): per channel a sum of plane
    waves below 0.3 cycles a pixel, in 0..255."""
    rng = np.random.default_rng(seed)
    out = np.zeros(u.shape + (3,), np.float32)
    for c in range(3):
        for _ in range(24):
            f = rng.uniform(0.01, 0.3)
            a = rng.uniform(0, np.pi)
            out[..., c] += np.sin(2 * np.pi * f * (np.cos(a) * u + np.sin(a) * v)
                                  + rng.uniform(0, 2 * np.pi))
    out = 127.5 + 127.5 * out / np.abs(out).max()
    return out


def slanted_scene(width=640, height=480):
    """A scene no parameter was tuned on, with exact truth: a slanted background plane and a
    slanted box in front of it, each with its own colour texture and a smooth shading, seen by
    two rectified cameras. Returns left, right (BGR uint8) and the left's true disparities."""
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    # Surfaces: d = a + b * x + c * y (x in the left image), region in the left image, seed.
    surfaces = [((6.0, 24.0 / width, 8.0 / height), None, 11),
                ((34.0, 10.0 / width, -4.0 / height), (0.3, 0.25, 0.7, 0.8), 12)]

    def render(right):
        image = np.zeros((height, width, 3), np.float32)
        depth = np.full((height, width), -np.inf, np.float32)
        for (a, b, c), region, seed in surfaces:
            # The left x this pixel sees on the surface: itself, or solved from xr = x - d(x).
            xl = (xs + a + c * ys) / (1 - b) if right else xs
            d = a + b * xl + c * ys
            inside = np.ones_like(xs, bool)
            if region:
                x0, y0, x1, y1 = region
                inside = (xl >= x0 * width) & (xl < x1 * width) & (ys >= y0 * height) \
                    & (ys < y1 * height)
            nearer = inside & (d > depth)
            shade = 0.75 + 0.25 * np.cos(xl / width * 3 + ys / height * 2)[..., None]
            colour = texture(xl, ys, seed) * shade
            image[nearer] = colour[nearer]
            depth[nearer] = d[nearer]
        return image, depth

    left, truth = render(False)
    right, _ = render(True)
    return left, right, truth


def aloe(data, scale=2):
    """Middlebury 2006 Aloe (scripts/data/fetch-aloe), a real scene nothing was tuned on, at
    1/`scale` size: the left and right images (OpenCV's area resize) and the truth, each
    block's mean of the full size's disparities (integers) over `scale`, inf where any of the
    block is unknown. Returns left, right, truth and the disparities to search."""
    left = cv2.imread(f"{data}/aloeL.jpg")
    right = cv2.imread(f"{data}/aloeR.jpg")
    full = cv2.imread(f"{data}/aloeGT.png", cv2.IMREAD_UNCHANGED).astype(np.float32)
    h, w = full.shape[0] // scale, full.shape[1] // scale
    small = lambda img: cv2.resize(img, None, fx=1 / scale, fy=1 / scale,
                                   interpolation=cv2.INTER_AREA)[:h, :w]
    blocks = full[: h * scale, : w * scale].reshape(h, scale, w, scale)
    truth = blocks.mean(axis=(1, 3)) / scale
    truth[(blocks == 0).any(axis=(1, 3))] = np.inf
    disparities = int(np.ceil((truth[np.isfinite(truth)].max() + 1) / 16) * 16)
    return small(left), small(right), truth, disparities
