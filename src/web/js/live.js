// Live mode: a stereo camera (one device giving both images side by side, or two devices)
// opened with getUserMedia and streamed through GET /depth-stream; each answer's depth drawn
// over the left image it was matched from, with frames a second, latency and drops; Z ± σ
// under the pointer from the answer's arrays, and a click's distance through /distance with
// the rig the answer states; and board views grabbed from the camera (/board finds the board
// in each frame, its outline drawn, a view kept when both cameras see it and it has moved),
// handed to Calibrate mode, whose result comes back here and is streamed with at once. The
// page computes no distance itself.

import { openSocket, post, postJson, problemsOf, readNpz } from './api.js';
import { colourRange, drawColourBar, sizeCanvas, svg, turbo } from './draw.js';
import { readForm, rigGiven, rigPart } from './rig.js';
import { EVENTS, emit } from './store.js';
import {
  cameraAllowed, cameraOpen, capture, closeCameras, grabPair, listCameras, openCameras,
} from './live-camera.js';
import { $, fmt, listItem, page } from './util.js';

/** Frames in flight at most: the service matches two at once, so a third would only wait. */
const IN_FLIGHT = 2;
/** Answers the frame rate and the latency are taken over. */
const WINDOW = 20;

const live = {
  socket: null,
  running: false,
  capturing: false,
  /** Frames sent and not yet answered: id → { sent (ms), left (ImageBitmap) }. */
  waiting: new Map(),
  sent: 0,
  /** The answer being read: its JSON and the files still to come. */
  answer: null,
  files: [],
  /** The last answer's arrays ({ width, height, disparity, depth, disparity_std, depth_std }),
   * its rig (as the summary states it, at the frames' size) and its unit. */
  arrays: null,
  rig: null,
  unit: 'px',
  answeredAt: [],
  latencies: [],
  drops: { frames: 0, answers: 0 },
  /** The calibration file's text, when one was chosen. */
  fileText: null,
  /** Answers are received but not shown: the frame shown stays to be measured. */
  paused: false,
  /** Board views: grabbing, and the pairs kept ({ left, right: File, outline, corners }). */
  grabbing: false,
  views: [],
};

const status = (text) => {
  $('live-status').textContent = text;
};

function showErrors(errors) {
  const list = $('live-errors-list');
  list.replaceChildren(...errors.map(({ field, message }) => listItem(`${field}: ${message}`)));
  $('live-errors').hidden = errors.length === 0;
}

/** The settings message: the layout, the rig (the calibration in use, a file, or none), the
 * search range, the files (all the arrays, as one NPZ) and the temporal filter. `null` with
 * the reason when the calibration asked for is missing. */
function settings() {
  const layout = $('live-layout').value;
  const message = { layout, outputs: ['arrays.npz'], temporal: $('live-temporal').checked };
  const max = $('live-max-disparity').value.trim();
  if (max !== '') message.options = { max_disparity: Number.isFinite(Number(max)) ? Number(max) : max };
  const choice = $('live-calibration').value;
  const used = nameInUse();
  if (choice === 'file') {
    if (live.fileText === null) return { reason: 'Choose the calibration file first.' };
    message.calibration = live.fileText;
    if ($('live-calibration-unit').value !== '') message.calibration_unit = $('live-calibration-unit').value;
  } else if (choice === 'in-use') {
    if (used === 'calibration') {
      const { request } = page.calibration;
      message.calibration = request.text;
      if (request.right_text) message.right_calibration = request.right_text;
      if (request.calibration_unit) message.calibration_unit = request.calibration_unit;
    } else if (used === 'rig') {
      message.rig = JSON.parse(rigPart(readForm()));
    } else {
      return { reason: 'No calibration in use: calibrate in Calibrate mode, import one under Inputs, or choose a file.' };
    }
  }
  return { message };
}

/** Sends the next frame while fewer than two are in flight. */
async function pump() {
  if (!live.running || live.capturing || live.waiting.size >= IN_FLIGHT) return;
  if (!live.socket || live.socket.readyState !== WebSocket.OPEN) return;
  if ($('live-video').readyState < 2) {
    setTimeout(pump, 50);
    return;
  }
  live.capturing = true;
  try {
    const { bytes, left } = await capture();
    if (!live.running) return;
    live.sent += 1;
    live.waiting.set(live.sent, { sent: performance.now(), left });
    live.socket.send(bytes);
  } finally {
    live.capturing = false;
  }
  pump();
}

/** Frames a second over the last answers, and their median latency. */
function showStats() {
  const times = live.answeredAt;
  const fps = times.length > 1 ? (1000 * (times.length - 1)) / (times[times.length - 1] - times[0]) : NaN;
  const sorted = [...live.latencies].sort((a, b) => a - b);
  const latency = sorted.length ? sorted[Math.floor(sorted.length / 2)] : NaN;
  const stats = $('live-stats');
  stats.dataset.fps = String(fps);
  stats.dataset.latency = String(latency);
  stats.dataset.frames = String(times.length);
  stats.textContent = `${Number.isFinite(fps) ? fps.toFixed(1) : '–'} frames a second, latency ${Number.isFinite(latency) ? latency.toFixed(0) : '–'} ms (median of the last ${sorted.length}), dropped: ${live.drops.frames} frames, ${live.drops.answers} answers.`;
}

/** Forgets frames answered or dropped up to `id` (the service answers in order). */
function settle(id) {
  let left = null;
  for (const [k, v] of live.waiting) {
    if (k > id) break;
    if (k === id) left = v;
    else v.left.close();
    live.waiting.delete(k);
  }
  return left;
}

/** A frame's answer, its files read: the arrays kept, drawn over the frame's left image. */
function answered(answer, files) {
  const now = performance.now();
  const frame = settle(answer.id);
  live.drops = { frames: answer.dropped_frames, answers: answer.dropped_answers };
  if (frame) {
    live.latencies.push(now - frame.sent);
    if (live.latencies.length > WINDOW) live.latencies.shift();
  }
  live.answeredAt.push(now);
  if (live.answeredAt.length > WINDOW) live.answeredAt.shift();
  if (live.paused) {
    if (frame) frame.left.close();
    showStats();
    pump();
    return;
  }
  const arrays = readNpz(files[0]);
  const a = arrays.disparity;
  live.arrays = {
    width: a.width,
    height: a.height,
    disparity: a.data,
    disparity_std: arrays.disparity_std.data,
    depth: arrays.depth ? arrays.depth.data : null,
    depth_std: arrays.depth_std ? arrays.depth_std.data : null,
  };
  live.rig = answer.summary.rig ?? null;
  live.unit = live.rig ? live.rig.unit : 'px';
  draw(frame ? frame.left : null);
  if (frame) frame.left.close();
  showStats();
  const density = answer.summary.valid_fraction;
  const median = answer.summary.distance ? `, median ${fmt(answer.summary.distance.median, 4)} ${live.unit}` : '';
  status(`Frame ${answer.id}: ${(100 * density).toFixed(1)} % of pixels with depth${median}; ${answer.times_ms.total.toFixed(0)} ms in the service.`);
  $('live-status').dataset.frames = String(answer.id);
  pump();
}

/** The depth in Turbo on inverse depth (near warm) over the left image. */
function draw(left) {
  const a = live.arrays;
  const canvas = $('live-canvas');
  const depthCanvas = $('live-depth-canvas');
  sizeCanvas(canvas, a.width, a.height);
  sizeCanvas(depthCanvas, a.width, a.height);
  $('live-overlay').setAttribute('viewBox', `0 0 ${a.width} ${a.height}`);
  if (left) canvas.getContext('2d').drawImage(left, 0, 0, a.width, a.height);
  const values = a.depth ?? a.disparity.map((d) => (d > 0 ? 1 / d : NaN));
  const range = colourRange(values);
  const image = new ImageData(a.width, a.height);
  if (range) {
    const [near, far] = range;
    const span = 1 / near - 1 / far;
    for (let i = 0; i < values.length; i += 1) {
      if (!(values[i] > 0)) continue;
      const [r, g, b] = turbo((1 / values[i] - 1 / far) / span);
      image.data.set([r, g, b, 255], i * 4);
    }
  }
  depthCanvas.getContext('2d').putImageData(image, 0, 0);
  drawColourBar(range, a.depth ? live.unit : 'px', 'live-colour-bar');
}

/** The image pixel under a pointer event. */
function pixelAt(event) {
  const a = live.arrays;
  const rect = $('live-frame').getBoundingClientRect();
  const x = Math.floor(((event.clientX - rect.left) * a.width) / rect.width);
  const y = Math.floor(((event.clientY - rect.top) * a.height) / rect.height);
  return { x: Math.min(a.width - 1, Math.max(0, x)), y: Math.min(a.height - 1, Math.max(0, y)) };
}

function hover(event) {
  const a = live.arrays;
  if (!a) return;
  const { x, y } = pixelAt(event);
  const i = y * a.width + x;
  const [d, sd] = [a.disparity[i], a.disparity_std[i]];
  const line = $('live-hover');
  if (a.depth && Number.isFinite(a.depth[i])) {
    line.textContent = `(${x}, ${y}): Z = ${fmt(a.depth[i], 5)} ± ${fmt(a.depth_std[i], 3)} ${live.unit}, d = ${fmt(d, 4)} ± ${fmt(sd, 3)} px`;
  } else if (Number.isFinite(d)) {
    line.textContent = `(${x}, ${y}): d = ${fmt(d, 4)} ± ${fmt(sd, 3)} px; distances need a calibration`;
  } else {
    line.textContent = `(${x}, ${y}): no reliable depth here`;
  }
}

/** The members /distance takes of the rig an answer states. */
const RIG_MEMBERS = ['focal_length_px', 'baseline', 'unit', 'cx', 'cy', 'doffs', 'image_width', 'image_height', 'focal_length_std_px', 'baseline_std'];

/** A click: the distance there through /distance, from the pixel's disparity and its σ in
 * the last answer and the rig it states. */
async function measure(event) {
  const a = live.arrays;
  if (!a) return;
  const { x, y } = pixelAt(event);
  const i = y * a.width + x;
  const [d, sd] = [a.disparity[i], a.disparity_std[i]];
  const out = $('live-distance');
  delete out.dataset.distance;
  delete out.dataset.point;
  if (!live.rig) {
    out.textContent = `(${x}, ${y}): d = ${fmt(d, 4)} px; distances need a calibration.`;
    return;
  }
  if (!Number.isFinite(d)) {
    out.textContent = `(${x}, ${y}): no reliable depth here; click a textured surface.`;
    return;
  }
  const request = { x_left: x, y, disparity_px: d, disparity_error_px: sd };
  for (const name of RIG_MEMBERS) if (live.rig[name] !== undefined) request[name] = live.rig[name];
  const { ok, status: code, body } = await postJson('/distance', request);
  if (!ok) {
    out.textContent = `(${x}, ${y}): ${problemsOf({ status: code, body }).map((e) => `${e.field}: ${e.message}`).join('; ')}`;
    return;
  }
  out.dataset.distance = String(body.distance);
  out.dataset.error = String(body.depth_error);
  out.dataset.x = String(x);
  out.dataset.y = String(y);
  if (body.point) out.dataset.point = JSON.stringify([body.point.x, body.point.y, body.point.z]);
  const terms = body.depth_error_terms;
  out.textContent = `(${x}, ${y}): ${fmt(body.distance, 5)} ± ${fmt(body.depth_error, 3)} ${body.unit} (matching ± ${fmt(terms.disparity, 3)}, focal length ± ${fmt(terms.focal_length, 3)}, baseline ± ${fmt(terms.baseline, 3)}; d = ${fmt(d, 5)} ± ${fmt(sd, 3)} px; range ${fmt(body.range ?? body.distance, 5)} ${body.unit})`;
  const r = Math.max(4, a.width / 60);
  const ns = 'http://www.w3.org/2000/svg';
  const mark = document.createElementNS(ns, 'circle');
  for (const [k, v] of Object.entries({ cx: x + 0.5, cy: y + 0.5, r, class: 'marker-core' })) mark.setAttribute(k, String(v));
  $('live-overlay').replaceChildren(mark);
}

/** A message from the service: the settings resolved, an answer and its files, an error. */
function received(event) {
  if (typeof event.data !== 'string') {
    if (!live.answer) return;
    live.files.push(event.data);
    if (live.files.length === live.answer.files.length) {
      const [answer, files] = [live.answer, live.files];
      live.answer = null;
      live.files = [];
      answered(answer, files);
    }
    return;
  }
  const message = JSON.parse(event.data);
  if (message.type === 'settings') {
    showErrors([]);
    status(`Streaming: ${message.max_disparity === null ? 'the range found from each frame' : `${message.max_disparity - message.min_disparity} disparities`}, ${message.temporal ? 'temporal filter on' : 'no temporal filter'}${message.rig ? `, B = ${fmt(message.rig.baseline, 4)} ${message.rig.unit}` : ''}.`);
    (message.warnings || []).forEach((w) => status(`${$('live-status').textContent} ${w}`));
    pump();
  } else if (message.type === 'frame') {
    if (message.files.length === 0) answered(message, []);
    else {
      live.answer = message;
      live.files = [];
    }
  } else if (message.type === 'error') {
    const errors = problemsOf({ status: message.problem.status, body: message.problem });
    showErrors(errors);
    if (message.id === 0) {
      status('The service refused the settings.');
      stop(false);
    } else {
      settle(message.id)?.left.close();
      status(`Frame ${message.id} refused; the stream goes on.`);
      pump();
    }
  }
}

async function start() {
  stopGrabbing();
  showErrors([]);
  if (!cameraAllowed()) {
    $('live-secure').hidden = false;
    status('No camera: this page is not a secure one (HTTPS or localhost).');
    return;
  }
  const { message, reason } = settings();
  if (!message) {
    status(reason);
    return;
  }
  $('live-start').disabled = true;
  try {
    if (!cameraOpen()) {
      status('Opening the camera…');
      await openCameras();
      await listCameras();
    }
    status('Opening the stream…');
    $('live-overlay').replaceChildren();
    const socket = await openSocket('/depth-stream');
    live.socket = socket;
    Object.assign(live, { running: true, sent: 0, waiting: new Map(), answer: null, files: [], answeredAt: [], latencies: [] });
    socket.addEventListener('message', received);
    socket.send(JSON.stringify(message));
    socket.addEventListener('close', (event) => {
      if (live.socket !== socket) return;
      const why = event.code === 1000 ? 'Stopped.' : `The stream closed (${event.code}${event.reason ? `: ${event.reason}` : ''}).`;
      stop(false);
      status(why);
    });
    $('live-stop').disabled = false;
    $('live-pause').disabled = false;
  } catch (error) {
    stop(false);
    status(`Could not start: ${error.message}`);
  }
}

function stop(byUser = true) {
  live.running = false;
  live.paused = false;
  $('live-pause').setAttribute('aria-pressed', 'false');
  $('live-pause').textContent = 'Pause';
  $('live-pause').disabled = true;
  const socket = live.socket;
  live.socket = null;
  if (socket && socket.readyState <= WebSocket.OPEN) socket.close(1000);
  for (const frame of live.waiting.values()) frame.left.close();
  live.waiting = new Map();
  if (!live.grabbing) closeCameras();
  $('live-start').disabled = false;
  $('live-stop').disabled = true;
  if (byUser) status('Stopped.');
}

// ---------------------------------------------------------------------------------------
// Board views grabbed from the camera.

/** A view is new when its corners moved on average by more than this share of the image's
 * width from those of every view kept (over the corners both show; a view sharing fewer than
 * four with a kept one is new beside it): the same view again adds nothing to a calibration,
 * while one moved, turned or tilted does. */
const NEW_VIEW = 0.02;

function isNew(corners, width) {
  const here = new Map(corners.map((c) => [c.id, c]));
  return live.views.every((v) => {
    let [sum, n] = [0, 0];
    for (const c of v.corners) {
      const d = here.get(c.id);
      if (!d) continue;
      sum += Math.hypot(d.x - c.x, d.y - c.y);
      n += 1;
    }
    return n < 4 || sum / n > NEW_VIEW * width;
  });
}

/** The left image with the board's outline in this frame (dashed when not kept) and the
 * views kept shaded: the coverage so far. */
function drawBoard(bitmap, answer, kept) {
  const [w, h] = [bitmap.width, bitmap.height];
  const canvas = $('live-canvas');
  sizeCanvas(canvas, w, h);
  sizeCanvas($('live-depth-canvas'), w, h);
  $('live-depth-canvas').getContext('2d').clearRect(0, 0, w, h);
  canvas.getContext('2d').drawImage(bitmap, 0, 0);
  const overlay = $('live-overlay');
  overlay.setAttribute('viewBox', `0 0 ${w} ${h}`);
  const points = (outline) => outline.map(([x, y]) => `${x.toFixed(1)},${y.toFixed(1)}`).join(' ');
  const shapes = live.views.map((v) => svg('polygon', { class: 'coverage', points: points(v.outline) }));
  if (answer && answer.left.found) {
    shapes.push(svg('polygon', { class: kept ? 'board-outline kept' : 'board-outline', points: points(answer.left.outline) }));
  }
  overlay.replaceChildren(...shapes);
}

function showViews(note) {
  const n = live.views.length;
  const line = $('live-grab-status');
  line.dataset.views = String(n);
  line.textContent = `${n} ${n === 1 ? 'view' : 'views'} kept. ${note}`;
  $('live-calibrate').disabled = n < 3;
  $('live-forget').disabled = n === 0;
}

/** Grabs frames while grabbing: each pair to /board, its outline drawn, kept when new; a
 * failure (the service gone) stops grabbing and says why. */
async function grabLoop() {
  try {
    await grabFrames();
  } catch (error) {
    stopGrabbing();
    showViews(`Stopped grabbing: ${error.message}.`);
  }
}

async function grabFrames() {
  let n = 0;
  while (live.grabbing) {
    if ($('live-video').readyState < 2) {
      await new Promise((resolve) => setTimeout(resolve, 50));
      continue;
    }
    n += 1;
    const { left, right, bitmap } = await grabPair(n);
    const body = new FormData();
    body.append('left', left);
    body.append('right', right);
    body.append('board', emit(EVENTS.boardPart)[0]);
    const { response, errors } = await post('/board', '', body);
    if (!live.grabbing) break;
    if (errors) {
      showErrors(errors);
      stopGrabbing();
      showViews('The service refused the board: check it in Calibrate mode.');
      break;
    }
    const answer = await response.json();
    const kept = answer.view && isNew(answer.left.corners, answer.width);
    if (kept) live.views.push({ left, right, outline: answer.left.outline, corners: answer.left.corners });
    drawBoard(bitmap, answer, kept);
    bitmap.close();
    showViews(kept ? 'Kept this one.'
      : answer.view ? 'The board is seen by both cameras, but this view is too like one kept: move or tilt it.'
        : `No board here: ${(answer.left.found ? answer.right?.reason : answer.left.reason) ?? 'the right camera does not see it'}.`);
  }
}

async function startGrabbing() {
  if (!cameraAllowed()) {
    $('live-secure').hidden = false;
    status('No camera: this page is not a secure one (HTTPS or localhost).');
    return;
  }
  if (live.running) stop(false);
  showErrors([]);
  if (!cameraOpen()) {
    try {
      status('Opening the camera…');
      await openCameras();
      await listCameras();
    } catch (error) {
      status(`Could not open the camera: ${error.message}`);
      return;
    }
  }
  live.grabbing = true;
  $('live-grab').setAttribute('aria-pressed', 'true');
  $('live-grab').textContent = 'Stop grabbing';
  status('Grabbing board views: hold the board in front of both cameras.');
  grabLoop();
}

function stopGrabbing() {
  if (!live.grabbing) return;
  live.grabbing = false;
  $('live-grab').setAttribute('aria-pressed', 'false');
  $('live-grab').textContent = 'Grab board views';
  if (!live.running) closeCameras();
}

/** Back from Calibrate mode with its calibration: stream with it at once. */
export function useLiveCalibration() {
  $('live-calibration').value = 'in-use';
  $('live-calibration-file-field').hidden = true;
  enterLive();
  start();
}

/** What the menu's "in use" stands for now, named in the menu: Calibrate mode's (or an
 * imported) calibration, the rig under Inputs, or nothing. Start sends what this says, so the
 * menu and the stream cannot disagree; the page calls it again whenever the form is
 * rewritten (the address read back, a calibration imported). */
export function nameInUse() {
  const used = page.calibration ? 'calibration' : rigGiven() ? 'rig' : null;
  const option = $('live-calibration').querySelector('option[value="in-use"]');
  option.textContent = {
    calibration: 'The one in use (Calibrate mode\'s, or imported)',
    rig: 'The rig under Inputs (rectified cameras)',
    null: 'The one in use (none yet)',
  }[used];
  return used;
}

/** Entering Live mode: the secure-context note, and the calibration in use named. */
export function enterLive() {
  $('live-secure').hidden = cameraAllowed();
  nameInUse();
}

/** Leaving Live mode stops the stream and the camera. */
export function leaveLive() {
  stopGrabbing();
  if (live.running) stop();
}

/** Live mode's controls. `calibrate(files)` takes the kept views to Calibrate mode. */
export function wireLive(calibrate) {
  $('live-grab').addEventListener('click', () => (live.grabbing ? stopGrabbing() : startGrabbing()));
  $('live-forget').addEventListener('click', () => {
    live.views = [];
    $('live-overlay').replaceChildren();
    showViews('');
  });
  $('live-calibrate').addEventListener('click', () => {
    stopGrabbing();
    calibrate(live.views.flatMap((v) => [v.left, v.right]));
  });
  $('live-pause').addEventListener('click', () => {
    live.paused = !live.paused;
    $('live-pause').setAttribute('aria-pressed', String(live.paused));
    $('live-pause').textContent = live.paused ? 'Resume' : 'Pause';
    $('live-stats').dataset.paused = String(live.paused);
  });
  $('live-start').addEventListener('click', start);
  $('live-stop').addEventListener('click', () => stop());
  $('live-layout').addEventListener('change', () => {
    $('live-camera-right-field').hidden = $('live-layout').value !== 'pair';
  });
  $('live-calibration').addEventListener('change', () => {
    $('live-calibration-file-field').hidden = $('live-calibration').value !== 'file';
  });
  $('live-calibration-file').addEventListener('change', async (event) => {
    const file = event.target.files[0];
    live.fileText = file ? await file.text() : null;
  });
  $('live-opacity').addEventListener('input', () => {
    $('live-depth-canvas').style.opacity = String(Number($('live-opacity').value) / 100);
  });
  $('live-frame').addEventListener('pointermove', hover);
  $('live-frame').addEventListener('click', measure);
}
