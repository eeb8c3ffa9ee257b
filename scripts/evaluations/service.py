"""Shared HTTP for the evaluations: the one multipart encoder, a POST on its own connection or
many on one kept-alive connection timed whole, NPY answers read, and the query settings several
evaluations measure. The standard library only (the mrcal evaluation runs under Debian's
python3).
"""

import http.client
import io
import json
import os
import statistics
import sys
import time
import urllib.parse
import uuid


# How many times each time is taken (medians of RUNS): EVAL_RUNS, 5 unless set. CI takes 2, as it
# asserts accuracy only; the README's times come from runs at 5.
try:
    RUNS = int(os.environ.get("EVAL_RUNS", "5"))
except ValueError:
    RUNS = 0
if RUNS < 1:
    raise SystemExit(f"EVAL_RUNS must be a whole number of at least 1, not {os.environ['EVAL_RUNS']!r}")


# Rounds of goal 1's timing taken in turns with OpenCV (`taking_turns`).
TURNS = 2 * RUNS + 1


# The keep rule's settings the evaluations measure beside the defaults (max_disparity_std 4 px
# with the uniqueness and speckle rules on): the threshold with those rules, and with them off so
# that sigma_d alone judges (sigma.py on the truth, indoor.py on real indoor pairs).
KEEP_RULES = ["max_disparity_std=2", "max_disparity_std=1", "max_disparity_std=0.5",
              "uniqueness=0&speckle_size=0",
              "uniqueness=0&speckle_size=0&max_disparity_std=1",
              "uniqueness=0&speckle_size=0&max_disparity_std=0.5"]


def multipart(parts):
    """A multipart/form-data body of `parts`, a dict of name -> (data, filename, type), or a
    list of (name, that) pairs where a name may repeat; with its content type."""
    boundary = uuid.uuid4().hex
    body = bytearray()
    for name, (data, filename, ctype) in parts.items() if isinstance(parts, dict) else parts:
        body += f"--{boundary}\r\n".encode()
        disposition = f'form-data; name="{name}"'
        if filename:
            disposition += f'; filename="{filename}"'
        body += f"Content-Disposition: {disposition}\r\nContent-Type: {ctype}\r\n\r\n".encode()
        body += data + b"\r\n"
    body += f"--{boundary}--\r\n".encode()
    return bytes(body), f"multipart/form-data; boundary={boundary}"


def connect(url, parts, rig):
    """A connection to the service at `url`, and the multipart body of `parts` with `rig` (the
    members of /distance) added, and its content type."""
    target = urllib.parse.urlsplit(url)
    conn = http.client.HTTPConnection(target.hostname, target.port, timeout=60)
    body, ctype = multipart(
        {**parts, "rig": (json.dumps(rig).encode(), None, "application/json")}
    )
    return conn, body, ctype


def send(url, method, path, body, ctype, timeout=300):
    """One request of `body` (of type `ctype`) on its own connection: the answer's bytes, or
    exit naming the status."""
    target = urllib.parse.urlsplit(url)
    conn = http.client.HTTPConnection(target.hostname, target.port, timeout=timeout)
    conn.request(method, path, body=body, headers={"Content-Type": ctype})
    response = conn.getresponse()
    answer = response.read()
    conn.close()
    if response.status != 200:
        sys.exit(f"{method} {path} answered {response.status}: {answer[:500]!r}")
    return answer


def post_once(url, path, parts):
    """One multipart POST of `parts` ([`multipart`]) on its own connection: the answer's
    bytes, or exit naming the status."""
    body, ctype = multipart(parts)
    return send(url, "POST", path, body, ctype)


def timed(conn, path, body, ctype):
    """One POST of `body` to `path` on the kept-alive `conn`, timed whole: the answer's bytes,
    the seconds it took and the response, or exit naming the status."""
    started = time.perf_counter()
    conn.request("POST", path, body=body, headers={"Content-Type": ctype})
    response = conn.getresponse()
    answer = response.read()
    seconds = time.perf_counter() - started
    if response.status != 200:
        sys.exit(f"{path} answered {response.status}: {answer[:500]!r}")
    return answer, seconds, response


def post(url, path, parts, rig):
    """The same multipart POST (with `rig`), RUNS + 1 times on one kept-alive connection: the
    last answer, the median time of the last RUNS, and the Server-Timing header."""
    conn, body, ctype = connect(url, parts, rig)
    times, answer, timing = [], None, ""
    for _ in range(RUNS + 1):  # the first warms the connection and the allocator
        answer, seconds, response = timed(conn, path, body, ctype)
        times.append(seconds)
        timing = response.getheader("Server-Timing", "")
    conn.close()
    return answer, statistics.median(times[1:]), timing


def load_npy(data):
    """An NPY answer's array (numpy is imported only here: uncertainty.py runs under Debian's
    python3 with mrcal, whose numpy is its own)."""
    import numpy as np

    return np.load(io.BytesIO(data))
