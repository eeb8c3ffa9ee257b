"""Rectification against OpenCV 4.14 on the same calibrations and frames, in one run.

For plumb_bob, rational_polynomial and equidistant rigs (each a bare stereoCalibrate file:
K1 D1 K2 D2 R T and the image size) and alpha 0, 0.5 and 1:
- transforms: /calibration's R1 R2 P1 P2 Q and ROIs against cv2.stereoRectify
  (cv2.fisheye.stereoRectify with balance = alpha, which gives no ROIs), relative error
  max|ours - OpenCV| / max|OpenCV| per matrix;
- maps: /rectify?output=maps.npz against cv2.initUndistortRectifyMap (CV_32FC1) on OpenCV's
  own R and P, the largest difference over the pixels that read inside the raw frame;
- images: /rectify?output=left.png (linear) against cv2.remap(INTER_LINEAR) with OpenCV's
  maps, the mean absolute difference inside the valid ROI;
- speed: the remap stage of a 1280 x 720 pair with cached maps (/depth-map's own
  `timings_ms.rectify`, the remapping its matching needs) and cv2.remap of the same pair with
  2 threads, taking turns, medians of 7 (reported, never asserted);
- end to end: Middlebury Motorcycle (quarter size, from --data) made raw by
  scripts/evaluations/raw_pair.py through each of its four rigs (k1 around -0.2, the cameras turned 1 to 2
  degrees, OpenCV's own transforms); the raw pair and its stereoCalibrate file sent to /depth-map, against the same
  raw pair rectified by cv2.initUndistortRectifyMap + cv2.remap (linear) and sent as
  rectified: bad-1.0 and bad-2.0 against the ground truth (stereo.py's metric), and the
  whole requests' medians of 9, the two taking turns (reported, never asserted).
Exit 1 when a floor is missed: transforms 1e-6 relative (ROIs within 1 px), maps 0.01 px
(0.05 fisheye), images 1 grey level on average; end to end, bad-1.0 and bad-2.0 no worse than
OpenCV's rectification, as the mean over raw_pair's four rigs.
"""
import argparse
import http.client
import io
import json
import statistics
import sys
import time
import urllib.parse

import cv2
import numpy as np

from . import raw_pair, scenes, scoring, service

SIZE = (1280, 720)
RIGS = {
    "plumb_bob": dict(
        K1=[[980.0, 0, 652.3], [0, 978.5, 361.8], [0, 0, 1]],
        D1=[-0.21, 0.06, 0.0012, -0.0007, -0.008],
        K2=[[985.0, 0, 628.9], [0, 983.0, 355.2], [0, 0, 1]],
        D2=[-0.19, 0.045, -0.0006, 0.0009, -0.004],
        rvec=[0.012, -0.025, 0.008], T=[-119.5, 1.2, -2.1]),
    "rational_polynomial": dict(
        K1=[[910.0, 0, 640.5], [0, 909.0, 359.1], [0, 0, 1]],
        D1=[-0.27, 0.085, 0.0008, -0.0004, -0.011, 0.05, -0.012, 0.002],
        K2=[[915.0, 0, 637.2], [0, 914.0, 362.7], [0, 0, 1]],
        D2=[-0.25, 0.075, -0.0005, 0.0006, -0.009, 0.045, -0.01, 0.0018],
        rvec=[-0.01, 0.02, -0.006], T=[-64.8, -0.6, 1.3]),
    "equidistant": dict(
        K1=[[600.0, 0, 641.0], [0, 599.0, 358.0], [0, 0, 1]],
        D1=[-0.03, 0.006, -0.002, 0.0003],
        K2=[[602.0, 0, 636.0], [0, 601.5, 363.0], [0, 0, 1]],
        D2=[-0.028, 0.005, -0.0018, 0.00025],
        rvec=[0.008, -0.015, 0.004], T=[-95.0, 0.8, -1.1]),
}


def opencv_yml(rig, model):
    fs = cv2.FileStorage(".yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    fs.write("imageSize", np.array(SIZE, dtype=np.float64).reshape(1, 2))
    fs.write("distortionModel", model)
    fs.write("M1", np.array(rig["K1"]))
    fs.write("D1", np.array(rig["D1"]).reshape(1, -1))
    fs.write("M2", np.array(rig["K2"]))
    fs.write("D2", np.array(rig["D2"]).reshape(1, -1))
    fs.write("R", cv2.Rodrigues(np.array(rig["rvec"]))[0])
    fs.write("T", np.array(rig["T"]).reshape(3, 1))
    text = fs.releaseAndGetString()
    # FileStorage writes imageSize as a matrix; the service reads [w, h].
    return text.split("imageSize")[0] + f"imageSize: [ {SIZE[0]}, {SIZE[1]} ]\n" + \
        text.split("imageSize")[1].split("\n", 6)[-1] if False else text.replace(
            text[text.index("imageSize"):text.index("distortionModel")],
            f"imageSize: [ {SIZE[0]}, {SIZE[1]} ]\n")


def cv_rectify(rig, model, alpha):
    K1, K2 = np.array(rig["K1"]), np.array(rig["K2"])
    D1, D2 = np.array(rig["D1"]), np.array(rig["D2"])
    R = cv2.Rodrigues(np.array(rig["rvec"]))[0]
    T = np.array(rig["T"])
    if model == "equidistant":
        R1, R2, P1, P2, Q = cv2.fisheye.stereoRectify(
            K1, D1, K2, D2, SIZE, R, T, flags=cv2.CALIB_ZERO_DISPARITY, balance=alpha)
        rois = None
    else:
        R1, R2, P1, P2, Q, roi1, roi2 = cv2.stereoRectify(
            K1, D1, K2, D2, SIZE, R, T, flags=cv2.CALIB_ZERO_DISPARITY, alpha=alpha)
        rois = (list(roi1), list(roi2))
    return dict(R1=R1, R2=R2, P1=P1, P2=P2, Q=Q, rois=rois)


def cv_maps(rig, model, cv):
    out = []
    for k, (K, D, R, P) in enumerate([(rig["K1"], rig["D1"], cv["R1"], cv["P1"]),
                                      (rig["K2"], rig["D2"], cv["R2"], cv["P2"])]):
        K, D = np.array(K), np.array(D)
        if model == "equidistant":
            mx, my = cv2.fisheye.initUndistortRectifyMap(K, D, R, P, SIZE, cv2.CV_32FC1)
        else:
            mx, my = cv2.initUndistortRectifyMap(K, D, R, P, SIZE, cv2.CV_32FC1)
        out.append((mx, my))
    return out


def rectify(url, yml, left, right, query):
    return service.post_once(url, "/rectify?" + urllib.parse.urlencode(query), {
        "left": (left, "left.png", "image/png"),
        "right": (right, "right.png", "image/png"),
        "calibration": (yml.encode(), "calib.yml", "text/yaml"),
        "calibration_unit": (b"mm", None, "text/plain"),
    })


def texture(seed):
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (SIZE[1] // 8, SIZE[0] // 8), dtype=np.uint8)
    img = cv2.resize(small, SIZE, interpolation=cv2.INTER_CUBIC)
    img = cv2.GaussianBlur(img, (0, 0), 1.2)
    return img


def interleaved(url, path, requests, runs=9):
    """Sends each of `requests` (multipart parts, rig included where wanted) on its own
    kept-alive connection, taking turns (one of each per round, after a round to warm up), so
    that a slow spell of the machine falls on all of them alike. For each: the last answer,
    the median time in seconds, and the last Server-Timing header."""
    target = urllib.parse.urlsplit(url)
    conns, bodies, times = [], [], [[] for _ in requests]
    answers, timings = [None] * len(requests), [""] * len(requests)
    for parts in requests:
        conns.append(http.client.HTTPConnection(target.hostname, target.port, timeout=60))
        bodies.append(service.multipart(parts))
    for round_ in range(runs + 1):
        for k, (conn, (body, ctype)) in enumerate(zip(conns, bodies)):
            t = time.perf_counter()
            conn.request("POST", path, body=body, headers={"Content-Type": ctype})
            response = conn.getresponse()
            answers[k] = response.read()
            if response.status != 200:
                sys.exit(f"{path} answered {response.status}: {answers[k][:500]!r}")
            timings[k] = response.getheader("Server-Timing", "")
            if round_:
                times[k].append(time.perf_counter() - t)
    for conn in conns:
        conn.close()
    return list(zip(answers, (statistics.median(t) for t in times), timings))


def end_to_end(url, data):
    """Motorcycle made raw through each of raw_pair's rigs, rectified by us inside /depth-map
    and by OpenCV before it; and the original, never resampled."""
    left = cv2.imread(f"{data}/motorcycle_left.png")
    right = cv2.imread(f"{data}/motorcycle_right.png")
    truth = np.load(f"{data}/motorcycle_disp.npz")["arr_0"]
    rig = scenes.RIG
    f, cx, cy, doffs, b = (rig["focal_length_px"], rig["cx"], rig["cy"], rig["doffs"],
                           rig["baseline"])
    png = lambda img: cv2.imencode(".png", img)[1].tobytes()
    path = f"/depth-map?max_disparity={scenes.NUM_DISPARITIES}&output=disparity.npy"
    score = lambda answer: scoring.score(
        np.where(np.isnan(d := service.load_npy(answer)), np.inf, d), truth)
    answer, _, _ = service.post(url, path, {
        "left": (png(left), "left.png", "image/png"),
        "right": (png(right), "right.png", "image/png")}, scenes.RIG)
    out = dict(original=score(answer), rigs=[])
    size = (left.shape[1], left.shape[0])
    for i in range(len(raw_pair.RIGS)):
        raw_l, raw_r, yml = raw_pair.make_raw(left, right, f, cx, cy, doffs, b, i)
        # Ours: the raw pair and the file.
        raw_parts = {
            "left": (png(raw_l), "raw_left.png", "image/png"),
            "right": (png(raw_r), "raw_right.png", "image/png"),
            "calibration": (yml.encode(), "stereo_calibration.yml", "text/yaml"),
            "calibration_unit": (b"mm", None, "text/plain")}
        # OpenCV: the file's own transforms, initUndistortRectifyMap and remap (linear).
        fs = cv2.FileStorage(yml, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
        rectified = []
        for img, k, d, r, p in ((raw_l, "M1", "D1", "R1", "P1"), (raw_r, "M2", "D2", "R2", "P2")):
            mx, my = cv2.initUndistortRectifyMap(fs.getNode(k).mat(), fs.getNode(d).mat(),
                                                 fs.getNode(r).mat(), fs.getNode(p).mat(), size,
                                                 cv2.CV_32FC1)
            rectified.append(cv2.remap(img, mx, my, cv2.INTER_LINEAR))
        rectified_parts = {
            "left": (png(rectified[0]), "left.png", "image/png"),
            "right": (png(rectified[1]), "right.png", "image/png")}
        # The two whole requests, timed taking turns; the first round fills the map cache.
        rig_part = {"rig": (json.dumps(scenes.RIG).encode(), None, "application/json")}
        (answer, ours_s, timing), (cv_answer, cv_s, _) = interleaved(
            url, path, [raw_parts, {**rectified_parts, **rig_part}])
        out["rigs"].append(dict(ours_raw=score(answer), opencv_rectified=score(cv_answer),
                                ours_raw_ms=ours_s * 1e3, opencv_rectified_ms=cv_s * 1e3,
                                server_timing=timing))
    for key in ("ours_raw", "opencv_rectified"):
        out[key] = {m: statistics.mean(r[key][m] for r in out["rigs"]) for m in ("bad1", "bad2")}
    return out


def rel(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--url", required=True)
    ap.add_argument("--data", required=True, help="the directory with Motorcycle")
    ap.add_argument("--json")
    args = ap.parse_args()
    cv2.setNumThreads(2)
    left_img, right_img = texture(1), texture(2)
    left_png = cv2.imencode(".png", left_img)[1].tobytes()
    right_png = cv2.imencode(".png", right_img)[1].tobytes()
    rows, failed = [], []
    for model, rig in RIGS.items():
        yml = opencv_yml(rig, model)
        for alpha in (0.0, 0.5, 1.0):
            cv = cv_rectify(rig, model, alpha)
            answer = json.loads(service.send(args.url, "POST", "/calibration",
                                        json.dumps({"text": yml, "calibration_unit": "mm",
                                                    "alpha": alpha}).encode(),
                                        "application/json"))
            raw = answer["raw"]
            t_err = max(rel(raw[k], cv[k]) for k in ("R1", "R2", "P1", "P2", "Q"))
            roi_err = None
            if cv["rois"]:
                roi_err = max(abs(a - b) for ours, theirs in zip((raw["roi_left"], raw["roi_right"]), cv["rois"])
                              for a, b in zip(ours, theirs))
            npz = np.load(io.BytesIO(rectify(args.url, yml, left_png, right_png,
                                             {"output": "maps.npz", "alpha": alpha})))
            maps = cv_maps(rig, model, cv)
            map_err = 0.0
            for side, (mx, my) in zip(("left", "right"), maps):
                inside = (mx >= 0) & (my >= 0) & (mx <= SIZE[0] - 1) & (my <= SIZE[1] - 1)
                ox, oy = npz[f"{side}_map_x"], npz[f"{side}_map_y"]
                map_err = max(map_err, float(np.max(np.abs(ox - mx)[inside])),
                              float(np.max(np.abs(oy - my)[inside])))
            ours_png = cv2.imdecode(np.frombuffer(rectify(args.url, yml, left_png, right_png,
                                                          {"output": "left.png", "alpha": alpha}),
                                                  np.uint8), cv2.IMREAD_UNCHANGED)
            theirs = cv2.remap(left_img, maps[0][0], maps[0][1], cv2.INTER_LINEAR)
            x, y, w, h = raw["roi_left"]
            diff = np.abs(ours_png.astype(float) - theirs.astype(float))[y:y + h, x:x + w]
            img_err = float(diff.mean()) if diff.size else float("nan")
            map_floor = 0.05 if model == "equidistant" else 0.01
            ok = t_err <= 1e-6 and (roi_err is None or roi_err <= 1) and map_err <= map_floor \
                and img_err <= 1.0
            rows.append(dict(model=model, alpha=alpha, transforms_rel=t_err, roi_px=roi_err,
                             maps_px=map_err, image_mean_grey=img_err, ok=ok))
            if not ok:
                failed.append(f"{model} alpha {alpha}")
    # Speed: the depth job's remap stage with cached maps, against cv2.remap with 2 threads,
    # taking turns.
    yml = opencv_yml(RIGS["plumb_bob"], "plumb_bob")
    cv = cv_rectify(RIGS["plumb_bob"], "plumb_bob", 0.0)
    (mlx, mly), (mrx, mry) = cv_maps(RIGS["plumb_bob"], "plumb_bob", cv)
    query = "/depth-map?" + urllib.parse.urlencode({"output": "summary", "max_disparity": 16})
    parts = {
        "left": (left_png, "left.png", "image/png"),
        "right": (right_png, "right.png", "image/png"),
        "calibration": (yml.encode(), "calib.yml", "text/yaml"),
        "calibration_unit": (b"mm", None, "text/plain"),
    }
    ours_ms, cv_ms = [], []
    for round_ in range(8):
        s = json.loads(service.post_once(args.url, query, parts))
        assert s["rectified"], "the raw pair must be rectified"
        t = time.perf_counter()
        cv2.remap(left_img, mlx, mly, cv2.INTER_LINEAR)
        cv2.remap(right_img, mrx, mry, cv2.INTER_LINEAR)
        if round_:  # the first round builds the maps
            cv_ms.append((time.perf_counter() - t) * 1e3)
            ours_ms.append(s["timings_ms"]["rectify"])
    speed = dict(ours_remap_ms=statistics.median(ours_ms), opencv_remap_ms=statistics.median(cv_ms))

    print(f"{'model':<20} {'alpha':>5} {'R1..Q rel':>10} {'ROI px':>6} {'maps px':>9} {'image grey':>10}  ok")
    for r in rows:
        roi = "-" if r["roi_px"] is None else f"{r['roi_px']}"
        print(f"{r['model']:<20} {r['alpha']:>5} {r['transforms_rel']:>10.2e} {roi:>6} "
              f"{r['maps_px']:>9.5f} {r['image_mean_grey']:>10.4f}  {'yes' if r['ok'] else 'NO'}")
    print(f"remap of a 1280x720 grey pair, cached maps (median of 7): ours {speed['ours_remap_ms']:.2f} ms "
          f"(/depth-map's rectify stage), cv2.remap 2 threads {speed['opencv_remap_ms']:.2f} ms")
    e2e = end_to_end(args.url, args.data)
    print(f"Motorcycle (quarter size) made raw, /depth-map at {scenes.NUM_DISPARITIES} "
          f"disparities, against the ground truth (bad-1.0 / bad-2.0, %):")
    heads = [f"rig {i}" for i in range(len(e2e["rigs"]))] + ["mean"]
    print(f"  {'input':<46} " + " ".join(f"{h:>13}" for h in heads))
    o = e2e["original"]
    print(f"  {'the rectified original (never resampled)':<46} {o['bad1']:6.2f} {o['bad2']:6.2f}")
    for key, label in (("opencv_rectified", "raw, rectified by OpenCV, sent as rectified"),
                       ("ours_raw", "raw with its stereoCalibrate file (ours)")):
        cells = [f"{r[key]['bad1']:6.2f} {r[key]['bad2']:6.2f}" for r in e2e["rigs"]]
        cells.append(f"{e2e[key]['bad1']:6.2f} {e2e[key]['bad2']:6.2f}")
        print(f"  {label:<46} " + " ".join(cells))
    for i, r in enumerate(e2e["rigs"]):
        extra = 100 * (r["ours_raw_ms"] / r["opencv_rectified_ms"] - 1)
        print(f"  rig {i}: whole /depth-map requests (medians of 9, taking turns): raw {r['ours_raw_ms']:.1f} ms, "
              f"rectified {r['opencv_rectified_ms']:.1f} ms ({extra:+.1f} %); raw stages: "
              f"{r['server_timing']}")
    for metric in ("bad1", "bad2"):
        ours, theirs = e2e["ours_raw"][metric], e2e["opencv_rectified"][metric]
        if ours > theirs:
            failed.append(f"end to end {metric} {ours:.2f} % against OpenCV-rectified {theirs:.2f} %")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(dict(rows=rows, speed=speed, end_to_end=e2e), f, indent=1)
    if failed:
        print("floors missed:", ", ".join(failed))
        sys.exit(1)
    print("all floors met")


if __name__ == "__main__":
    main()
