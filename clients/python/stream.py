"""Streams side-by-side stereo frames (a folder of images, or a camera by its index) through
GET /depth-stream and prints each frame's median distance. Needs websockets, numpy, OpenCV.

    python stream.py FOLDER_OR_CAMERA CALIBRATION_FILE [ws://127.0.0.1:8080/depth-stream]
"""
import glob, io, json, sys

import cv2
import numpy as np
from websockets.sync.client import connect

source, calibration = sys.argv[1], open(sys.argv[2]).read()
url = sys.argv[3] if len(sys.argv) > 3 else "ws://127.0.0.1:8080/depth-stream"


def frames():
    if source.isdigit():  # a USB stereo camera: one side-by-side image a frame
        camera = cv2.VideoCapture(int(source))
        while (grabbed := camera.read())[0]:
            yield cv2.imencode(".jpg", grabbed[1])[1].tobytes()
    else:
        for path in sorted(glob.glob(f"{source}/*.png") + glob.glob(f"{source}/*.jpg")):
            yield open(path, "rb").read()


with connect(url, max_size=None) as ws:
    ws.send(json.dumps({"calibration": calibration, "calibration_unit": "mm",
                        "outputs": ["depth.npy"]}))
    settings = json.loads(ws.recv())
    if settings["type"] == "error":
        sys.exit(settings["problem"]["detail"])
    for frame in frames():
        ws.send(frame)
        answer = json.loads(ws.recv())
        if answer["type"] == "error":
            print(answer["id"], answer["problem"]["detail"])
            continue
        depth = np.load(io.BytesIO(ws.recv()))  # float32 in mm, NaN where unknown
        print(answer["id"], f"{np.nanmedian(depth):.0f} mm", f"{answer['times_ms']['total']:.0f} ms")
