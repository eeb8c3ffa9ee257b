"""A stream of raw frames, as a rig records them: issue 55's frames per second against OpenCV's
own pipeline, same run, and each preset's accuracy over the sequence.

The sequence (rendered here, exact truth): a camera moving sideways and forward past a slanted
background, a slanted box and a near pillar (each surface's parallax its own, the disparities
growing as the camera comes closer: 24 to 115 px), 100 frames of 1280 x 720 with sensor noise
sigma 2, made raw through scripts/evaluations/raw_pair.py's first rig (k1 around -0.2, the cameras turned 1
to 2 degrees) and sent as JPEG (quality 95) with the rig's stereoCalibrate file.

Ours: whole POST /depth-map requests at 128 disparities, the calibration sent with every frame
(the service keeps the rig's rectification maps), over one kept-alive connection with two
requests in flight (HTTP/1.1 pipelining: the next frame is sent before the last answer is
read), the disparity as NPY. OpenCV: cv2.imdecode x 2 (grey), cv2.remap x 2 with maps made
once (initUndistortRectifyMap from the same file), StereoSGBM_3WAY (block 3, as
scripts/evaluate/matcher sets it) compute(). Rounds taken in turns (OpenCV's sequence, then each
preset's), medians over the rounds. The first frame's time (the rig's maps built) and the rest's
are taken apart, one request at a time, before the rounds.

    PYTHONPATH=scripts python3 -m evaluations.stream --url URL [--rounds 2] [--frames 100] [--stride 1] [--json FILE]

Accuracy over every pixel and over the pixels both cameras see (`nonocc`); over every pixel,
bad-2.0 is set by the holes of the pillar's occlusion shadow, which Middlebury's fill takes from
the pillar's side for every method alike, and nonocc bad-2.0 is about 0.2 % for every method
(printed, not floored). Fails (exit 1) when a preset's bad-1.0, over every pixel or nonocc, over
the sequence is above OpenCV SGBM_3WAY's (accuracy only, never a time).
"""
import argparse
import json
import socket
import statistics
import sys
import time
import urllib.parse

import cv2
import numpy as np

from . import peers, raw_pair, scenes, scoring, service

W, H = 1280, 720
F, CX, CY, DOFFS, BASELINE = 1000.0, 640.0, 360.0, 0.0, 120.0
DISPARITIES = 128
NOISE = 2.0
# Surfaces: disparity d = a(t) + b * (x + shift(t)) + c * y in the left image, a(t) = a (1 +
# APPROACH t), shift(t) = PAN a t (a surface's parallax is its disparity's), its region in
# scene coordinates (fractions of the frame), and its texture's seed.
SURFACES = [
    ((24.0, 16.0 / W, 10.0 / H), None, 21),
    ((56.0, 12.0 / W, -6.0 / H), (0.25, 0.2, 0.65, 0.85), 22),
    ((96.0, 0.0, 8.0 / H), (0.7, 0.0, 0.8, 1.0), 23),
]
APPROACH = 0.002
PAN = 0.04
ATLAS_W = 2048


def atlases():
    """Each surface's texture, rendered once on a grid wide enough for the whole pan."""
    ys, xs = np.mgrid[0:H + 16, 0:ATLAS_W].astype(np.float32)
    return [scenes.texture(xs, ys, seed) for _, _, seed in SURFACES]


def frame(t, textures, rng):
    """Frame t's rectified left and right images (uint8 BGR), the left's true disparity and
    where the right camera sees what the left one does (not occluded)."""
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float32)

    def render(right):
        """The image and, at each of its pixels, the disparity of the surface it shows."""
        image = np.zeros((H, W, 3), np.float32)
        depth = np.full((H, W), -np.inf, np.float32)
        for ((a, b, c), region, _), tex in zip(SURFACES, textures):
            a_t = a * (1 + APPROACH * t)
            shift = PAN * a * t
            a_eff = a_t + b * shift
            # The left x this pixel sees on the surface: itself, or solved from xr = x - d(x).
            xl = (xs + a_eff + c * ys) / (1 - b) if right else xs
            d = a_eff + b * xl + c * ys
            u = xl + shift
            inside = (u >= 0) & (u < ATLAS_W - 1)
            if region:
                x0, y0, x1, y1 = region
                inside &= (u >= x0 * W) & (u < x1 * W) & (ys >= y0 * H) & (ys < y1 * H)
            nearer = inside & (d > depth)
            colour = cv2.remap(tex, u, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
            image[nearer] = colour[nearer]
            depth[nearer] = d[nearer]
        return image, depth

    left, truth = render(False)
    right, seen = render(True)
    # A left pixel is occluded where the right image shows another surface at x - d.
    xr = np.rint(xs - truth).astype(np.int64)
    inside = (xr >= 0) & (xr < W)
    there = np.take_along_axis(seen, np.clip(xr, 0, W - 1), axis=1)
    visible = inside & (np.abs(there - truth) < 1.0)
    noisy = [np.clip(img + NOISE * rng.standard_normal(img.shape, dtype=np.float32), 0, 255)
             .astype(np.uint8) for img in (left, right)]
    return noisy[0], noisy[1], truth, visible


def sequence(count, stride=1):
    """The raw JPEG pairs of every `stride`-th of `count` frames, their truths, and the
    calibration file's text."""
    textures = atlases()
    left_map, right_map, calibration = raw_pair.rig_maps(W, H, F, CX, CY, DOFFS, BASELINE, 0)
    rng = np.random.default_rng(55)
    pairs, truths = [], []
    for t in range(0, count, stride):
        left, right, truth, visible = frame(t, textures, rng)
        jpeg = [cv2.imencode(".jpg", raw_pair.to_raw(img, m), [cv2.IMWRITE_JPEG_QUALITY, 95])[1]
                .tobytes() for img, m in ((left, left_map), (right, right_map))]
        pairs.append(jpeg)
        truths.append((truth, visible))
    return pairs, truths, calibration


def request(target, query, pair, calibration):
    """The bytes of one pipelined POST /depth-map of `pair` with the calibration."""
    body, ctype = service.multipart({
        "left": (pair[0], "left.jpg", "image/jpeg"),
        "right": (pair[1], "right.jpg", "image/jpeg"),
        "calibration": (calibration.encode(), "rig.yml", "application/x-yaml"),
        "calibration_unit": (b"mm", None, "text/plain"),
    })
    head = (f"POST /depth-map?max_disparity={DISPARITIES}&output=disparity.npy{query} HTTP/1.1\r\n"
            f"Host: {target}\r\nContent-Type: {ctype}\r\nContent-Length: {len(body)}\r\n\r\n")
    return head.encode() + body


class Reader:
    """Answers read off one socket, in order (Content-Length bodies)."""

    def __init__(self, sock):
        self.sock, self.buffer = sock, b""
        # Each answer's Server-Timing stages, in ms, in the order read.
        self.stages = []

    def _fill(self):
        chunk = self.sock.recv(1 << 20)
        if not chunk:
            raise ConnectionError("the service closed the connection")
        self.buffer += chunk

    def answer(self):
        while b"\r\n\r\n" not in self.buffer:
            self._fill()
        head, self.buffer = self.buffer.split(b"\r\n\r\n", 1)
        lines = head.decode("latin-1").split("\r\n")
        status = int(lines[0].split()[1])
        headers = {k.strip().lower(): v.strip() for k, v in
                   (line.split(":", 1) for line in lines[1:] if ":" in line)}
        length = int(headers.get("content-length", "0"))
        while len(self.buffer) < length:
            self._fill()
        body, self.buffer = self.buffer[:length], self.buffer[length:]
        if status != 200:
            sys.exit(f"/depth-map answered {status}: {body[:400]!r}")
        self.stages.append(stages(headers.get("server-timing", "")))
        return body


def stages(timing):
    """A Server-Timing header's stages, `{name: ms}`."""
    out = {}
    for entry in timing.split(","):
        name, _, dur = entry.strip().partition(";dur=")
        if name and dur:
            out[name] = float(dur)
    return out


# Where a frame's time goes, by the stages of Server-Timing: the match is the matcher's three.
STAGES = {"decode": ("decode",), "remap": ("rectify",), "match": ("cost", "aggregate", "refine"),
          "encode": ("encode",)}


def connect(url):
    target = urllib.parse.urlsplit(url)
    sock = socket.create_connection((target.hostname, target.port), timeout=120)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock, f"{target.hostname}:{target.port}"


def ours_stream(url, pairs, calibration, query, in_flight=2, keep=False):
    """The frames over one connection with `in_flight` requests pipelined: (seconds, maps,
    each frame's Server-Timing stages)."""
    sock, target = connect(url)
    reader = Reader(sock)
    bodies = [request(target, query, p, calibration) for p in pairs]
    maps = []
    started = time.perf_counter()
    sent = 0
    for i in range(len(bodies)):
        while sent < len(bodies) and sent < i + in_flight:
            sock.sendall(bodies[sent])
            sent += 1
        answer = reader.answer()
        if keep:
            maps.append(service.load_npy(answer))
    seconds = time.perf_counter() - started
    sock.close()
    return seconds, maps, reader.stages


def one_at_a_time(url, pairs, calibration, query):
    """Each frame's whole request time, one at a time, in ms."""
    sock, target = connect(url)
    reader = Reader(sock)
    times = []
    for p in pairs:
        body = request(target, query, p, calibration)
        t = time.perf_counter()
        sock.sendall(body)
        reader.answer()
        times.append(1e3 * (time.perf_counter() - t))
    sock.close()
    return times


def opencv_stream(pairs, calibration, keep=False):
    """OpenCV's pipeline over the frames: (seconds, maps, each frame's stages in ms)."""
    cv2.setNumThreads(2)
    fs = cv2.FileStorage(calibration, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    node = lambda k: fs.getNode(k).mat()
    maps = [cv2.initUndistortRectifyMap(node(f"M{i}"), node(f"D{i}"), node(f"R{i}"),
                                        node(f"P{i}")[:, :3], (W, H), cv2.CV_16SC2)
            for i in (1, 2)]
    matcher = peers.sgbm_matcher(cv2.STEREO_SGBM_MODE_SGBM_3WAY, 3, DISPARITIES)
    out, frames = [], []
    started = time.perf_counter()
    for left, right in pairs:
        images, spent = [], {"decode": 0.0, "remap": 0.0}
        for data, (m1, m2) in zip((left, right), maps):
            t = time.perf_counter()
            raw = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)
            t2 = time.perf_counter()
            images.append(cv2.remap(raw, m1, m2, cv2.INTER_LINEAR))
            spent["decode"] += 1e3 * (t2 - t)
            spent["remap"] += 1e3 * (time.perf_counter() - t2)
        t = time.perf_counter()
        disp = matcher.compute(images[0], images[1])
        spent["match"] = 1e3 * (time.perf_counter() - t)
        t = time.perf_counter()
        if keep:
            d = disp.astype(np.float32) / 16
            out.append(np.where(disp < 0, np.inf, d))
        spent["encode"] = 1e3 * (time.perf_counter() - t)
        frames.append(spent)
    return time.perf_counter() - started, out, frames


def accuracy(maps, truths):
    """Mean bad-1.0 and bad-2.0 (%) over the frames, holes filled as Middlebury does: over
    every pixel, and over the pixels both cameras see (`nonocc`, Middlebury's other mask)."""
    rows = []
    for m, (truth, visible) in zip(maps, truths):
        m = np.where(np.isnan(m), np.inf, m)
        every = scoring.score(m, truth)
        nonocc = scoring.score(m, np.where(visible, truth, np.inf))
        rows.append({**every, "nonocc_bad1": nonocc["bad1"], "nonocc_bad2": nonocc["bad2"]})
    return {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--url", required=True)
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=2)
    # Every n-th frame only: the same path in fewer frames (CI takes 2, for time).
    parser.add_argument("--stride", type=int, default=1)
    parser.add_argument("--json")
    args = parser.parse_args()
    if args.stride < 1:
        parser.error("--stride must be at least 1")
    started = time.perf_counter()
    pairs, truths, calibration = sequence(args.frames, args.stride)
    every = f" (one in {args.stride} of {args.frames})" if args.stride > 1 else ""
    print(f"Stream: {len(pairs)} raw frames{every} of {W} x {H} (JPEG, {sum(len(a) + len(b) for a, b in pairs) / len(pairs) / 1e3:.0f} kB a pair), "
          f"{DISPARITIES} disparities, a camera moving past three surfaces through a distorted "
          f"rig (rendered in {time.perf_counter() - started:.1f} s)")

    # First and rest: the rig's maps are built by the first request and kept.
    first = one_at_a_time(args.url, pairs[:11], calibration, "")
    print(f"  one request at a time, preset=accurate: first frame {first[0]:.1f} ms (the rig's "
          f"maps built), the next 10 median {statistics.median(first[1:]):.1f} ms "
          f"[{min(first[1:]):.1f}-{max(first[1:]):.1f}]")

    results = {"first_ms": first[0], "rest_ms": first[1:]}
    fps = {"opencv": [], "accurate": [], "fast": []}
    maps, frames = {}, {"opencv": [], "accurate": [], "fast": []}
    for r in range(args.rounds):
        keep = r == 0
        seconds, m, spent = opencv_stream(pairs, calibration, keep)
        fps["opencv"].append(len(pairs) / seconds)
        frames["opencv"] += spent
        if keep:
            maps["opencv"] = m
        for preset in ("accurate", "fast"):
            seconds, m, spent = ours_stream(args.url, pairs, calibration, f"&preset={preset}",
                                            keep=keep)
            fps[preset].append(len(pairs) / seconds)
            frames[preset] += [{name: sum(f.get(k, 0.0) for k in keys)
                                for name, keys in STAGES.items()} for f in spent]
            if keep:
                maps[preset] = m
    acc = {name: accuracy(m, truths) for name, m in maps.items()}
    med = {k: statistics.median(v) for k, v in fps.items()}
    spread = lambda k: f"[{min(fps[k]):.2f}-{max(fps[k]):.2f}]"
    print(f"  {'method':<44} {'frames/s':>9} {'spread':>13} {'bad-1.0':>8} {'bad-2.0':>8} "
          f"{'nonocc':>8} {'nonocc':>8} {'density':>8}")
    for key, name in (("opencv", "OpenCV imdecode, remap, SGBM_3WAY b3"),
                      ("accurate", "ours, preset=accurate (2 in flight)"),
                      ("fast", "ours, preset=fast (2 in flight)")):
        print(f"  {name:<44} {med[key]:9.2f} {spread(key):>13} {acc[key]['bad1']:8.2f} "
              f"{acc[key]['bad2']:8.2f} {acc[key]['nonocc_bad1']:8.2f} "
              f"{acc[key]['nonocc_bad2']:8.2f} {acc[key]['density']:8.1f}")
    # Where a frame's time goes (ours from Server-Timing, with two frames in flight on two
    # cores each stage's time is its own frame's, not the wall's).
    spent = {k: {name: statistics.median(f[name] for f in v) for name in STAGES}
             for k, v in frames.items()}
    print(f"  where a frame's time goes, median ms a frame: {'':<13} "
          + " ".join(f"{name:>8}" for name in STAGES))
    for key in ("opencv", "accurate", "fast"):
        print(f"  {key:<58} " + " ".join(f"{spent[key][name]:8.1f}" for name in STAGES))
    results["stages_ms"] = spent
    goal = med["fast"] >= 1.5 * med["opencv"]
    print(f"  goal: preset=fast >= 1.5 x OpenCV's pipeline: {med['fast'] / med['opencv']:.2f} x "
          f"({'met' if goal else 'NOT MET'}); preset=accurate {med['accurate'] / med['opencv']:.2f} x "
          f"(medians of {args.rounds} rounds taken in turns; reported, never asserted)")
    results.update({"fps": fps, "accuracy": acc})
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)
    failures = [f"stream preset={p}: {m} {acc[p][m]:.2f} % is above OpenCV SGBM_3WAY's "
                f"{acc['opencv'][m]:.2f} %"
                for p in ("accurate", "fast") for m in ("bad1", "nonocc_bad1")
                if acc[p][m] > acc["opencv"][m]]
    scoring.floors(failures, "stream accuracy floors")


if __name__ == "__main__":
    main()
