"""Two builds of the service side by side (before and after a change), whole /depth-map requests
taking turns on kept-alive connections (11 rounds, 5 at 5.9 MP; medians): Middlebury Motorcycle
at quarter size and 64 disparities, OpenCV's real board pair 01 (rectified by the service) at
144, and Motorcycle upscaled 4 x (5.9 MP) at 400. Reported, never asserted; not in CI.

    git worktree add /tmp/before HEAD~1 && (cd /tmp/before && cargo build --release)
    /tmp/before/target/release/stereo-distance --port 18081 &
    target/release/stereo-distance --port 18082 &
    PYTHONPATH=scripts python3 -m evaluations.compare_builds http://127.0.0.1:18081 http://127.0.0.1:18082
"""
import statistics
import sys

import cv2

from . import indoor, scenes, service

old, new = sys.argv[1], sys.argv[2]
cases = []
l = cv2.imread('target/eval-stereo/motorcycle_left.png')
r = cv2.imread('target/eval-stereo/motorcycle_right.png')
cases.append(("motorcycle 741x500, 64", l, r, 64))
for name, a, b in indoor.rectified_pairs(new, 'tests/data/photographs/opencv-stereo'):
    if name == "01":
        cases.append(("board pair 01 640x480, 144", a, b, 144))
up = [cv2.resize(img, None, fx=4, fy=4, interpolation=cv2.INTER_CUBIC) for img in (l, r)]
cases.append(("motorcycle x4 5.9 MP, 400", *up, 400))
for label, a, b, nd in cases:
    parts = {"left": (cv2.imencode('.png', a)[1].tobytes(), 'l.png', 'image/png'),
             "right": (cv2.imencode('.png', b)[1].tobytes(), 'r.png', 'image/png')}
    path = f"/depth-map?max_disparity={nd}&output=disparity.npy"
    conns = {u: service.connect(u, parts, scenes.RIG) for u in (old, new)}
    times = {old: [], new: []}
    rounds = 11 if nd < 400 else 5
    for i in range(rounds + 1):
        for u in ((old, new) if i % 2 == 0 else (new, old)):
            conn, body, ctype = conns[u]
            _, sec, _ = service.timed(conn, path, body, ctype)
            if i: times[u].append(sec)
    mo, mn = statistics.median(times[old]) * 1000, statistics.median(times[new]) * 1000
    print(f"{label:30s} before {mo:8.1f} ms  after {mn:8.1f} ms  ({100 * (mn / mo - 1):+.1f} %)")
