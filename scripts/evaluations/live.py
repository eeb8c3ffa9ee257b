"""The live stream (issue 73): GET /depth-stream, a WebSocket, over loopback, against the
pipelined HTTP stream and OpenCV's pipeline in the same run, on stream.py's rendered raw
1280 x 720 sequence (a camera moving past three surfaces through a distorted rig, JPEG pairs,
exact truth) at 128 disparities with preset=fast.

- Frames per second: the WebSocket with two frames in flight (the next sent before the last
  answer is read: one matched, one waiting, so none is dropped), POST /depth-map with two
  requests pipelined on one connection (stream.py's), and OpenCV's pipeline (imdecode, remap
  with maps made once, SGBM_3WAY); rounds taken in turns, medians. Goal: the WebSocket's
  frames per second at least the HTTP stream's.
- Latency: one frame at a time, from the frame sent to its answer read, the median of the
  frames after the first, against one /depth-map request's time (one at a time, on a kept-
  alive connection). Goal: at most 1.2 x.
- The first frame (the rig resolved and its maps built) and the rest, from the stream's own
  stage times.
- The temporal filter (on by default for streams) against the same stream without it: bad-1.0
  over every pixel and over the pixels both cameras see, over the moving sequence. Fails
  (exit 1) when the filter raises either by more than 0.5 points (accuracy only, never a time).

    PYTHONPATH=scripts python3 -m evaluations.live --url URL [--frames 40] [--rounds 3] [--json FILE]

Needs the `websockets` package (pinned by scripts/evaluate/lib.sh).
"""
import argparse
import io
import json
import os
import statistics
import struct
import subprocess
import sys
import tempfile
import time

import cv2

import numpy as np
from websockets.sync.client import connect

from . import scoring, stream

QUERY = "&preset=fast"


def ws_url(url):
    return url.replace("http://", "ws://", 1) + "/depth-stream"


def settings(calibration, temporal=True):
    return json.dumps({
        "layout": "pair",
        "calibration": calibration,
        "calibration_unit": "mm",
        "options": {"preset": "fast", "max_disparity": stream.DISPARITIES},
        "outputs": ["disparity.npy"],
        "temporal": temporal,
    })


def pair_frame(pair):
    """A pair-layout frame: the left JPEG's length (u32, little-endian), left, right."""
    return struct.pack("<I", len(pair[0])) + pair[0] + pair[1]


def answer(ws):
    """One frame's answer: its JSON and the disparity it carries."""
    head = json.loads(ws.recv())
    if head["type"] != "frame":
        sys.exit(f"/depth-stream answered {head}")
    files = [ws.recv() for _ in head["files"]]
    return head, np.load(io.BytesIO(files[0]))


def ws_stream(url, pairs, calibration, in_flight=2, temporal=True, keep=False):
    """The frames through one stream with `in_flight` outstanding: (seconds, maps, answers)."""
    with connect(ws_url(url), max_size=None, compression=None) as ws:
        ws.send(settings(calibration, temporal))
        resolved = json.loads(ws.recv())
        if resolved["type"] != "settings":
            sys.exit(f"/depth-stream refused the settings: {resolved}")
        frames = [pair_frame(p) for p in pairs]
        maps, heads, sent = [], [], 0
        started = time.perf_counter()
        for i in range(len(frames)):
            while sent < len(frames) and sent < i + in_flight:
                ws.send(frames[sent])
                sent += 1
            head, disparity = answer(ws)
            heads.append(head)
            if keep:
                maps.append(disparity)
        seconds = time.perf_counter() - started
    return seconds, maps, heads


def ws_latency(url, pairs, calibration):
    """Each frame's time from sent to answered, one at a time, in ms, and the answers."""
    with connect(ws_url(url), max_size=None, compression=None) as ws:
        ws.send(settings(calibration))
        ws.recv()
        times, heads = [], []
        for p in pairs:
            frame = pair_frame(p)
            t = time.perf_counter()
            ws.send(frame)
            head, _ = answer(ws)
            times.append(1e3 * (time.perf_counter() - t))
            heads.append(head)
    return times, heads


def readme_client(url, pairs, calibration):
    """The README's client (clients/python/stream.py) run on a folder of side-by-side frames
    made from the first pairs: the lines it prints, one a frame."""
    with tempfile.TemporaryDirectory() as folder:
        for i, (left, right) in enumerate(pairs):
            images = [cv2.imdecode(np.frombuffer(b, np.uint8), cv2.IMREAD_COLOR)
                      for b in (left, right)]
            cv2.imwrite(os.path.join(folder, f"{i:03}.jpg"), cv2.hconcat(images),
                        [cv2.IMWRITE_JPEG_QUALITY, 95])
        path = os.path.join(folder, "rig.yml")
        with open(path, "w") as f:
            f.write(calibration)
        client = os.path.join(os.path.dirname(__file__), "..", "..", "clients", "python",
                              "stream.py")
        run = subprocess.run([sys.executable, client, folder, path, ws_url(url)],
                             capture_output=True, text=True, timeout=300)
    lines = run.stdout.splitlines()
    if run.returncode != 0 or len(lines) != len(pairs) or any("mm" not in l for l in lines):
        sys.exit(f"clients/python/stream.py failed: {run.returncode}\n{run.stdout}\n{run.stderr}")
    return lines


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--url", required=True)
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json")
    args = parser.parse_args()
    pairs, truths, calibration = stream.sequence(args.frames)
    print(f"Live stream (GET /depth-stream): {args.frames} raw frames of {stream.W} x "
          f"{stream.H} (JPEG pairs, the pair layout), {stream.DISPARITIES} disparities, "
          f"preset=fast, against POST /depth-map and OpenCV's pipeline")

    # Latency, one frame at a time: the stream's and one request's, in turns.
    lat_ws, lat_http, firsts = [], [], []
    for _ in range(args.rounds):
        times, heads = ws_latency(args.url, pairs[:11], calibration)
        lat_ws += times[1:]
        firsts.append((heads[0]["times_ms"], [h["times_ms"] for h in heads[1:]]))
        lat_http += stream.one_at_a_time(args.url, pairs[:11], calibration, QUERY)[1:]
    first, rest = firsts[0]
    print(f"  first frame: {first['total']:.1f} ms of which setup (the rig at the frames' size, "
          f"the maps) {first['setup']:.1f} ms; the next 10: median "
          f"{statistics.median(t['total'] for t in rest):.1f} ms, setup "
          f"{max(t['setup'] for t in rest):.1f} ms at most")

    fps = {"opencv": [], "http": [], "ws": []}
    maps = {}
    for r in range(args.rounds):
        keep = r == 0
        seconds, m, _ = stream.opencv_stream(pairs, calibration)
        fps["opencv"].append(len(pairs) / seconds)
        seconds, _, _ = stream.ours_stream(args.url, pairs, calibration, QUERY)
        fps["http"].append(len(pairs) / seconds)
        seconds, m, heads = ws_stream(args.url, pairs, calibration, keep=keep)
        fps["ws"].append(len(pairs) / seconds)
        if keep:
            maps["ws"] = m
            dropped = heads[-1]["dropped_frames"]
    _, maps["ws_off"], _ = ws_stream(args.url, pairs, calibration, temporal=False, keep=True)
    med = {k: statistics.median(v) for k, v in fps.items()}
    print(f"  {'method':<52} {'frames/s':>9} {'spread':>13}")
    for key, name in (("opencv", "OpenCV imdecode, remap, SGBM_3WAY b3"),
                      ("http", "POST /depth-map, 2 in flight on one connection"),
                      ("ws", "GET /depth-stream, 2 in flight, temporal filter on")):
        print(f"  {name:<52} {med[key]:9.2f} [{min(fps[key]):.2f}-{max(fps[key]):.2f}]")
    print(f"  frames dropped by the stream with 2 in flight: {dropped}")
    lat = {"ws": statistics.median(lat_ws), "http": statistics.median(lat_http)}
    print(f"  latency, one frame at a time (median of {len(lat_ws)}): stream {lat['ws']:.1f} ms, "
          f"one /depth-map request {lat['http']:.1f} ms, OpenCV's pipeline "
          f"{1e3 / med['opencv']:.1f} ms a frame")
    goal_fps = med["ws"] >= med["http"]
    goal_lat = lat["ws"] <= 1.2 * lat["http"]
    print(f"  goal: stream frames/s >= the HTTP stream's: {med['ws'] / med['http']:.2f} x "
          f"({'met' if goal_fps else 'NOT MET'}); latency <= 1.2 x one request's: "
          f"{lat['ws'] / lat['http']:.2f} x ({'met' if goal_lat else 'NOT MET'}) "
          f"(medians of {args.rounds} rounds taken in turns; reported, never asserted)")

    lines = readme_client(args.url, pairs[:5], calibration)
    print(f"  the README's client (clients/python/stream.py), 5 side-by-side JPEG frames: "
          f"{' | '.join(lines)}")
    acc = {k: stream.accuracy(m, truths) for k, m in maps.items()}
    print(f"  temporal filter over the moving sequence: bad-1.0 {acc['ws']['bad1']:.2f} % with, "
          f"{acc['ws_off']['bad1']:.2f} % without; nonocc {acc['ws']['nonocc_bad1']:.2f} % "
          f"against {acc['ws_off']['nonocc_bad1']:.2f} %; density {acc['ws']['density']:.1f} "
          f"against {acc['ws_off']['density']:.1f} %")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"fps": fps, "latency_ms": {"ws": lat_ws, "http": lat_http},
                       "first": first, "accuracy": acc, "dropped": dropped}, f, indent=2)
    failures = [f"the temporal filter raises {m} from {acc['ws_off'][m]:.2f} % to "
                f"{acc['ws'][m]:.2f} %" for m in ("bad1", "nonocc_bad1")
                if acc["ws"][m] > acc["ws_off"][m] + 0.5]
    scoring.floors(failures, "live stream accuracy floors")


if __name__ == "__main__":
    main()
