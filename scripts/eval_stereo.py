"""The evaluation behind scripts/eval-stereo: our /depth-map against OpenCV's StereoSGBM on
Middlebury 2014 Motorcycle (quarter size) and two variants of it, with Middlebury's metric.

Run it through scripts/eval-stereo, which fetches the data and OpenCV and starts the service.
"""

import argparse
import http.client
import json
import statistics
import sys
import time
import urllib.parse
import uuid

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
RUNS = 5

# Accuracy floors (percent of ground-truth pixels), set from this script's results with a
# little room. Motorcycle's are the goal itself, 0.75 x OpenCV's best (11.02 % bad-1.0 and
# 8.69 % bad-2.0, so 8.27 and 6.52; measured 7.94 and 6.03). The variants' are OpenCV's best
# on them (measured: gain 7.85 / 5.94 against 11.18 / 8.74; noise 16.44 / 10.39 against
# 17.13 / 11.44), so that we never fall behind it where nothing was tuned.
FLOORS = {
    "motorcycle": {"bad1": 8.27, "bad2": 6.52},
    "gain": {"bad1": 11.18, "bad2": 8.74},
    "noise": {"bad1": 17.13, "bad2": 11.44},
}


def fill(disp):
    """Middlebury's filling: each hole takes the smaller of the nearest valid disparities to
    its left and right on the row."""
    out = disp.copy()
    h, w = disp.shape
    idx = np.arange(w)
    for y in range(h):
        row = disp[y]
        valid = np.isfinite(row)
        if not valid.any():
            out[y] = 0
            continue
        left = np.maximum.accumulate(np.where(valid, idx, -1))
        right = np.minimum.accumulate(np.where(valid, idx, w)[::-1])[::-1]
        lv = np.where(left >= 0, row[np.clip(left, 0, w - 1)], np.inf)
        rv = np.where(right < w, row[np.clip(right, 0, w - 1)], np.inf)
        out[y] = np.where(valid, row, np.minimum(lv, rv))
    return out


def score(disp, truth):
    known = np.isfinite(truth)
    err = np.abs(fill(disp)[known] - truth[known])
    bad = {f"bad{t:g}": 100.0 * float(np.mean(err > t)) for t in (0.5, 1.0, 2.0)}
    bad["density"] = 100.0 * float(np.mean(np.isfinite(disp)))
    return bad


def opencv(left, right):
    """Every StereoSGBM mode with block 3 and 5, as the issue sets them."""
    cv2.setNumThreads(2)
    modes = {
        "SGBM": cv2.STEREO_SGBM_MODE_SGBM,
        "HH": cv2.STEREO_SGBM_MODE_HH,
        "SGBM_3WAY": cv2.STEREO_SGBM_MODE_SGBM_3WAY,
        "HH4": cv2.STEREO_SGBM_MODE_HH4,
    }
    for name, mode in modes.items():
        for block in (3, 5):
            matcher = cv2.StereoSGBM_create(
                minDisparity=0,
                numDisparities=NUM_DISPARITIES,
                blockSize=block,
                P1=8 * 3 * block * block,
                P2=32 * 3 * block * block,
                disp12MaxDiff=1,
                uniquenessRatio=10,
                speckleWindowSize=100,
                speckleRange=2,
                mode=mode,
            )
            times = []
            for _ in range(RUNS):
                t = time.perf_counter()
                raw = matcher.compute(left, right)
                times.append(time.perf_counter() - t)
            disp = raw.astype(np.float32) / 16.0
            disp[raw < 0] = np.inf
            yield f"OpenCV {name} b{block}", disp, statistics.median(times)


def multipart(parts):
    boundary = uuid.uuid4().hex
    body = bytearray()
    for name, (data, filename, ctype) in parts.items():
        body += f"--{boundary}\r\n".encode()
        disposition = f'form-data; name="{name}"'
        if filename:
            disposition += f'; filename="{filename}"'
        body += f"Content-Disposition: {disposition}\r\nContent-Type: {ctype}\r\n\r\n".encode()
        body += data + b"\r\n"
    body += f"--{boundary}--\r\n".encode()
    return bytes(body), f"multipart/form-data; boundary={boundary}"


def ours(url, left_png, right_png, output="disparity.npy"):
    """Whole /depth-map requests on one kept-alive connection: the median of RUNS."""
    target = urllib.parse.urlsplit(url)
    conn = http.client.HTTPConnection(target.hostname, target.port, timeout=60)
    body, ctype = multipart(
        {
            "left": (left_png, "left.png", "image/png"),
            "right": (right_png, "right.png", "image/png"),
            "rig": (json.dumps(RIG).encode(), None, "application/json"),
        }
    )
    path = f"/depth-map?max_disparity={NUM_DISPARITIES}&output={output}"
    times, answer, timing = [], None, ""
    for _ in range(RUNS + 1):  # the first warms the connection and the allocator
        t = time.perf_counter()
        conn.request("POST", path, body=body, headers={"Content-Type": ctype})
        response = conn.getresponse()
        answer = response.read()
        times.append(time.perf_counter() - t)
        if response.status != 200:
            sys.exit(f"/depth-map answered {response.status}: {answer[:500]!r}")
        timing = response.getheader("Server-Timing", "")
    conn.close()
    return answer, statistics.median(times[1:]), timing


def load_npy(data):
    import io

    return np.load(io.BytesIO(data))


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


def colour(disp, lo, hi):
    d = np.where(np.isfinite(disp), disp, np.nan)
    scaled = np.clip((d - lo) / (hi - lo) * 255, 0, 255)
    img = cv2.applyColorMap(np.nan_to_num(scaled).astype(np.uint8), cv2.COLORMAP_TURBO)
    img[~np.isfinite(d)] = 0
    return img


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--data", required=True)
    parser.add_argument("--url", required=True)
    parser.add_argument("--figure")
    parser.add_argument("--json")
    args = parser.parse_args()

    left = cv2.imread(f"{args.data}/motorcycle_left.png")
    right = cv2.imread(f"{args.data}/motorcycle_right.png")
    truth = np.load(f"{args.data}/motorcycle_disp.npz")["arr_0"]
    print(f"Motorcycle (quarter size) {left.shape[1]} x {left.shape[0]}, "
          f"{NUM_DISPARITIES} disparities; OpenCV {cv2.__version__}, 2 threads; "
          f"median of {RUNS} runs")
    results, failures, maps = {}, [], {}
    header = f"{'scene':<11} {'method':<22} {'bad-0.5':>8} {'bad-1.0':>8} {'bad-2.0':>8} " \
             f"{'density':>8} {'time ms':>8}"
    print(header)
    print("-" * len(header))
    for scene, l, r in variants(left, right):
        rows = []
        for name, disp, seconds in opencv(l, r):
            rows.append((name, score(disp, truth), seconds))
            maps.setdefault(scene, {})[name] = disp
        ok_l = cv2.imencode(".png", l)[1].tobytes()
        ok_r = cv2.imencode(".png", r)[1].tobytes()
        answer, seconds, timing = ours(args.url, ok_l, ok_r)
        disp = load_npy(answer)
        disp = np.where(np.isnan(disp), np.inf, disp)
        maps[scene]["ours"] = disp
        mine = score(disp, truth)
        best1 = min(rows, key=lambda row: row[1]["bad1"])
        best2 = min(rows, key=lambda row: row[1]["bad2"])
        for name, s, secs in rows + [("ours (/depth-map)", mine, seconds)]:
            print(f"{scene:<11} {name:<22} {s['bad0.5']:8.2f} {s['bad1']:8.2f} "
                  f"{s['bad2']:8.2f} {s['density']:8.1f} {secs * 1e3:8.1f}")
        print(f"{scene:<11} {'  OpenCV best':<22} {'':8} {best1[1]['bad1']:8.2f} "
              f"{best2[1]['bad2']:8.2f}   ours/best: bad-1.0 "
              f"{mine['bad1'] / best1[1]['bad1']:.2f}, bad-2.0 {mine['bad2'] / best2[1]['bad2']:.2f}")
        print(f"{scene:<11}   our stages: {timing}")
        results[scene] = {
            "ours": {**mine, "ms": seconds * 1e3, "server_timing": timing},
            "opencv": {name: {**s, "ms": secs * 1e3} for name, s, secs in rows},
        }
        for metric, floor in FLOORS[scene].items():
            if mine[metric] > floor:
                failures.append(f"{scene}: {metric} {mine[metric]:.2f} % is above the floor {floor} %")
        print()
    sgbm3 = results["motorcycle"]["opencv"]["OpenCV SGBM_3WAY b3"]["ms"]
    print(f"time: our whole request {results['motorcycle']['ours']['ms']:.1f} ms, "
          f"OpenCV SGBM_3WAY compute alone {sgbm3:.1f} ms (a timing, reported, never asserted)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)
    if args.figure:
        lo, hi = 0, NUM_DISPARITIES
        best = min(results["motorcycle"]["opencv"].items(), key=lambda kv: kv[1]["bad1"])[0]
        panels = [left, colour(truth, lo, hi), colour(maps["motorcycle"][best], lo, hi),
                  colour(maps["motorcycle"]["ours"], lo, hi)]
        labels = ["left image", "ground truth", best, "ours"]
        for img, label in zip(panels, labels):
            cv2.putText(img, label, (10, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.9, (255, 255, 255), 2)
        top = np.hstack(panels[:2])
        bottom = np.hstack(panels[2:])
        figure = cv2.resize(np.vstack([top, bottom]), None, fx=0.6, fy=0.6,
                            interpolation=cv2.INTER_AREA)
        cv2.imwrite(args.figure, figure, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        print(f"figure: {args.figure}")
    if failures:
        print("\n".join(["ACCURACY BELOW THE FLOOR:"] + failures))
        sys.exit(1)
    print("accuracy floors: met")


if __name__ == "__main__":
    main()
