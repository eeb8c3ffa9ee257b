// Live mode's camera: one device giving both images side by side, or two devices, opened
// with getUserMedia into the page's video elements; a frame encoded as the stream's layout
// wants it, and a pair cut out as two JPEG files for /board and /calibrate.

import { $ } from './util.js';

/** The JPEG quality frames are streamed at. */
const JPEG_QUALITY = 0.9;

const camera = { streams: [] };

/** Whether a camera is open. */
export function cameraOpen() {
  return camera.streams.length > 0;
}

/** Whether the page may open a camera: browsers give them to secure pages only. */
export function cameraAllowed() {
  return window.isSecureContext && !!navigator.mediaDevices && !!navigator.mediaDevices.getUserMedia;
}

/** The cameras, once the browser lets the page name them (after a first permission). */
export async function listCameras() {
  const devices = (await navigator.mediaDevices.enumerateDevices()).filter((d) => d.kind === 'videoinput');
  for (const id of ['live-camera', 'live-camera-right']) {
    const select = $(id);
    const chosen = select.value;
    const first = select.options[0];
    select.replaceChildren(first, ...devices.map((d, i) => {
      const option = document.createElement('option');
      option.value = d.deviceId;
      option.textContent = d.label || `Camera ${i + 1}`;
      return option;
    }));
    select.value = chosen;
  }
}

/** Opens the camera(s) into the page's video elements. */
export async function openCameras() {
  const pairOfDevices = $('live-layout').value === 'pair';
  const ids = pairOfDevices ? [$('live-camera').value, $('live-camera-right').value] : [$('live-camera').value];
  // USB stereo cameras give both images side by side in one wide frame: ask for it.
  const size = pairOfDevices ? { width: { ideal: 1280 }, height: { ideal: 720 } } : { width: { ideal: 2560 }, height: { ideal: 720 } };
  camera.streams = [];
  const videos = [$('live-video'), $('live-video-right')];
  for (const [i, id] of ids.entries()) {
    const video = id ? { ...size, deviceId: { exact: id } } : size;
    const stream = await navigator.mediaDevices.getUserMedia({ video, audio: false });
    camera.streams.push(stream);
    videos[i].srcObject = stream;
    await videos[i].play();
  }
}

export function closeCameras() {
  for (const stream of camera.streams) for (const track of stream.getTracks()) track.stop();
  camera.streams = [];
}

/** One frame from the camera(s), encoded as the layout wants, and its left image. */
export async function capture() {
  const video = $('live-video');
  const canvas = document.createElement('canvas');
  const jpeg = (c) => new Promise((resolve) => c.toBlob(resolve, 'image/jpeg', JPEG_QUALITY));
  if ($('live-layout').value === 'pair') {
    const right = $('live-video-right');
    const grab = (v) => {
      const c = document.createElement('canvas');
      c.width = v.videoWidth;
      c.height = v.videoHeight;
      c.getContext('2d').drawImage(v, 0, 0);
      return c;
    };
    const [l, r] = [grab(video), grab(right)];
    const [lb, rb] = await Promise.all([jpeg(l), jpeg(r)]);
    const [la, ra] = await Promise.all([lb.arrayBuffer(), rb.arrayBuffer()]);
    const bytes = new Uint8Array(4 + la.byteLength + ra.byteLength);
    new DataView(bytes.buffer).setUint32(0, la.byteLength, true);
    bytes.set(new Uint8Array(la), 4);
    bytes.set(new Uint8Array(ra), 4 + la.byteLength);
    return { bytes, left: await createImageBitmap(l) };
  }
  canvas.width = video.videoWidth;
  canvas.height = video.videoHeight;
  canvas.getContext('2d').drawImage(video, 0, 0);
  const blob = await jpeg(canvas);
  const left = await createImageBitmap(canvas, 0, 0, Math.floor(canvas.width / 2), canvas.height);
  return { bytes: await blob.arrayBuffer(), left };
}

/** The current frame's two images as JPEG files, and the left one to draw. */
export async function grabPair(n) {
  const jpeg = (c) => new Promise((resolve) => c.toBlob(resolve, 'image/jpeg', 0.95));
  const cut = (video, x, w) => {
    const c = document.createElement('canvas');
    c.width = w;
    c.height = video.videoHeight;
    c.getContext('2d').drawImage(video, x, 0, w, c.height, 0, 0, w, c.height);
    return c;
  };
  const video = $('live-video');
  const [l, r] = $('live-layout').value === 'pair'
    ? [cut(video, 0, video.videoWidth), cut($('live-video-right'), 0, $('live-video-right').videoWidth)]
    : [cut(video, 0, Math.floor(video.videoWidth / 2)), cut(video, Math.floor(video.videoWidth / 2), Math.floor(video.videoWidth / 2))];
  const [lb, rb] = await Promise.all([jpeg(l), jpeg(r)]);
  return {
    left: new File([lb], `live_${n}_left.jpg`, { type: 'image/jpeg' }),
    right: new File([rb], `live_${n}_right.jpg`, { type: 'image/jpeg' }),
    bitmap: await createImageBitmap(l),
  };
}
