"""Streams stereo frames through GET /depth-stream and prints each frame's median distance:
a folder of side-by-side images (or a camera giving both side by side, by its index), or, with
--right, the left and right images as two folders (or two cameras). Needs websockets, numpy,
OpenCV.

    python stream.py FOLDER_OR_CAMERA CALIBRATION_FILE [ws://127.0.0.1:8080/depth-stream]
    python stream.py LEFT_FOLDER CALIBRATION_FILE --right RIGHT_FOLDER
    python stream.py 0 rig.txt --unit mm --option max_disparity=96 --option preset=accurate

--unit gives the calibration's length unit where the file does not say it; --option passes
any of /depth-map's options (the range is found from the frames unless max_disparity is given).
"""
import argparse, glob, io, json, os, struct, sys

import cv2
import numpy as np
from websockets.sync.client import connect

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("source", help="a folder of frames, or a camera's index")
parser.add_argument("calibration", help="the rig's calibration file")
parser.add_argument("url", nargs="?", default="ws://127.0.0.1:8080/depth-stream")
parser.add_argument("--right", help="the right images' folder or camera: frames sent as pairs")
parser.add_argument("--unit", help="the calibration's length unit, where the file has none")
parser.add_argument("--option", action="append", default=[], metavar="NAME=VALUE",
                    help="one of /depth-map's options, repeated as needed")
args = parser.parse_args()


def images(source):
    """Each image of a folder (in name order) or of a camera, as JPEG or PNG bytes."""
    if source.isdigit():
        camera = cv2.VideoCapture(int(source))
        while (grabbed := camera.read())[0]:
            yield cv2.imencode(".jpg", grabbed[1])[1].tobytes()
    else:
        paths = sorted(glob.glob(os.path.join(source, "*.png"))
                       + glob.glob(os.path.join(source, "*.jpg")))
        for path in paths:
            with open(path, "rb") as f:
                yield f.read()


def frames():
    """Side-by-side frames as they come, or a pair frame: the left image's length (4 bytes,
    little-endian), the left image, the right image."""
    if args.right is None:
        yield from images(args.source)
    else:
        for left, right in zip(images(args.source), images(args.right)):
            yield struct.pack("<I", len(left)) + left + right


def option(text):
    name, _, value = text.partition("=")
    try:
        return name, json.loads(value)
    except ValueError:
        return name, value


settings = {"layout": "side_by_side" if args.right is None else "pair",
            "calibration": open(args.calibration).read(), "outputs": ["depth.npy"],
            "options": dict(option(o) for o in args.option)}
if args.unit:
    settings["calibration_unit"] = args.unit

with connect(args.url, max_size=None) as ws:
    ws.send(json.dumps(settings))
    resolved = json.loads(ws.recv())
    if resolved["type"] == "error":
        sys.exit(resolved["problem"]["detail"])
    for frame in frames():
        ws.send(frame)
        answer = json.loads(ws.recv())
        if answer["type"] == "error":
            print(answer["id"], answer["problem"]["detail"])
            continue
        depth = np.load(io.BytesIO(ws.recv()))  # float32 in the rig's unit, NaN where unknown
        print(answer["id"], f"{np.nanmedian(depth):.0f} {resolved['rig']['unit']}",
              f"{answer['times_ms']['total']:.0f} ms")
