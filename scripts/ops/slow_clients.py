"""Slow and stalled clients against a running service, as a hostile client would be (issue 52).

Two phases, each on its own or both:

- `uploads`: N connections (`--slow`, 16) declare a 30 MB body to /depth-map and send one byte
  every 2 s, while real /depth-map requests (the service's own sample pair, from /sample/) are
  sent one after another. Reports each real request's status and, for each slow connection,
  how long the server took to answer or close it, and with what.
- `readers`: N connections (`--readers`, 48) each ask /depth-map for a W x H pair with
  `output=arrays.npz` (2048 x 1536: 38 MB) until one is answered 200 (a 503 is retried after
  its Retry-After), read the answer's head and nothing more (a 4 KiB receive buffer). The
  server's memory is sampled all along (`--pid`: its RSS; `--memory-file`: a cgroup's usage,
  for a container) with what its budget holds (`heavy_memory_reserved_bytes`). Halfway through
  `--stall` seconds a /distance and a small /depth-map are asked; at the end every stalled
  connection is read, to see what it got (the whole answer, or cut off), and one more
  /depth-map is asked.

With `--check`, exits 1 unless: every real request during the uploads was answered 200 and
every slow connection was answered or closed within 15 s; during the readers the memory grew by
at most `--budget` plus `--slack` bytes, /distance was answered 200 and the small /depth-map 200
or 503 with Retry-After, the /depth-map after the stall 200, and (`--expect-cut`) at least one
stalled reader was cut off.

    python3 scripts/ops/slow_clients.py --url http://127.0.0.1:8080 --pid PID --phase both \
        --budget 1073741824 --slack 0 --check
"""

import argparse
import json
import socket
import sys
import threading
import time
import urllib.parse
import uuid

SLOW_DECLARED = 30 * 1000 * 1000


def multipart(parts):
    boundary = uuid.uuid4().hex
    body = bytearray()
    for name, (data, ctype, filename) in parts.items():
        body += f"--{boundary}\r\n".encode()
        disposition = f'form-data; name="{name}"' + (f'; filename="{filename}"' if filename else "")
        body += f"Content-Disposition: {disposition}\r\n".encode()
        body += f"Content-Type: {ctype}\r\n\r\n".encode() + data + b"\r\n"
    body += f"--{boundary}--\r\n".encode()
    return bytes(body), f"multipart/form-data; boundary={boundary}"


def head_of(sock):
    """Reads one response head from `sock`, byte by byte, so that nothing after it is read."""
    data = bytearray()
    while not data.endswith(b"\r\n\r\n"):
        chunk = sock.recv(1)
        if not chunk:
            raise ConnectionError("closed before an answer")
        data += chunk
    lines = data.decode("latin-1").split("\r\n")
    headers = {}
    for line in lines[1:]:
        name, _, value = line.partition(":")
        if name:
            headers[name.strip().lower()] = value.strip()
    return int(lines[0].split()[1]), headers


def request(url, method, path, body=b"", headers=None, timeout=60):
    """One request on its own connection; (status, headers, body, seconds)."""
    target = urllib.parse.urlsplit(url)
    head = [f"{method} {path} HTTP/1.1", f"Host: {target.hostname}:{target.port}",
            "Connection: close", f"Content-Length: {len(body)}"]
    head += [f"{k}: {v}" for k, v in (headers or {}).items()]
    started = time.perf_counter()
    try:
        with socket.create_connection((target.hostname, target.port), timeout=timeout) as sock:
            sock.sendall(("\r\n".join(head) + "\r\n\r\n").encode() + body)
            status, headers = head_of(sock)
            rest = bytearray()
            while (chunk := sock.recv(1 << 20)):
                rest += chunk
            return status, headers, bytes(rest), time.perf_counter() - started
    except OSError as e:
        return None, {}, str(e).encode(), time.perf_counter() - started


class Memory:
    """Samples the server's memory every 100 ms: a process's RSS or a cgroup's usage."""

    def __init__(self, pid=None, path=None, url=None):
        self.pid, self.path, self.url = pid, path, url
        self.samples = []  # (seconds, bytes)
        self.reserved = []  # (seconds, bytes the budget holds, process memory then)
        self.started = time.perf_counter()
        self._stop = threading.Event()
        self._thread = None

    def read(self):
        if self.path:
            with open(self.path) as f:
                return int(f.read().split()[0])
        if self.pid:
            with open(f"/proc/{self.pid}/status") as f:
                for line in f:
                    if line.startswith("VmRSS:"):
                        return int(line.split()[1]) * 1024
        return None

    def start(self):
        def run():
            while not self._stop.is_set():
                value = self.read()
                if value is not None:
                    self.samples.append((time.perf_counter() - self.started, value))
                    held = self.budget_held()
                    if held is not None:
                        self.reserved.append((time.perf_counter() - self.started, held, value))
                time.sleep(0.1)
        self._thread = threading.Thread(target=run, daemon=True)
        self._thread.start()
        return self

    def budget_held(self):
        """The service's heavy_memory_reserved_bytes gauge, when a URL was given."""
        if not self.url:
            return None
        status, _, body, _ = request(self.url, "GET", "/metrics", timeout=5)
        if status != 200:
            return None
        for line in body.decode().splitlines():
            if line.startswith("heavy_memory_reserved_bytes "):
                return int(float(line.split()[1]))
        return None

    def outside(self, baseline):
        """The most the process held beyond its start and what the budget counted, and when."""
        if not self.reserved:
            return None
        return max((value - baseline - held, held) for _, held, value in self.reserved)

    def stop(self):
        self._stop.set()
        if self._thread:
            self._thread.join()

    def peak(self):
        values = [v for _, v in self.samples]
        return max(values) if values else None


def mib(n):
    return "n/a" if n is None else f"{n / 1048576:.0f} MiB"


def sample_request(url):
    """The service's own sample pair and rig, as a /depth-map form."""
    def get(path):
        status, _, body, _ = request(url, "GET", path)
        assert status == 200, f"GET {path}: {status}"
        return body
    left, right, rig = get("/sample/left.png"), get("/sample/right.png"), get("/sample/sample.json")
    return multipart({"left": (left, "image/png", "left.png"),
                      "right": (right, "image/png", "right.png"),
                      "rig": (rig, "application/json", None)})


def phase_uploads(args, failures):
    target = urllib.parse.urlsplit(args.url)
    body, ctype = sample_request(args.url)
    boundary = ctype.split("=", 1)[1]
    prefix = (f"--{boundary}\r\nContent-Disposition: form-data; name=\"left\"; "
              f"filename=\"left.png\"\r\nContent-Type: image/png\r\n\r\n").encode()
    slow = []  # (socket, when it was opened)

    print(f"uploads: {args.slow} connections declaring {SLOW_DECLARED / 1e6:.0f} MB to /depth-map, "
          f"a byte every 2 s")
    for _ in range(args.slow):
        sock = socket.create_connection((target.hostname, target.port), timeout=60)
        head = (f"POST /depth-map HTTP/1.1\r\nHost: {target.hostname}\r\n"
                f"Content-Type: {ctype}\r\nContent-Length: {SLOW_DECLARED}\r\n\r\n")
        sock.sendall(head.encode() + prefix)
        slow.append((sock, time.perf_counter()))

    results = {}  # index -> (status or reason, seconds)
    done = threading.Event()

    def dribble():
        while not done.is_set():
            time.sleep(2)
            for i, (sock, opened) in enumerate(slow):
                if i in results:
                    continue
                try:
                    sock.sendall(b"\x89")  # a byte of the left image
                except OSError as e:
                    results.setdefault(i, (f"closed ({e.__class__.__name__})",
                                           time.perf_counter() - opened))

    def watch(i):
        sock, opened = slow[i]
        try:
            status, _ = head_of(sock)
            results.setdefault(i, (status, time.perf_counter() - opened))
        except OSError as e:  # ConnectionError too: closed before an answer
            results.setdefault(i, (f"closed ({e.__class__.__name__})", time.perf_counter() - opened))

    dribbler = threading.Thread(target=dribble, daemon=True)
    dribbler.start()
    watchers = [threading.Thread(target=watch, args=(i,), daemon=True) for i in range(len(slow))]
    for w in watchers:
        w.start()

    real = []
    started = time.perf_counter()
    while time.perf_counter() - started < args.uploads_seconds:
        status, headers, data, seconds = request(args.url, "POST", "/depth-map", body,
                                                 {"Content-Type": ctype})
        real.append((status, seconds, headers.get("retry-after"), data[:200]))
        time.sleep(0.2)
        if len(results) == len(slow) and len(real) >= 5:
            break
    done.set()
    for w in watchers:
        w.join(timeout=20)
    for sock, _ in slow:
        sock.close()

    statuses = {}
    for status, *_ in real:
        statuses[status] = statuses.get(status, 0) + 1
    print(f"  real /depth-map requests meanwhile: {len(real)}, by status {statuses}, "
          f"slowest {max(s for _, s, _, _ in real):.2f} s")
    closed = sorted(results.values(), key=lambda r: r[1])
    by = {}
    for what, seconds in closed:
        by.setdefault(str(what), []).append(seconds)
    for what, times in by.items():
        print(f"  slow connections answered {what}: {len(times)}, after "
              f"{min(times):.1f}-{max(times):.1f} s")
    if len(results) < len(slow):
        failures.append(f"uploads: {len(slow) - len(results)} slow connections still open")
    late = [s for _, s in closed if s > 15]
    if late:
        failures.append(f"uploads: {len(late)} slow connections closed after 15 s")
    bad = [r for r in real if r[0] != 200]
    if bad:
        failures.append(f"uploads: {len(bad)} real requests not 200: {bad[:3]}")


def pair(width, height, disparities):
    import cv2
    import numpy as np
    rng = np.random.default_rng(5)
    texture = rng.integers(0, 256, (height, width + disparities), dtype=np.uint8)
    texture = cv2.GaussianBlur(texture, (0, 0), 1.2)
    left = texture[:, :width].copy()
    right = texture[:, disparities // 3:width + disparities // 3].copy()
    encode = lambda img: cv2.imencode(".png", img)[1].tobytes()
    return encode(left), encode(right)


def phase_readers(args, failures):
    target = urllib.parse.urlsplit(args.url)
    left, right = pair(args.width, args.height, args.disparities)
    rig = json.dumps({"focal_length_px": 1000, "baseline": 120, "unit": "mm"}).encode()
    body, ctype = multipart({"left": (left, "image/png", "left.png"),
                             "right": (right, "image/png", "right.png"),
                             "rig": (rig, "application/json", None)})
    path = f"/depth-map?max_disparity={args.disparities}&output=arrays.npz"
    small, small_type = sample_request(args.url)
    memory = Memory(args.pid, args.memory_file, args.url).start()
    time.sleep(0.5)
    baseline = memory.peak()
    print(f"readers: {args.readers} connections each POST {path} ({args.width} x {args.height}, "
          f"{len(body) / 1e6:.1f} MB) and never read; memory at start {mib(baseline)}")

    readers = []  # (socket, declared length) of those that got a 200 head and read no further
    refused = [0]
    deadline = time.perf_counter() + args.stall

    def open_one():
        # Asks until a 200 comes (a 503 retried after its Retry-After), then reads nothing more.
        while time.perf_counter() < deadline:
            sock = socket.socket()
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            sock.settimeout(180)
            try:
                sock.connect((target.hostname, target.port))
                head = (f"POST {path} HTTP/1.1\r\nHost: {target.hostname}\r\n"
                        f"Content-Type: {ctype}\r\nContent-Length: {len(body)}\r\n"
                        "Expect: 100-continue\r\n\r\n")
                sock.sendall(head.encode())
                status, headers = head_of(sock)
                if status == 100:
                    sock.sendall(body)
                    status, headers = head_of(sock)
            except OSError:
                sock.close()
                time.sleep(1)
                continue
            if status == 200:
                readers.append((sock, int(headers.get("content-length", "-1"))))
                return
            sock.close()
            refused[0] += 1
            time.sleep(float(headers.get("retry-after", "1")))

    openers = [threading.Thread(target=open_one, daemon=True) for _ in range(args.readers)]
    for t in openers:
        t.start()

    # While they stall: a light request and a small image request.
    time.sleep(args.stall / 2)
    light = request(args.url, "POST", "/distance",
                    json.dumps({"focal_length_px": 700, "baseline": 0.12, "unit": "m",
                                "x_left": 420, "x_right": 380}).encode(),
                    {"Content-Type": "application/json"})
    heavy = request(args.url, "POST", "/depth-map", small, {"Content-Type": small_type})
    print(f"  after {args.stall / 2:.0f} s: {len(readers)} readers hold a 200 unread, "
          f"{refused[0]} refusals so far; POST /distance {light[0]}, POST /depth-map (sample) "
          f"{heavy[0]}" + (f" Retry-After {heavy[1].get('retry-after')}" if heavy[0] == 503 else "")
          + f"; memory {mib(memory.read())}")
    time.sleep(max(deadline - time.perf_counter(), 0))
    for t in openers:
        t.join(timeout=1)
    stall_end = time.perf_counter() - memory.started
    peak = memory.peak()
    at_end = memory.read()

    outcomes = {}
    for sock, length in list(readers):
        sock.settimeout(2)
        got, what = 0, None
        try:
            while True:
                chunk = sock.recv(1 << 20)
                if not chunk:
                    break
                got += len(chunk)
        except ConnectionResetError:
            what = "reset"
        except OSError:
            what = "still open"
        key = "whole" if got >= length else f"cut off ({what or 'closed'})"
        outcomes[key] = outcomes.get(key, 0) + 1
        sock.close()
    time.sleep(2)
    freed = memory.read()
    memory.stop()
    print(f"  after {args.stall:.0f} s: {len(readers)} readers had a 200 and read nothing more "
          f"({refused[0]} refusals with 503 on the way); reading them now: {outcomes}")
    print(f"  memory: start {mib(baseline)}, peak {mib(peak)} (+{mib(peak - baseline)}), "
          f"at {stall_end:.0f} s {mib(at_end)}, 2 s after the readers are read or closed {mib(freed)}")
    outside = memory.outside(baseline)
    if outside:
        print(f"  the budget held at most {mib(max(h for _, h, _ in memory.reserved))}; the growth "
              f"beyond what it held peaked at {mib(outside[0])} (with {mib(outside[1])} held)")
    last = request(args.url, "POST", path, body, {"Content-Type": ctype}, timeout=180)
    print(f"  after the stall: POST {path} {last[0]}, {len(last[2]) / 1e6:.1f} MB")

    if baseline is not None and peak is not None and args.budget:
        if peak - baseline > args.budget + args.slack:
            failures.append(f"readers: memory grew by {mib(peak - baseline)}, more than "
                            f"the budget {mib(args.budget)} + {mib(args.slack)}")
    if light[0] != 200:
        failures.append(f"readers: /distance answered {light[0]} during the stall")
    if heavy[0] not in (200, 503) or (heavy[0] == 503 and not heavy[1].get("retry-after")):
        failures.append(f"readers: /depth-map answered {heavy[0]} during the stall")
    if last[0] != 200:
        failures.append(f"readers: /depth-map answered {last[0]} after the stall: {last[2][:200]!r}")
    if args.expect_cut and not any(k.startswith("cut off") for k in outcomes):
        failures.append("readers: no stalled reader was cut off")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--url", required=True)
    parser.add_argument("--pid", type=int)
    parser.add_argument("--memory-file")
    parser.add_argument("--phase", choices=["uploads", "readers", "both"], default="both")
    parser.add_argument("--slow", type=int, default=16)
    parser.add_argument("--uploads-seconds", type=float, default=40)
    parser.add_argument("--readers", type=int, default=48)
    parser.add_argument("--width", type=int, default=2048)
    parser.add_argument("--height", type=int, default=1536)
    parser.add_argument("--disparities", type=int, default=64)
    parser.add_argument("--stall", type=float, default=60)
    parser.add_argument("--budget", type=int, default=0)
    parser.add_argument("--slack", type=int, default=256 << 20)
    parser.add_argument("--expect-cut", action="store_true")
    parser.add_argument("--check", action="store_true")
    args = parser.parse_args()
    failures = []
    if args.phase in ("uploads", "both"):
        phase_uploads(args, failures)
    if args.phase in ("readers", "both"):
        phase_readers(args, failures)
    if failures:
        print("failed:\n  " + "\n  ".join(failures))
        if args.check:
            sys.exit(1)
    else:
        print("passed")


if __name__ == "__main__":
    main()
