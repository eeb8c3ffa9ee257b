"""A burst of concurrent image requests at the largest size the deployment is sized for, against
a running service (scripts/ops/container-test runs it against the container under the Kubernetes
manifest's memory limit and budget): N requests of a 6-megapixel pair at 400 disparities sent at
once, while the light routes and /readyz are asked every 100 ms.

Passes (exit 0) when every burst request is first answered 200, or 503 with Retry-After (the
memory budget refusing what does not fit now), and nothing else; each one refused, retried after
its Retry-After, is answered 200 in the end; every light request and readiness probe answers 200
throughout; and the same request sent once more after the burst is answered 200.

    python3 scripts/ops/burst.py --url http://127.0.0.1:8080 [--requests 8]
"""

import argparse
import json
import socket
import sys
import threading
import time
import urllib.parse
import uuid

import cv2
import numpy as np

WIDTH, HEIGHT, DISPARITIES = 3000, 2000, 400


def pair():
    """A textured 3000 x 2000 pair: a background plane at 60 px and a box in front at 300 px,
    as PNG bytes."""
    rng = np.random.default_rng(3)
    texture = rng.integers(0, 256, (HEIGHT, WIDTH + DISPARITIES), dtype=np.uint8)
    texture = cv2.GaussianBlur(texture, (0, 0), 1.2)
    left = texture[:, :WIDTH].copy()
    right = texture[:, 60:WIDTH + 60].copy()
    # The box: the same texture shifted further.
    y0, y1, x0, x1 = 600, 1400, 1200, 2200
    right[y0:y1, x0 - 300 + 60:x1 - 300 + 60] = 0
    right[y0:y1, x0 - 300:x1 - 300] = left[y0:y1, x0:x1]
    encode = lambda img: cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))[1].tobytes()
    return encode(left), encode(right)


def multipart(parts):
    boundary = uuid.uuid4().hex
    body = bytearray()
    for name, data in parts.items():
        body += f"--{boundary}\r\n".encode()
        body += f'Content-Disposition: form-data; name="{name}"; filename="{name}.png"\r\n'.encode()
        body += b"Content-Type: image/png\r\n\r\n" + data + b"\r\n"
    body += f"--{boundary}--\r\n".encode()
    return bytes(body), f"multipart/form-data; boundary={boundary}"


def send(url, method, path, body=None, headers=None, timeout=120):
    """One request on its own connection (closed after it), as curl sends a large body: with
    `Expect: 100-continue`, the body sent only once the server says so, so that a refusal
    before the body (the budget's 503) is read rather than lost in a broken pipe. Returns the
    status (None when no answer came), the headers (lower-case), the body and the seconds."""
    target = urllib.parse.urlsplit(url)
    body = body or b""
    head = [f"{method} {path} HTTP/1.1", f"Host: {target.hostname}:{target.port}",
            "Connection: close", f"Content-Length: {len(body)}"]
    head += [f"{k}: {v}" for k, v in (headers or {}).items()]
    if len(body) > 65536:
        head.append("Expect: 100-continue")
    started = time.perf_counter()
    try:
        with socket.create_connection((target.hostname, target.port), timeout=timeout) as sock:
            sock.sendall(("\r\n".join(head) + "\r\n\r\n").encode())
            reader = sock.makefile("rb")
            if len(body) > 65536:
                status, headers = read_head(reader)
                if status != 100:
                    return status, headers, reader.read(), time.perf_counter() - started
            sock.sendall(body)
            status, headers = read_head(reader)
            return status, headers, reader.read(), time.perf_counter() - started
    except OSError as e:
        return None, {}, str(e).encode(), time.perf_counter() - started


def read_head(reader):
    """The status and headers of the next response on `reader`."""
    status = int(reader.readline().split()[1])
    headers = {}
    while (line := reader.readline().strip()):
        name, _, value = line.decode("latin-1").partition(":")
        headers[name.strip().lower()] = value.strip()
    return status, headers


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--url", required=True)
    parser.add_argument("--requests", type=int, default=8)
    args = parser.parse_args()

    left, right = pair()
    body, ctype = multipart({"left": left, "right": right})
    path = f"/depth-map?max_disparity={DISPARITIES}&output=disparity.npy"
    print(f"burst: {args.requests} x POST {path}, {WIDTH} x {HEIGHT} pair, "
          f"{len(body) / 1e6:.1f} MB each")

    done = threading.Event()
    light = []  # (route, status, seconds)

    def poll():
        distance = json.dumps({"focal_length_px": 700, "baseline": 0.12, "unit": "m",
                               "x_left": 420, "x_right": 380}).encode()
        while not done.is_set():
            status, _, _, t = send(args.url, "GET", "/readyz", timeout=10)
            light.append(("/readyz", status, t))
            status, _, _, t = send(args.url, "POST", "/distance", distance,
                                   {"Content-Type": "application/json"}, timeout=10)
            light.append(("/distance", status, t))
            time.sleep(0.1)

    results = [None] * args.requests
    finals = [None] * args.requests

    def burst(i):
        # The first answer, then retries after each 503's Retry-After until a 200 (or 3 min).
        results[i] = answer = send(args.url, "POST", path, body, {"Content-Type": ctype})
        deadline = time.perf_counter() + 180
        tries = 1
        while answer[0] == 503 and time.perf_counter() < deadline:
            time.sleep(float(answer[1].get("retry-after", "1")))
            answer = send(args.url, "POST", path, body, {"Content-Type": ctype})
            tries += 1
        finals[i] = (answer[0], tries)

    poller = threading.Thread(target=poll)
    poller.start()
    started = time.perf_counter()
    threads = [threading.Thread(target=burst, args=(i,)) for i in range(args.requests)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    burst_time = time.perf_counter() - started
    done.set()
    poller.join()

    failures = []
    counts = {}
    for i, (status, headers, data, seconds) in enumerate(results):
        counts[status] = counts.get(status, 0) + 1
        retry = headers.get("retry-after")
        print(f"  request {i}: first {status} in {seconds:.2f} s"
              + (f", Retry-After {retry}" if status == 503 else ""))
        if status == 200:
            if len(data) < WIDTH * HEIGHT * 4:
                failures.append(f"request {i}: a 200 with {len(data)} bytes")
        elif status == 503:
            if not retry:
                failures.append(f"request {i}: a 503 without Retry-After")
        else:
            failures.append(f"request {i}: {status}: {data[:300]!r}")
    for i, (status, tries) in enumerate(finals):
        if status != 200:
            failures.append(f"request {i}: still {status} after {tries} tries")
    print(f"retrying after Retry-After: {[f'{s} after {n}' for s, n in finals]}")
    bad_light = [(r, s) for r, s, _ in light if s != 200]
    slowest = max((t for _, _, t in light), default=0.0)
    print(f"burst (with its retries) answered in {burst_time:.1f} s: {counts}; light and readiness requests "
          f"{len(light)}, not 200: {len(bad_light)}, slowest {slowest * 1e3:.0f} ms")
    if bad_light:
        failures.append(f"light routes or /readyz not 200 during the burst: {bad_light[:5]}")
    if not light:
        failures.append("no light request was answered during the burst")

    status, _, data, seconds = send(args.url, "POST", path, body, {"Content-Type": ctype})
    print(f"after the burst: {status} in {seconds:.2f} s")
    if status != 200:
        failures.append(f"after the burst: {status}: {data[:300]!r}")
    if failures:
        sys.exit("burst failed:\n  " + "\n  ".join(failures))
    print("burst passed")


if __name__ == "__main__":
    main()
