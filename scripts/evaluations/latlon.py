"""Issue 96: latitude-longitude rectification (`/rectify?projection=latlon`) beside mrcal 2.2
and against exact geometry, in one run.

- mrcal: a 120-degree rational lens pair (`rational_polynomial`, mrcal's LENSMODEL_OPENCV8)
  as a stereoCalibrate file. Our summary's field (az0, el0, az_fov, el_fov) and resolution
  are given to mrcal.rectified_system; its rectified size, fx fy cx cy and rotations against
  ours, and mrcal.rectification_maps against our maps.npz (the largest difference over the
  pixels both read inside the raw frame). mrcal's own default resolution (pixels_per_deg -1)
  at our field's centre against ours. Ranges: our summary's system through mrcal.stereo_range
  against the true range of points of the scene (ours are in the engine's unit tests; the
  depth path comes in a later step).
- Exact geometry, for the fisheyes mrcal has no model of (equidistant, OpenCV's fisheye
  k1-k4) at 150 and 180 degrees, and for the rational lens: points in every direction of the
  field at 0.5, 3 and 40 m are projected into both raw images by this file's own numpy model
  of the lens (independent of the service's), then found in our rectified pair through our
  maps (inverted by Newton on the bilinear map). Rows must agree (RMS, and the share within
  0.1 px), and the range from the disparity (law of sines) must be the point's.
- The field: the share of the overlapping field (the directions both raw cameras see, an
  even spread over the sphere) that lands inside both rectified images, latlon beside the
  pinhole rectification at alpha 0 and 1 of the same rig.

Exit 1 when a floor is missed: maps within 0.05 px of mrcal's, sizes and rotations equal,
mrcal's range of our system within 1e-6 of the truth, rows within 0.1 px RMS, disparities
within 0.01 px of the truth (the maps are float32: a range at 40 m moves by 1e-3 with it) and
ranges within 1e-5 (median), latlon keeping at least 90 % of the overlapping field. Runs under Debian's python3 (mrcal and its numpy) with the standard library.

    PYTHONPATH=scripts /usr/bin/python3 -m evaluations.latlon --url URL [--json FILE]
"""
import argparse
import io
import json
import struct
import sys
import urllib.parse
import zlib

import numpy as np

from . import service

SIZE = (1280, 960)

RIGS = {
    # f = 581 px over 1280 px sees 120 degrees across with these coefficients (whose mapping
    # rises everywhere: no fold, so each pixel has one ray).
    "rational-120": dict(
        model="rational_polynomial",
        K1=[581.0, 580.0, 641.5, 478.0],
        D1=[0.3, 0.01, 0.0005, -0.0003, 0.0, 0.65, 0.02, 0.0],
        K2=[583.0, 582.5, 637.0, 482.5],
        D2=[0.28, 0.009, -0.0004, 0.0002, 0.0, 0.62, 0.018, 0.0],
        rvec=[0.006, -0.02, 0.004], T=[-120.0, 1.1, -1.6]),
    # Equidistant: theta_d = 0.5 * 1280 / f at the image's edge; 150 degrees across.
    "equidistant-150": dict(
        model="equidistant",
        K1=[490.0, 489.5, 640.5, 479.0],
        D1=[-0.01, 0.002, -0.0004, 0.00005],
        K2=[492.0, 491.0, 638.0, 481.5],
        D2=[-0.009, 0.0018, -0.0003, 0.00004],
        rvec=[0.008, -0.015, 0.004], T=[-95.0, 0.8, -1.1]),
    # 180 degrees across the 1280 px (theta = 90 degrees at 640 px: f = 407 px).
    "equidistant-180": dict(
        model="equidistant",
        K1=[407.4, 407.0, 639.5, 480.5],
        D1=[0.01, -0.002, 0.0005, -0.0001],
        K2=[405.0, 405.5, 641.0, 478.5],
        D2=[0.008, -0.001, 0.0002, 0.0],
        rvec=[0.01, -0.03, 0.008], T=[-120.0, 1.5, -2.0]),
}


def rodrigues(rvec):
    r = np.asarray(rvec, dtype=float)
    theta = np.linalg.norm(r)
    if theta < 1e-15:
        return np.eye(3)
    k = r / theta
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(theta) * kx + (1 - np.cos(theta)) * kx @ kx


def yml(rig):
    """The stereoCalibrate file of `rig`, as OpenCV's FileStorage writes it."""
    def mat(name, rows, cols, values):
        data = ", ".join(repr(float(v)) for v in values)
        return (f"{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n"
                f"   data: [ {data} ]\n")
    k = lambda c: [c[0], 0, c[2], 0, c[1], c[3], 0, 0, 1]
    r = rodrigues(rig["rvec"]).ravel()
    return ("%YAML:1.0\n---\n" + f"imageSize: [ {SIZE[0]}, {SIZE[1]} ]\n"
            + f"distortionModel: {rig['model']}\n"
            + mat("M1", 3, 3, k(rig["K1"])) + mat("D1", 1, len(rig["D1"]), rig["D1"])
            + mat("M2", 3, 3, k(rig["K2"])) + mat("D2", 1, len(rig["D2"]), rig["D2"])
            + mat("R", 3, 3, r) + mat("T", 3, 1, rig["T"]))


def png_grey(width, height, value=128):
    """A grey PNG (the frames /rectify needs for their size; the maps do not read them)."""
    raw = b"".join(b"\x00" + bytes([value]) * width for _ in range(height))
    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


FRAME = None


def rectify(url, rig, query):
    global FRAME
    FRAME = FRAME or png_grey(*SIZE)
    return service.post_once(url, "/rectify?" + urllib.parse.urlencode(query), {
        "left": (FRAME, "left.png", "image/png"),
        "right": (FRAME, "right.png", "image/png"),
        "calibration": (yml(rig).encode(), "calib.yml", "text/yaml"),
        "calibration_unit": (b"mm", None, "text/plain"),
    })


# --- this file's own lens models (OpenCV's formulas), for the truth ---------------------------

def project(rig, side, points):
    """Pixels of camera `side` (0 left, 1 right) of points (N, 3) in its own frame; NaN where
    the lens does not see them."""
    fx, fy, cx, cy = rig["K1" if side == 0 else "K2"]
    d = np.asarray(rig["D1" if side == 0 else "D2"], dtype=float)
    x, y, z = points[:, 0], points[:, 1], points[:, 2]
    if rig["model"] == "equidistant":
        r = np.hypot(x, y)
        theta = np.arctan2(r, z)
        t2 = theta * theta
        theta_d = theta * (1 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3]))))
        scale = np.where(r > 0, theta_d / np.where(r > 0, r, 1), 0)
        u, v = x * scale, y * scale
        bad = theta >= np.pi - 1e-9
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            a, b = x / z, y / z
        r2 = a * a + b * b
        k1, k2, p1, p2, k3, k4, k5, k6 = d
        radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
        u = a * radial + 2 * p1 * a * b + p2 * (r2 + 2 * a * a)
        v = b * radial + p1 * (r2 + 2 * b * b) + 2 * p2 * a * b
        bad = z <= 1e-9
    px = np.stack([fx * u + cx, fy * v + cy], axis=1)
    px[bad] = np.nan
    return px


def ray_of(az, el):
    return np.stack([np.sin(az), np.cos(az) * np.sin(el), np.cos(az) * np.cos(el)], axis=-1)


def bilinear(map_xy, u, v):
    h, w = map_xy.shape[:2]
    u0 = np.clip(np.floor(u).astype(int), 0, w - 2)
    v0 = np.clip(np.floor(v).astype(int), 0, h - 2)
    fu, fv = u - u0, v - v0
    m = lambda dv, du: map_xy[v0 + dv, u0 + du]
    return ((1 - fu)[..., None] * (1 - fv)[..., None] * m(0, 0) + fu[..., None] * (1 - fv)[..., None] * m(0, 1)
            + (1 - fu)[..., None] * fv[..., None] * m(1, 0) + fu[..., None] * fv[..., None] * m(1, 1))


def invert(map_xy, target, guess_row):
    """The rectified pixel (u, v) whose map value is `target` (a raw pixel), searched near row
    `guess_row`, refined by Newton on the bilinear map; None when not found."""
    h, w = map_xy.shape[:2]
    lo, hi = max(0, int(guess_row) - 6), min(h, int(guess_row) + 7)
    band = map_xy[lo:hi]
    dist = np.nansum((band - target) ** 2, axis=-1)
    dist[~np.isfinite(band).all(axis=-1)] = np.inf
    k = np.argmin(dist)
    if not np.isfinite(dist.flat[k]):
        return None
    v, u = np.unravel_index(k, dist.shape)
    q = np.array([float(u), float(v + lo)])
    for _ in range(6):
        if not (0 <= q[0] <= w - 2 and 0 <= q[1] <= h - 2):
            return None
        at = bilinear(map_xy, np.array([q[0]]), np.array([q[1]]))[0]
        e = 1e-3
        jx = (bilinear(map_xy, np.array([q[0] + e]), np.array([q[1]]))[0] - at) / e
        jy = (bilinear(map_xy, np.array([q[0]]), np.array([q[1] + e]))[0] - at) / e
        jac = np.stack([jx, jy], axis=1)
        if not np.all(np.isfinite(jac)) or abs(np.linalg.det(jac)) < 1e-12:
            return None
        q = q + np.linalg.solve(jac, target - at)
    return q


def geometry(rig, system, maps):
    """Rows and ranges of points over the whole field, found through our maps."""
    r1, r2 = np.array(system["r1"]).reshape(3, 3), np.array(system["r2"]).reshape(3, 3)
    rot = rodrigues(rig["rvec"])
    t = np.array(rig["T"], dtype=float)
    fx, cx, fy, cy = system["fx"], system["cx"], system["fy"], system["cy"]
    w, h = maps["left"].shape[1], maps["left"].shape[0]
    rows, ranges, disparities, tried = [], [], [], 0
    for v in np.linspace(2, h - 3, 15):
        for u in np.linspace(2, w - 3, 25):
            az, el = (u - cx) / fx, (v - cy) / fy
            for metres in (0.5, 3.0, 40.0):
                tried += 1
                p_rect = ray_of(az, el) * metres * 1000.0
                p_left = r1.T @ p_rect
                p_right = rot @ p_left + t
                raw_l = project(rig, 0, p_left[None])[0]
                raw_r = project(rig, 1, p_right[None])[0]
                inside = lambda p: np.all(np.isfinite(p)) and 0 <= p[0] <= SIZE[0] - 1 and 0 <= p[1] <= SIZE[1] - 1
                if not (inside(raw_l) and inside(raw_r)):
                    continue
                ql = invert(maps["left"], raw_l, v)
                qr = invert(maps["right"], raw_r, v)
                if ql is None or qr is None:
                    continue
                rows.append(qr[1] - ql[1])
                d = ql[0] - qr[0]
                true_l, true_r = r1 @ p_left, r2 @ p_right
                az_l = np.arctan2(true_l[0], np.hypot(true_l[1], true_l[2]))
                az_r = np.arctan2(true_r[0], np.hypot(true_r[1], true_r[2]))
                disparities.append(d - fx * (az_l - az_r))
                a = (ql[0] - cx) / fx
                angle = d / fx
                rng = system["baseline"] * np.cos(a - angle) / np.sin(angle)
                ranges.append(rng / np.linalg.norm(p_left) - 1)
    rows, ranges, disparities = np.array(rows), np.array(ranges), np.array(disparities)
    return dict(points=len(rows), tried=tried,
                disparity_max_px=float(np.max(np.abs(disparities))),
                rows_rms_px=float(np.sqrt(np.mean(rows ** 2))),
                rows_within_0_1=float(np.mean(np.abs(rows) <= 0.1)),
                rows_max_px=float(np.max(np.abs(rows))),
                range_rel_max=float(np.max(np.abs(ranges))),
                range_rel_median=float(np.median(np.abs(ranges))))


def our_maps(url, rig, query):
    npz = np.load(io.BytesIO(rectify(url, rig, {**query, "output": "maps.npz"})))
    return {side: np.stack([npz[f"{side}_map_x"], npz[f"{side}_map_y"]], axis=-1)
            for side in ("left", "right")}


def beside_mrcal(rig, system, maps):
    import mrcal

    def model(side):
        k = rig["K1" if side == 0 else "K2"]
        d = rig["D1" if side == 0 else "D2"]
        rt = np.zeros((4, 3))
        rt[:3] = np.eye(3) if side == 0 else rodrigues(rig["rvec"])
        rt[3] = 0 if side == 0 else np.array(rig["T"], dtype=float)
        return mrcal.cameramodel(intrinsics=("LENSMODEL_OPENCV8", np.r_[k, d]),
                                 imagersize=SIZE, extrinsics_Rt_fromref=rt)
    models = [model(0), model(1)]
    rect, meta = mrcal.rectified_system(
        models, az_fov_deg=system["az_fov_deg"], el_fov_deg=system["el_fov_deg"],
        az0_deg=system["az0_deg"], el0_deg=system["el0_deg"],
        pixels_per_deg_az=system["pixels_per_degree_az"],
        pixels_per_deg_el=system["pixels_per_degree_el"], return_metadata=True)
    _, default = mrcal.rectified_system(
        models, az_fov_deg=system["az_fov_deg"], el_fov_deg=system["el_fov_deg"],
        az0_deg=system["az0_deg"], el0_deg=system["el0_deg"], return_metadata=True)
    theirs = mrcal.rectification_maps(models, rect)
    ours = [maps["left"], maps["right"]]
    size_equal = tuple(rect[0].imagersize()) == (ours[0].shape[1], ours[0].shape[0])
    out = dict(size_ours=[ours[0].shape[1], ours[0].shape[0]],
               size_mrcal=[int(v) for v in rect[0].imagersize()], size_equal=size_equal)
    fxycxy = rect[0].intrinsics()[1]
    out["fxycxy_diff"] = float(np.max(np.abs(
        fxycxy - np.array([system["fx"], system["fy"], system["cx"], system["cy"]]))))
    r_rect0 = rect[0].extrinsics_Rt_fromref()[:3]
    r_rect1 = rect[1].extrinsics_Rt_fromref()[:3] @ models[1].extrinsics_Rt_toref()[:3]
    out["rotation_diff"] = float(max(
        np.max(np.abs(r_rect0 - np.array(system["r1"]).reshape(3, 3))),
        np.max(np.abs(r_rect1 - np.array(system["r2"]).reshape(3, 3)))))
    out["resolution_rel_diff"] = float(max(
        abs(default["pixels_per_deg_az"] / system["pixels_per_degree_az"] - 1),
        abs(default["pixels_per_deg_el"] / system["pixels_per_degree_el"] - 1)))
    if size_equal:
        worst = 0.0
        for o, m in zip(ours, theirs):
            inside = (np.isfinite(o).all(axis=-1) & (m[..., 0] >= 0) & (m[..., 0] <= SIZE[0] - 1)
                      & (m[..., 1] >= 0) & (m[..., 1] <= SIZE[1] - 1))
            worst = max(worst, float(np.max(np.abs(o[inside] - m[inside]))))
        out["maps_max_diff_px"] = worst
    # mrcal's stereo_range on disparities of true points, against the truth.
    w = rect[0].imagersize()[0]
    qx = np.linspace(0.1 * w, 0.9 * w, 9)
    az = (qx - system["cx"]) / system["fx"]
    worst = 0.0
    for metres in (0.5, 3.0, 40.0):
        p = ray_of(az, np.zeros_like(az)) * metres * 1000
        right = p - np.array([system["baseline"], 0, 0])
        az1 = np.arctan2(right[:, 0], np.hypot(right[:, 1], right[:, 2]))
        disparity = (az - az1) * system["fx"]
        r = mrcal.stereo_range(disparity, rect, qrect0=np.stack([qx, np.zeros_like(qx)], axis=1))
        worst = max(worst, float(np.max(np.abs(r / (metres * 1000) - 1))))
    out["mrcal_range_rel_diff"] = worst
    return out


def overlap_directions(rig, count=40000):
    """Directions (left camera frame, unit) both raw cameras see, from an even spread over
    the sphere (a Fibonacci lattice), taken far away (the right ray is R times the left)."""
    k = np.arange(count) + 0.5
    z = 1 - 2 * k / count
    phi = np.pi * (1 + 5 ** 0.5) * k
    v = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], axis=1)
    inside = lambda p: np.isfinite(p).all(axis=1) & (p[:, 0] >= 0) & (p[:, 0] <= SIZE[0] - 1) \
        & (p[:, 1] >= 0) & (p[:, 1] <= SIZE[1] - 1)
    seen = inside(project(rig, 0, v)) & inside(project(rig, 1, v @ rodrigues(rig["rvec"]).T))
    return v[seen]


def field_shares(url, rig):
    """The share of the overlapping field (the directions both raw cameras see) that lands
    inside both rectified images, for latlon and the pinhole plane at alpha 0 and 1, and the
    share of each rectified image read from inside the raw frames."""
    v = overlap_directions(rig)
    rot = rodrigues(rig["rvec"])
    out = {}
    for name, query in [("latlon", {"projection": "latlon"}), ("pinhole alpha 0", {"alpha": 0}),
                        ("pinhole alpha 1", {"alpha": 1})]:
        summary = json.loads(rectify(url, rig, {**query, "output": "summary"}))
        w, h = summary["width"], summary["height"]
        kept = np.ones(len(v), dtype=bool)
        for side in (0, 1):
            rays = v if side == 0 else v @ rot.T
            if summary["projection"] == "latlon":
                s = summary["latlon"]
                r = np.array(s["r1" if side == 0 else "r2"]).reshape(3, 3)
                q = rays @ r.T
                az = np.arctan2(q[:, 0], np.hypot(q[:, 1], q[:, 2]))
                el = np.arctan2(q[:, 1], q[:, 2])
                px = np.stack([s["fx"] * az + s["cx"], s["fy"] * el + s["cy"]], axis=1)
            else:
                raw = summary["raw"]
                r = np.array(raw["R1" if side == 0 else "R2"])
                p = np.array(raw["P1" if side == 0 else "P2"])[:, :3]
                q = rays @ (p @ r).T
                with np.errstate(divide="ignore", invalid="ignore"):
                    px = q[:, :2] / q[:, 2:3]
                px[q[:, 2] <= 1e-9] = np.nan
            kept &= np.isfinite(px).all(axis=1) & (px[:, 0] >= 0) & (px[:, 0] <= w - 1) \
                & (px[:, 1] >= 0) & (px[:, 1] <= h - 1)
        out[name] = dict(field_share=float(kept.mean()), size=[w, h],
                         valid_left=summary["valid_fraction"]["left"],
                         valid_right=summary["valid_fraction"]["right"])
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--url", required=True)
    parser.add_argument("--json")
    args = parser.parse_args()
    report, failures = {}, []
    for name, rig in RIGS.items():
        query = {"projection": "latlon"}
        system = json.loads(rectify(args.url, rig, {**query, "output": "summary"}))["latlon"]
        maps = our_maps(args.url, rig, query)
        entry = dict(system={k: system[k] for k in ("az0_deg", "el0_deg", "az_fov_deg",
                                                   "el_fov_deg", "pixels_per_degree_az",
                                                   "pixels_per_degree_el")},
                     size=[maps["left"].shape[1], maps["left"].shape[0]])
        entry["truth"] = geometry(rig, system, maps)
        entry["field"] = field_shares(args.url, rig)
        truth = entry["truth"]
        print(f"{name}: latlon {entry['size'][0]} x {entry['size'][1]}, az {system['az_fov_deg']:.1f} deg "
              f"x el {system['el_fov_deg']:.1f} deg at {system['pixels_per_degree_az']:.2f} px/deg; "
              f"{truth['points']} of {truth['tried']} points seen by both: rows {truth['rows_rms_px']:.4f} px "
              f"RMS (max {truth['rows_max_px']:.4f}, {100 * truth['rows_within_0_1']:.1f} % within 0.1), "
              f"disparity within {truth['disparity_max_px']:.4f} px, so the range within "
              f"{truth['range_rel_median']:.1e} (median) and {truth['range_rel_max']:.1e} (max, at 40 m)")
        for k, v in entry["field"].items():
            print(f"    {k:16} {v['size'][0]} x {v['size'][1]}: {100 * v['field_share']:.1f} % of the "
                  f"overlapping field rectified; valid pixels left {v['valid_left']:.3f}, right {v['valid_right']:.3f}")
        if entry["field"]["latlon"]["field_share"] < 0.9:
            failures.append(f"{name}: latlon keeps {entry['field']['latlon']['field_share']:.3f} of the field < 0.9")
        if truth["points"] < 100:
            failures.append(f"{name}: only {truth['points']} points found")
        if truth["rows_rms_px"] > 0.1:
            failures.append(f"{name}: rows {truth['rows_rms_px']:.4f} px RMS > 0.1")
        if truth["disparity_max_px"] > 0.01:
            failures.append(f"{name}: disparity off by {truth['disparity_max_px']:.4f} px > 0.01")
        if truth["range_rel_median"] > 1e-5:
            failures.append(f"{name}: range off by {truth['range_rel_median']:.2e} > 1e-5 (median)")
        if rig["model"] == "rational_polynomial":
            m = beside_mrcal(rig, system, maps)
            entry["mrcal"] = m
            print(f"    mrcal 2.2: size {m['size_mrcal']} (ours {m['size_ours']}), fx fy cx cy within "
                  f"{m['fxycxy_diff']:.2e}, rotations within {m['rotation_diff']:.2e}, maps within "
                  f"{m.get('maps_max_diff_px', float('nan')):.4f} px, default resolution within "
                  f"{m['resolution_rel_diff']:.2e}; stereo_range on true disparities within "
                  f"{m['mrcal_range_rel_diff']:.2e}")
            if not m["size_equal"]:
                failures.append(f"{name}: size {m['size_ours']} against mrcal's {m['size_mrcal']}")
            elif m["maps_max_diff_px"] > 0.05:
                failures.append(f"{name}: maps {m['maps_max_diff_px']:.4f} px from mrcal's > 0.05")
            if m["rotation_diff"] > 1e-9 or m["fxycxy_diff"] > 1e-6:
                failures.append(f"{name}: the system differs from mrcal's")
            if m["resolution_rel_diff"] > 1e-4:
                failures.append(f"{name}: resolution {m['resolution_rel_diff']:.2e} from mrcal's default")
            if m["mrcal_range_rel_diff"] > 1e-6:
                failures.append(f"{name}: mrcal's range of our system off by {m['mrcal_range_rel_diff']:.2e}")
        report[name] = entry
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=1)
    for f in failures:
        print("FLOOR MISSED:", f)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
