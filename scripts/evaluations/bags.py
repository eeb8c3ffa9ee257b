"""ROS recordings through `stereo-distance depth-map --bag` (issue 95), on real photographs:
OpenCV's 13 stereo pairs (Apache-2.0 AND BSD-3-Clause, tests/data/photographs/opencv-stereo),
their CameraInfo from POST /calibrate (ros-left.yaml, ros-right.yaml), recorded into bags by
the field's own Python libraries:

- a ROS 2 MCAP bag by `rosbags` 0.11.9 (sensor_msgs/Image bgr8, 30 frames/s);
- a ROS 2 MCAP file by `mcap` 1.6.0 with `mcap-ros2-support` 0.6.0 (CompressedImage JPEG);
- a ROS 1 bag by `rosbags` (Image mono8);
- a ROS 2 bag with dropped frames and the right camera 5 ms late;
- and broken ones: cut off mid-chunk, a wrong encoding, a topic that does not exist, a
  CameraInfo without D.

Each is run through the command into an MCAP file of ROS 2 messages, read back with `rosbags`
and with `mcap-ros2-support`. Floors: every pair processed (every true pair of the dropped
bag, every orphan named); the depth image (32FC1, metres) equal to POST /depth-map's depth.npy
for the same pair and calibration (the same pixels); the DisparityImage's f·t/d equal to the
depth; the point cloud's z equal to the depth; each broken bag refused by name, the pairs
before a cut written and readable. The frames per second from the bag beside the same frames
from a folder (median of paired rounds) are printed, not asserted.
"""

import argparse
import io
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import yaml

from .service import load_npy, post_once

NAMES = ["01", "02", "03", "04", "05", "06", "07", "08", "09", "11", "12", "13", "14"]
BOARD = {"columns": 9, "rows": 6, "square_size": 25.0, "unit": "mm"}
START_NS = 1_700_000_000_000_000_000
FRAME_NS = 33_333_333
NS = "/stereo"

# The ROS 2 definitions mcap-ros2-support's writer needs (as `ros2 bag record` stores them).
HEADER_DEFS = ("=" * 80 + "\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
               + "=" * 80 + "\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n")
IMAGE_DEF = ("std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
             "uint8 is_bigendian\nuint32 step\nuint8[] data\n" + HEADER_DEFS)
COMPRESSED_DEF = "std_msgs/Header header\nstring format\nuint8[] data\n" + HEADER_DEFS
INFO_DEF = ("std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
            "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n"
            "uint32 binning_y\nsensor_msgs/RegionOfInterest roi\n" + HEADER_DEFS + "=" * 80
            + "\nMSG: sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\n"
            "uint32 height\nuint32 width\nbool do_rectify\n")


def camera_info(text):
    """A ros-*.yaml's CameraInfo members."""
    doc = yaml.safe_load(text)
    return {
        "width": doc["image_width"], "height": doc["image_height"],
        "model": doc["distortion_model"],
        "d": doc["distortion_coefficients"]["data"], "k": doc["camera_matrix"]["data"],
        "r": doc["rectification_matrix"]["data"], "p": doc["projection_matrix"]["data"],
    }


class Frames:
    """The pairs as recorded: each camera's stamp and image, with frames dropped and a skew."""

    def __init__(self, pairs, skew_ns=0, drop_left=(), drop_right=(), repeat=1):
        self.left, self.right = [], []
        for k in range(len(pairs) * repeat):
            l, r = pairs[k % len(pairs)]
            stamp = START_NS + k * FRAME_NS
            if k not in drop_left:
                self.left.append((stamp, l))
            if k not in drop_right:
                self.right.append((stamp + skew_ns, r))

    def interleaved(self):
        """(camera, stamp, image) in recording order."""
        out = [("left", s, i) for s, i in self.left] + [("right", s, i) for s, i in self.right]
        return sorted(out, key=lambda e: (e[1], e[0]))


def messages(typestore, stamp, image, info, encoding, frame, ros1):
    """The image message (with its type's name) and the CameraInfo of one frame, as rosbags
    types (ROS 1's Header has a seq, its CameraInfo's arrays are D, K, R, P)."""
    t = typestore.types
    stamp_msg = t["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9)
    header = (t["std_msgs/msg/Header"](seq=0, stamp=stamp_msg, frame_id=frame) if ros1 else
              t["std_msgs/msg/Header"](stamp=stamp_msg, frame_id=frame))
    if encoding == "jpeg":
        ok, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 95])
        kind = "sensor_msgs/msg/CompressedImage"
        msg = t[kind](header=header, format="jpeg", data=np.frombuffer(jpeg.tobytes(), np.uint8))
    else:
        grey = encoding in ("mono8", "yuv422")
        pixels = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if grey else image
        kind = "sensor_msgs/msg/Image"
        msg = t[kind](header=header, height=image.shape[0], width=image.shape[1],
                      encoding=encoding, is_bigendian=0,
                      step=image.shape[1] * (1 if grey else 3),
                      data=np.ascontiguousarray(pixels).reshape(-1).astype(np.uint8))
    roi = t["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0,
                                                do_rectify=False)
    arrays = {name: np.array(info[name.lower()], float) for name in "DKRP"}
    if not ros1:
        arrays = {k.lower(): v for k, v in arrays.items()}
    info_msg = t["sensor_msgs/msg/CameraInfo"](
        header=header, height=info["height"], width=info["width"],
        distortion_model=info["model"], binning_x=0, binning_y=0, roi=roi, **arrays)
    return kind, msg, info_msg


def write_rosbags(path, frames, infos, encoding="bgr8", ros1=False, drop_d=False):
    """A bag written by rosbags: ROS 2 MCAP (a rosbag2 folder), or ROS 1."""
    from rosbags.typesys import Stores, get_typestore
    if ros1:
        from rosbags.rosbag1 import Writer
        typestore = get_typestore(Stores.ROS1_NOETIC)
        writer = Writer(path)
        serialize = typestore.serialize_ros1
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer
        typestore = get_typestore(Stores.ROS2_HUMBLE)
        writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        serialize = typestore.serialize_cdr
    image_topic = "image_raw/compressed" if encoding == "jpeg" else "image_raw"
    connections = {}
    with writer:
        for camera, stamp, image in frames.interleaved():
            info = dict(infos[camera], d=[] if drop_d else infos[camera]["d"])
            kind, msg, info_msg = messages(typestore, stamp, image, info, encoding,
                                           f"{camera}_camera_optical_frame", ros1)
            for topic, kind_of, m in [(f"{NS}/{camera}/{image_topic}", kind, msg),
                                      (f"{NS}/{camera}/camera_info",
                                       "sensor_msgs/msg/CameraInfo", info_msg)]:
                if topic not in connections:
                    connections[topic] = writer.add_connection(topic, kind_of, typestore=typestore)
                writer.write(connections[topic], stamp, serialize(m, kind_of))


def write_mcap_library(path, frames, infos):
    """An MCAP file written by the mcap library with mcap-ros2-support: CompressedImage JPEG."""
    from mcap_ros2.writer import Writer
    with open(path, "wb") as f:
        writer = Writer(f)
        compressed = writer.register_msgdef("sensor_msgs/msg/CompressedImage", COMPRESSED_DEF)
        info_schema = writer.register_msgdef("sensor_msgs/msg/CameraInfo", INFO_DEF)
        for camera, stamp, image in frames.interleaved():
            header = {"stamp": {"sec": stamp // 10**9, "nanosec": stamp % 10**9},
                      "frame_id": f"{camera}_camera_optical_frame"}
            ok, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 95])
            writer.write_message(f"{NS}/{camera}/image_raw/compressed", compressed,
                                 {"header": header, "format": "jpeg", "data": jpeg.tobytes()},
                                 log_time=stamp, publish_time=stamp)
            info = infos[camera]
            writer.write_message(f"{NS}/{camera}/camera_info", info_schema, {
                "header": header, "height": info["height"], "width": info["width"],
                "distortion_model": info["model"], "d": info["d"], "k": info["k"],
                "r": info["r"], "p": info["p"], "binning_x": 0, "binning_y": 0,
                "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0,
                        "do_rectify": False}}, log_time=stamp, publish_time=stamp)
        writer.finish()
def read_rosbags(path):
    """The messages of an MCAP file by topic, read with rosbags: {topic: [(time, msg)]}."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    out = {}
    with AnyReader([Path(path)], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        for conn, t, raw in reader.messages():
            out.setdefault(conn.topic, []).append((t, reader.deserialize(raw, conn.msgtype)))
    return out


def read_mcap_ros2(path):
    """The messages of an MCAP file by topic, decoded by mcap-ros2-support."""
    from mcap_ros2.reader import read_ros2_messages
    out = {}
    for m in read_ros2_messages(str(path)):
        out.setdefault(m.channel.topic, []).append((m.log_time_ns, m.ros_msg))
    return out


def float_image(msg):
    """A 32FC1 sensor_msgs/Image as an array."""
    assert msg.encoding == "32FC1", msg.encoding
    return np.frombuffer(bytes(msg.data), "<f4").reshape(msg.height, msg.width)


def run(binary, *args):
    """The command run to its end: its exit code and stderr."""
    done = subprocess.run([binary, "depth-map", *map(str, args)], capture_output=True, text=True,
                          timeout=600)
    return done.returncode, done.stderr


def frames_per_second(stderr):
    for line in stderr.splitlines():
        if "frames/s" in line:
            return float(line.split("; ")[-1].split(" frames/s")[0])
    sys.exit(f"no frames/s in: {stderr}")


def check_output(path, reference, stamps, label, failures):
    """The output MCAP read with both libraries: every pair's messages on every topic, the
    depth equal to /depth-map's, f·t/d and the cloud's z equal to the depth."""
    worst = 0.0
    for reader_name, reader in [("rosbags", read_rosbags), ("mcap-ros2-support", read_mcap_ros2)]:
        topics = reader(path)
        want = [f"{NS}/{t}" for t in ("disparity", "depth/image_rect", "depth/image_rect_std",
                                      "points2", "left/image_rect_color", "left/camera_info")]
        for topic in want:
            got = [t for t, _ in topics.get(topic, [])]
            if sorted(got) != sorted(stamps):
                failures.append(f"{label} ({reader_name}): {topic} has {len(got)} messages, "
                                f"want {len(stamps)} at the pairs' stamps")
                return worst
        by_stamp = lambda topic: dict(topics[f"{NS}/{topic}"])
        depths, disparities = by_stamp("depth/image_rect"), by_stamp("disparity")
        clouds, infos = by_stamp("points2"), by_stamp("left/camera_info")
        for k, stamp in enumerate(stamps):
            depth = float_image(depths[stamp])
            want_m = reference[k]  # the CameraInfo's baseline is in metres, so is the rig
            same_mask = np.array_equal(np.isnan(depth), np.isnan(want_m))
            finite = ~np.isnan(depth)
            err = float(np.max(np.abs(depth[finite] - want_m[finite]) / want_m[finite])) \
                if finite.any() else 0.0
            worst = max(worst, err)
            if not same_mask or err > 1e-6:
                failures.append(f"{label} ({reader_name}) pair {k}: the depth differs from "
                                f"/depth-map's (same NaNs: {same_mask}, worst {err:.2e})")
            d = disparities[stamp]
            with np.errstate(divide="ignore"):
                z_from_d = d.f * d.t / float_image(d.image)
            rel = np.abs(z_from_d[finite] - depth[finite]) / depth[finite]
            if finite.any() and float(np.max(rel)) > 1e-4:
                failures.append(f"{label} ({reader_name}) pair {k}: f·t/d is not the depth "
                                f"({float(np.max(rel)):.2e})")
            cloud = clouds[stamp]
            names = [f.name for f in cloud.fields]
            if names != ["x", "y", "z", "rgb", "depth_std"] or cloud.width != int(finite.sum()):
                failures.append(f"{label} ({reader_name}) pair {k}: the cloud has {names}, "
                                f"{cloud.width} points for {int(finite.sum())} depths")
            else:
                points = np.frombuffer(bytes(cloud.data), "<f4").reshape(-1, 5)
                if not np.allclose(np.sort(points[:, 2]), np.sort(depth[finite]), rtol=1e-6):
                    failures.append(f"{label} ({reader_name}) pair {k}: the cloud's z is not the "
                                    "depth")
            if depths[stamp].header.frame_id != "left_camera_optical_frame":
                failures.append(f"{label}: frame_id {depths[stamp].header.frame_id!r}")
            info = infos[stamp]
            if (info.width, info.height) != (depth.shape[1], depth.shape[0]):
                failures.append(f"{label}: the CameraInfo's size is not the depth's")
    return worst


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--url", required=True)
    parser.add_argument("--binary", required=True)
    parser.add_argument("--photographs", required=True)
    parser.add_argument("--work", required=True)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json")
    args = parser.parse_args()
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    folder = Path(args.photographs)
    images = [(cv2.imread(str(folder / f"left{n}.jpg")), cv2.imread(str(folder / f"right{n}.jpg")))
              for n in NAMES]
    parts = []
    for n in NAMES:
        parts.append(("left", ((folder / f"left{n}.jpg").read_bytes(), f"left{n}.jpg", "image/jpeg")))
        parts.append(("right", ((folder / f"right{n}.jpg").read_bytes(), f"right{n}.jpg",
                                "image/jpeg")))
    board = ("board", (json.dumps(BOARD).encode(), None, "application/json"))
    ros = {side: post_once(args.url, f"/calibrate?output=ros-{side}.yaml", parts + [board])
           for side in ("left", "right")}
    infos = {side: camera_info(text) for side, text in ros.items()}
    calibration = [("calibration", (ros["left"], "ros-left.yaml", "application/yaml")),
                   ("right_calibration", (ros["right"], "ros-right.yaml", "application/yaml"))]

    def reference(encode):
        out = []
        for l, r in images:
            pair = [("left", (encode(l), "l", "image/png")), ("right", (encode(r), "r", "image/png"))]
            out.append(load_npy(post_once(args.url, "/depth-map?output=depth.npy",
                                          pair + calibration)))
        return out

    png = lambda image: cv2.imencode(".png", image)[1].tobytes()
    jpeg = lambda image: cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()
    raw_reference, jpeg_reference = reference(png), reference(jpeg)
    stamps = [START_NS + k * FRAME_NS for k in range(len(images))]
    failures, results = [], {}

    # Whole bags, each through the command into MCAP, read back with both libraries.
    whole = Frames(images)
    write_rosbags(work / "rosbags-ros2", whole, infos, "bgr8")
    write_mcap_library(work / "mcap-library.mcap", whole, infos)
    write_rosbags(work / "rosbags-ros1.bag", whole, infos, "mono8", ros1=True)
    for label, bag, ref in [
        ("ROS 2 MCAP by rosbags, Image bgr8", work / "rosbags-ros2", raw_reference),
        ("MCAP by mcap + mcap-ros2-support, CompressedImage JPEG", work / "mcap-library.mcap",
         jpeg_reference),
        ("ROS 1 bag by rosbags, Image mono8", work / "rosbags-ros1.bag", raw_reference),
    ]:
        out = work / (bag.name.split(".")[0] + "-out.mcap")
        code, stderr = run(args.binary, "--bag", bag, "--out", out)
        if code != 0:
            failures.append(f"{label}: exit {code}: {stderr[-800:]}")
            continue
        worst = check_output(out, ref, stamps, label, failures)
        results[label] = {"pairs": len(stamps), "worst_relative_depth_error": worst,
                          "frames_per_second": frames_per_second(stderr)}
        print(f"{label}: {len(stamps)} of {len(stamps)} pairs; depth equal to /depth-map's "
              f"within {worst:.1e} (relative), read back by rosbags and mcap-ros2-support; "
              f"{frames_per_second(stderr):.2f} frames/s")

    # Dropped frames and a 5 ms skew: every true pair, every orphan named; into a folder.
    dropped = Frames(images, skew_ns=5_000_000, drop_left={8}, drop_right={3})
    write_rosbags(work / "dropped", dropped, infos, "bgr8")
    out = work / "dropped-out"
    code, stderr = run(args.binary, "--bag", work / "dropped", "--out", out)
    written = sorted(out.glob("*.depth.npy"))
    true_pairs = len(images) - 2
    orphans = [line for line in stderr.splitlines() if line.startswith("skipped ")]
    lost = [("left", START_NS + 3 * FRAME_NS), ("right", START_NS + 8 * FRAME_NS + 5_000_000)]
    named = all(any(f"{NS}/{side}/image_raw at {t // 10**9}.{t % 10**9:09d}" in o for o in orphans)
                for side, t in lost)
    print(f"dropped frames, right 5 ms late: {len(written)} of {true_pairs} true pairs written, "
          f"{len(orphans)} orphans named: " + "; ".join(orphans))
    if len(written) != true_pairs or len(orphans) != 2 or not named or code != 1:
        failures.append(f"the dropped bag: {len(written)} written, orphans {orphans}, exit {code}")
    results["dropped"] = {"written": len(written), "true_pairs": true_pairs, "orphans": orphans}

    # Broken bags: each refused by name; a cut one keeps what came before the cut.
    source = next((work / "rosbags-ros2").glob("*.mcap"))
    data = source.read_bytes()
    (work / "cut.mcap").write_bytes(data[: len(data) * 6 // 10])
    cut_out = work / "cut-out.mcap"
    code, stderr = run(args.binary, "--bag", work / "cut.mcap", "--out", cut_out)
    kept = len(read_mcap_ros2(cut_out).get(f"{NS}/depth/image_rect", [])) if cut_out.exists() else 0
    print(f"cut off at 60 %: exit {code}, {kept} pairs written and readable; "
          f"{stderr.strip().splitlines()[-1]}")
    if code != 1 or "cut off" not in stderr or kept < 5:
        failures.append(f"the cut bag: exit {code}, {kept} readable, {stderr[-400:]}")
    write_rosbags(work / "yuv", Frames(images[:2]), infos, "yuv422")
    code, stderr = run(args.binary, "--bag", work / "yuv", "--out", work / "yuv-out")
    print(f"a wrong encoding: exit {code}; " + next((l for l in stderr.splitlines()
                                                    if l.startswith("failed")), "?"))
    if code != 1 or "encoding `yuv422` is not one read here" not in stderr:
        failures.append(f"the yuv422 bag: {stderr[-400:]}")
    code, stderr = run(args.binary, "--bag", work / "rosbags-ros2", "--left-topic", "/cam0/image",
                       "--out", work / "topic-out")
    print(f"a topic that does not exist: exit {code}; {stderr.strip()}")
    if code != 1 or "no such image topic" not in stderr or "/stereo/left/image_raw" not in stderr:
        failures.append(f"the wrong topic: {stderr[-400:]}")
    write_rosbags(work / "no-d", Frames(images[:2]), infos, "bgr8", drop_d=True)
    code, stderr = run(args.binary, "--bag", work / "no-d", "--out", work / "no-d-out")
    print(f"a CameraInfo without D: exit {code}; {stderr.strip()}")
    if code != 1 or "/stereo/left/camera_info: it has no D" not in stderr:
        failures.append(f"the CameraInfo without D: {stderr[-400:]}")

    # Throughput: the same frames (PNG files in a folder, Image bgr8 in the bag) and the same
    # calibration file, in turns, to folders of depth.npy.
    opencv = work / "opencv.yml"
    opencv.write_bytes(post_once(args.url, "/calibrate?output=opencv.yml", parts + [board]))
    pngs = work / "folder"
    pngs.mkdir(exist_ok=True)
    for n, (l, r) in zip(NAMES, images):
        (pngs / f"left{n}.png").write_bytes(png(l))
        (pngs / f"right{n}.png").write_bytes(png(r))
    speeds = {"folder": [], "bag": []}
    for k in range(args.rounds):
        for name, source in [("folder", ["--frames", pngs]),
                             ("bag", ["--bag", work / "rosbags-ros2"])]:
            code, stderr = run(args.binary, *source, "--calibration", opencv,
                               "--out", work / f"speed-{name}-{k}")
            if code != 0:
                failures.append(f"the {name} speed run: {stderr[-400:]}")
                break
            speeds[name].append(frames_per_second(stderr))
    if all(speeds.values()):
        ratios = [b / f for f, b in zip(speeds["folder"], speeds["bag"])]
        results["speed"] = {**speeds, "ratio_median": statistics.median(ratios)}
        print(f"frames/s, {len(ratios)} paired rounds: folder "
              f"{statistics.median(speeds['folder']):.2f}, bag {statistics.median(speeds['bag']):.2f};"
              f" bag/folder {statistics.median(ratios):.3f} (median of the rounds' ratios)")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2))
    if failures:
        print("\nFAILED:\n  " + "\n  ".join(failures))
        sys.exit(1)
    print("\nall floors met")


if __name__ == "__main__":
    main()
