# What the evaluation launchers share (sourced, from the repository's root): OpenCV 4.14 and
# numpy pinned from PyPI, the service's release binary, and a service started on a free port
# for the launcher's run, stopped when it ends. The evaluations themselves are the Python
# package scripts/evaluations, run as `python3 -m evaluations.NAME`.

export PYTHONPATH="$PWD/scripts${PYTHONPATH:+:$PYTHONPATH}"

# numpy 2.1.3 and opencv-python-headless 4.14.0.94, unless they are there.
opencv_python() {
  python3 -c 'import numpy, cv2; assert cv2.__version__ == "4.14.0"' 2>/dev/null \
    || python3 -m pip install --quiet --disable-pip-version-check --root-user-action=ignore \
      numpy==2.1.3 opencv-python-headless==4.14.0.94
}

# websockets 15.0.1 (the live stream's client), unless it is there.
websockets_python() {
  python3 -c 'import websockets; assert websockets.__version__ == "15.0.1"' 2>/dev/null \
    || python3 -m pip install --quiet --disable-pip-version-check --root-user-action=ignore \
      websockets==15.0.1
}

# SERVICE_BIN, or the release build (built if missing).
service_binary() {
  if [ -z "${SERVICE_BIN:-}" ]; then
    cargo build --release --locked --quiet
    SERVICE_BIN=target/release/stereo-distance
  fi
}

# The service on a free loopback port, its log in $1/server.log; sets `url`, and stops the
# service when the launcher exits.
start_service() {
  service_binary
  local port
  port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  "$SERVICE_BIN" --host 127.0.0.1 --port "$port" >"$1/server.log" 2>&1 &
  service_pid=$!
  trap 'kill "$service_pid" 2>/dev/null || true; wait "$service_pid" 2>/dev/null || true' EXIT
  url="http://127.0.0.1:$port"
  for _ in $(seq 100); do
    curl -fs "$url/readyz" >/dev/null 2>&1 && return 0
    sleep 0.1
  done
  echo "the service did not start: $1/server.log" >&2
  return 1
}
