// What is found on a pair: the match of a clicked point and the median distance of a dragged
// box (/match), the markers drawn over the images, the distance under the pointer from the
// depth map's arrays, and the pointer and keyboard that ask for them.

import { post } from './api.js';
import { svg } from './draw.js';
import { clearImageErrors, pairForm, rangeQuery, showImageErrors, showRigNeeded } from './images.js';
import { readForm, rigGiven } from './rig.js';
import { EVENTS, NEEDS_RIG, emit, frameShown, on, pair, rawPair } from './store.js';
import { $, fmt, percent } from './util.js';

const status = $('status');

/** The image pixel under a pointer event in `frame`: the raw left image's on its raw view,
 * else the map's (the rectified frame's, which a latitude-longitude one does not share with
 * the raw images). */
export function pixelAt(event, frame) {
  const raw = frame.id === 'left-frame' && frameShown() === 'raw' && pair.bitmaps.left;
  const [width, height] = raw ? [pair.bitmaps.left.width, pair.bitmaps.left.height] : [pair.width, pair.height];
  const rect = frame.getBoundingClientRect();
  const x = Math.floor(((event.clientX - rect.left) * width) / rect.width);
  const y = Math.floor(((event.clientY - rect.top) * height) / rect.height);
  return { x: Math.min(width - 1, Math.max(0, x)), y: Math.min(height - 1, Math.max(0, y)) };
}

/** A latitude-longitude map: its pixels are angles, which /match's rectified pair (sent with
 * a pinhole rig) and the calculator's formula do not read. */
function latlonShown() {
  return pair.arrays !== null && pair.arrays.projection === 'latlon';
}

/** On a latitude-longitude map, a click on the rectified view is not sent: say where to click. */
function rawOnly() {
  if (!latlonShown() || frameShown() !== 'rectified') return false;
  status.textContent = 'The pair is rectified to latitude-longitude: click or box the raw view for a '
    + 'distance (hovering here reads the depth map).';
  return true;
}

/** The distance under the pointer, from the arrays fetched once. */
export function showHover({ x, y }, onRaw = false) {
  const a = pair.arrays;
  const hover = $('hover');
  if (!a) return;
  hover.dataset.x = String(x);
  hover.dataset.y = String(y);
  if (onRaw) {
    // The arrays are the rectified frame's: a raw pixel's distance is a click away.
    hover.textContent = `(${x}, ${y}) on the raw left image: click for the distance there (the depth map is rectified).`;
    return;
  }
  const i = y * a.width + x;
  const d = a.disparity[i];
  const z = a.depth ? a.depth[i] : NaN;
  hover.dataset.x = String(x);
  hover.dataset.y = String(y);
  const sd = a.disparity_std[i];
  if (Number.isFinite(z)) {
    hover.textContent = `(${x}, ${y}): ${fmt(z, 5)} ${pair.unit} ± ${fmt(a.depth_std[i], 3)} ${pair.unit}, d = ${fmt(d, 4)} ± ${fmt(sd, 3)} px`;
  } else if (Number.isFinite(d)) {
    hover.textContent = rigGiven()
      ? `(${x}, ${y}): d = ${fmt(d, 4)} ± ${fmt(sd, 3)} px, no depth (check the rig)`
      : `(${x}, ${y}): d = ${fmt(d, 4)} ± ${fmt(sd, 3)} px. ${NEEDS_RIG}`;
  } else {
    hover.textContent = `(${x}, ${y}): no reliable match here; click for /match's best guess and why`;
  }
}

export function overlayShapes(id, shapes) {
  $(id).replaceChildren(...shapes);
}

/** Markers in image pixels: the match on the left image and the depth map, its partner and
 * row (the epipolar line) on the right image, the box, and the keyboard's crosshair. */
export function drawMarkers() {
  const r = Math.max(4, Math.max(pair.width, pair.height) / 60);
  const left = [];
  const right = [];
  const c = pair.crosshair;
  const crosshair = svg('g', { class: 'crosshair', id: 'crosshair', 'data-x': c.x, 'data-y': c.y });
  crosshair.append(
    svg('line', { x1: c.x + 0.5, x2: c.x + 0.5, y1: c.y + 0.5 - 2 * r, y2: c.y + 0.5 + 2 * r }),
    svg('line', { y1: c.y + 0.5, y2: c.y + 0.5, x1: c.x + 0.5 - 2 * r, x2: c.x + 0.5 + 2 * r }),
  );
  const region = pair.region && (pair.region.frame ?? frameShown()) === frameShown() ? pair.region : null;
  const box = region ?? (pair.anchor ? boxOf(pair.anchor, c) : null);
  const shapes = [];
  if (box) {
    const attributes = { x: box.x, y: box.y, width: box.width, height: box.height };
    shapes.push(svg('rect', { ...attributes, class: 'box' }), svg('rect', { ...attributes, class: 'box-core', id: 'box' }));
  }
  const m = pair.match;
  const depth = [];
  if (m) {
    const at = placed(m);
    const dot = ([x, y], id, extra = {}) => {
      const where = { cx: x + 0.5, cy: y + 0.5, r, ...extra };
      const core = svg('circle', { ...where, class: 'marker-core' });
      if (id) core.id = id;
      return [svg('circle', { ...where, class: 'marker' }), core];
    };
    if (at.left) shapes.push(...dot(at.left, 'left-marker'));
    if (at.depth) depth.push(...dot(at.depth, null));
    if (at.row !== null) right.push(svg('line', { class: 'epipolar', id: 'epipolar', x1: 0, x2: pair.width, y1: at.row + 0.5, y2: at.row + 0.5 }));
    if (at.right) right.push(...dot(at.right, 'right-marker', { 'data-x': at.right[0], 'data-y': at.right[1] }));
  }
  if (frameShown() === 'rectified') {
    // The rectified pair's rows line up: lines every 32 rows show it, as /rectify's pair.png.
    for (let y = 16; y < pair.height; y += 32) {
      const line = { class: 'epipolar-grid', x1: 0, x2: pair.width, y1: y, y2: y };
      left.push(svg('line', line));
      right.push(svg('line', line));
    }
  }
  left.push(...shapes, crosshair);
  overlayShapes('left-overlay', left);
  const boxes = rawPair() ? [] : shapes.filter((s) => s.tagName === 'rect').map((s) => s.cloneNode(true));
  boxes.forEach((s) => s.removeAttribute('id'));
  overlayShapes('depth-overlay', [...boxes, ...depth]);
  overlayShapes('right-overlay', right);
}

/** Where a match is drawn in the frame shown: on the left image, on the depth map (always
 * the rectified frame), its row on the right image, and its partner there. A match made on the
 * raw frame knows both frames (`x_rectified` and `x_right_raw`); one made on the rectified view
 * knows only that. */
function placed(m) {
  const rectified = m.x_rectified !== undefined ? [m.x_rectified, m.y_rectified] : m.frame !== 'raw' ? [m.x, m.y] : null;
  const rightRectified = rectified && m.x_right !== undefined ? [m.x_right, rectified[1]] : null;
  if (frameShown() !== 'raw') {
    return { left: rectified, depth: rectified, row: rectified ? rectified[1] : null, right: rightRectified };
  }
  const rawRight = m.x_right_raw !== undefined ? [m.x_right_raw, m.y_right_raw] : null;
  return { left: m.frame === 'raw' ? [m.x, m.y] : null, depth: rectified, row: null, right: rawRight };
}

export function boxOf(a, b) {
  const x = Math.min(a.x, b.x);
  const y = Math.min(a.y, b.y);
  return { x, y, width: Math.abs(a.x - b.x) + 1, height: Math.abs(a.y - b.y) + 1 };
}

const STATUS_MEANING = {
  ok: 'a reliable match',
  occluded: 'hidden from the right camera (the left-right check failed)',
  ambiguous: 'several places in the right image match as well',
  textureless: 'too little texture to match',
  out_of_range: 'the match lies outside the disparity search range',
  inconsistent: 'disagrees with its neighbours (often a depth edge)',
  outside_image: 'outside the image',
};

export function showMatch(m) {
  const values = $('match-values');
  if (m === null) {
    $('match-summary').textContent = 'Click the left image (or press Enter on it) for a match.';
    values.hidden = true;
    return;
  }
  const meaning = STATUS_MEANING[m.status] ?? m.status;
  const raw = m.x_right_raw !== undefined
    ? ` On the raw frames: (${fmt(m.x_right_raw, 6)}, ${fmt(m.y_right_raw, 6)}) in the right image; rectified, (${fmt(m.x_rectified, 6)}, ${fmt(m.y_rectified, 6)}) in the left.`
    : '';
  const where = m.frame === 'raw' ? 'raw left image' : m.frame === 'rectified' ? 'rectified left image' : 'left image';
  $('match-summary').textContent = m.x_right !== undefined
    ? `(${m.x}, ${m.y}) in the ${where} is at x = ${fmt(m.x_right, 7)} px in the ${m.frame === 'plain' || !m.frame ? 'right image' : 'rectified right image'}: ${m.status}, ${meaning}.${raw}${m.error ? ` ${m.error}.` : ''}`
    : `(${m.x}, ${m.y}): no match, ${m.status}: ${meaning}.`;
  if (m.projection === 'latlon' && m.distance !== undefined) {
    // The calculator is not given a latitude-longitude match: its distance is said here.
    $('match-summary').textContent += ` In latitude-longitude: distance ${fmt(m.distance, 5)} ${m.unit} `
      + `± ${fmt(m.distance_std, 3)} ${m.unit}, range ${fmt(m.range, 5)} ${m.unit}.`;
  }
  $('match-left').textContent = `(${m.x}, ${m.y}) px`;
  $('match-x-right').textContent = m.x_right !== undefined ? `${fmt(m.x_right, 7)} px` : '–';
  $('match-disparity').textContent = m.disparity_px !== undefined ? `${fmt(m.disparity_px, 6)} px` : '–';
  const statusCell = $('match-status');
  statusCell.textContent = m.status;
  statusCell.className = m.status === 'ok' ? 'status-ok' : 'status-other';
  $('match-confidence').textContent = fmt(m.confidence, 3);
  $('match-sigma').textContent = m.disparity_std_px === undefined
    ? '–'
    : m.distance_std === undefined
      ? `${fmt(m.disparity_std_px, 3)} px (no distance)`
      : `${fmt(m.disparity_std_px, 3)} px (distance ± ${fmt(m.distance_std, 3)})`;
  values.hidden = false;
}

export function showRegion(r) {
  const summaryLine = $('region-summary');
  if (r === null) {
    summaryLine.textContent = 'Drag a box on the left image for its median distance.';
    delete summaryLine.dataset.distance;
    return;
  }
  const where = `Box at (${r.x}, ${r.y}), ${r.width} × ${r.height} px`;
  if (r.status !== 'ok' || r.distance === undefined) {
    summaryLine.textContent = `${where}: ${r.status === 'outside_image' ? 'outside the image' : 'no valid pixel'}.`;
    delete summaryLine.dataset.distance;
    return;
  }
  const u = r.unit;
  summaryLine.dataset.distance = String(r.distance);
  summaryLine.textContent =
    `${where}: median ${fmt(r.distance, 5)} ${u} (p10–p90 ${fmt(r.distance_p10, 5)}–${fmt(r.distance_p90, 5)} ${u}), ` +
    `± ${fmt(r.distance_std, 3)} ${u} (σ of the median), d = ${fmt(r.disparity_px, 5)} px, ${percent(r.valid_fraction)} of its pixels valid.`;
}

/** The lines "Copy results" adds in Images mode. */
export function findings() {
  const lines = [];
  const m = pair.match;
  if (m) {
    lines.push(`Match: left (${m.x}, ${m.y}) px -> right x ${m.x_right !== undefined ? `${fmt(m.x_right, 7)} px` : 'none'}; ` +
      `status ${m.status}; confidence ${fmt(m.confidence, 3)}`);
  }
  const r = pair.region;
  if (r && r.distance !== undefined) {
    lines.push(`Region: (${r.x}, ${r.y}) ${r.width} x ${r.height} px, median ${fmt(r.distance)} ${r.unit} ` +
      `(p10 ${fmt(r.distance_p10)}, p90 ${fmt(r.distance_p90)}), ${percent(r.valid_fraction)} valid`);
  }
  return lines;
}

let findController = null;

/** Asks /match for the points or regions in `parts`. */
export async function find(parts, what, frame) {
  const state = readForm();
  const body = pairForm(state, frame);
  for (const [name, value] of Object.entries(parts)) body.append(name, JSON.stringify(value));
  if (findController) findController.abort();
  findController = new AbortController();
  document.body.dataset.match = 'computing';
  try {
    const { response, errors } = await post('/match', rangeQuery(state), body, findController.signal);
    clearImageErrors();
    if (errors) {
      showImageErrors(errors);
      status.textContent = `No ${what}: the service refused the request.`;
      return null;
    }
    return { answer: await response.json(), state };
  } catch (error) {
    if (error.name !== 'AbortError') status.textContent = `No ${what}: ${error.message}.`;
    return null;
  } finally {
    document.body.dataset.match = 'done';
  }
}

/** A click or a box without a rig: /match answers distances, so it needs one; say so and
 * offer the import. */
export function askForRig() {
  $('match-summary').textContent = NEEDS_RIG;
  $('region-summary').textContent = NEEDS_RIG;
  status.textContent = NEEDS_RIG;
  showRigNeeded();
  drawMarkers();
}

export async function matchAt(x, y) {
  if (!pair.files.left || !pair.files.right) return;
  pair.crosshair = { x, y };
  if (!rigGiven()) {
    askForRig();
    return;
  }
  if (rawOnly()) return;
  $('match-summary').textContent = `Matching (${x}, ${y})…`;
  const frame = frameShown();
  const found = await find({ points: [{ x, y }] }, 'match', frame);
  if (!found) return;
  const m = { ...found.answer.matches[0], frame, projection: found.answer.projection, unit: found.answer.unit };
  pair.match = m;
  showMatch(m);
  drawMarkers();
  if (m.projection === 'latlon') {
    // Its distance is measured along its ray in latitude-longitude; the calculator's
    // pinhole formula would read the angles as pixels, so it is not given them.
    status.textContent = m.distance !== undefined
      ? `Matched (${x}, ${y}) in latitude-longitude: distance ${fmt(m.distance, 5)} ${m.unit}, range ${fmt(m.range, 5)} ${m.unit}.`
      : `Matched (${x}, ${y}) in latitude-longitude: ${m.status}, no distance.`;
    return;
  }
  // A match the service gives no distance (out_of_range, occluded: its disparity is not the
  // point's match) is not sent on to /distance; the match panel says why.
  const withheld = m.x_right !== undefined && m.distance === undefined;
  if (withheld) return;
  if (m.x_right !== undefined) {
    // /distance takes the rectified pair's coordinates: a raw click's are x_rectified, y_rectified.
    const rectified = m.x_rectified !== undefined;
    $('x_left').value = String(rectified ? m.x_rectified : m.x);
    $('x_right').value = String(m.x_right);
    $('y').value = String(rectified ? m.y_rectified : m.y);
  }
  await Promise.all(emit(EVENTS.compute, `Matched (${x}, ${y}): ${m.status}.`));
}

export async function measureRegion(a, b) {
  if (!pair.files.left || !pair.files.right) return;
  const box = boxOf(a, b);
  pair.region = box;
  pair.anchor = null;
  if (!rigGiven()) {
    askForRig();
    return;
  }
  if (rawOnly()) return;
  drawMarkers();
  $('region-summary').textContent = `Measuring the box at (${box.x}, ${box.y}), ${box.width} × ${box.height} px…`;
  const frame = frameShown();
  const found = await find({ regions: [box] }, 'region', frame);
  if (!found) return;
  pair.region = { ...found.answer.regions[0], unit: found.answer.unit, frame };
  showRegion(pair.region);
  drawMarkers();
  status.textContent = pair.region.distance !== undefined
    ? `Region: median ${fmt(pair.region.distance)} ${pair.region.unit}.`
    : 'Region: no distance.';
}

/** Pointing at the left image or the depth map: hover reads the arrays; a click matches; a
 * drag measures a box. The keyboard does the same on the left image. */
export function wirePointing() {
  let drag = null;
  for (const frame of [$('left-frame'), $('depth-frame')]) {
    frame.addEventListener('pointerdown', (event) => {
      if (!pair.arrays || event.button !== 0) return;
      event.preventDefault();
      frame.setPointerCapture(event.pointerId);
      const start = pixelAt(event, frame);
      drag = { frame, start, startX: event.clientX, startY: event.clientY, moved: false };
    });
    frame.addEventListener('pointermove', (event) => {
      if (!pair.arrays) return;
      const at = pixelAt(event, frame);
      showHover(at, frame.id === 'left-frame' && frameShown() === 'raw');
      if (drag && drag.frame === frame) {
        if (Math.hypot(event.clientX - drag.startX, event.clientY - drag.startY) > 6) drag.moved = true;
        if (drag.moved) {
          pair.region = boxOf(drag.start, at);
          drawMarkers();
        }
      }
    });
    frame.addEventListener('pointerup', (event) => {
      if (!drag || drag.frame !== frame) return;
      const done = drag;
      drag = null;
      if (done.moved) measureRegion(done.start, pixelAt(event, frame));
      else matchAt(done.start.x, done.start.y);
    });
    frame.addEventListener('pointercancel', () => {
      drag = null;
    });
  }
  $('left-frame').addEventListener('keydown', (event) => {
    if (!pair.arrays) return;
    const step = event.shiftKey ? 10 : 1;
    const moves = { ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, -step], ArrowDown: [0, step] };
    const c = pair.crosshair;
    if (event.key in moves) {
      event.preventDefault();
      const [dx, dy] = moves[event.key];
      pair.crosshair = {
        x: Math.min(pair.width - 1, Math.max(0, c.x + dx)),
        y: Math.min(pair.height - 1, Math.max(0, c.y + dy)),
      };
      showHover(pair.crosshair, frameShown() === 'raw');
      drawMarkers();
    } else if (event.key === 'Enter') {
      event.preventDefault();
      if (pair.anchor) measureRegion(pair.anchor, c);
      else matchAt(c.x, c.y);
    } else if (event.key === ' ') {
      event.preventDefault();
      pair.anchor = pair.anchor ? null : { ...c };
      pair.region = null;
      status.textContent = pair.anchor
        ? `Box corner at (${c.x}, ${c.y}): move to the opposite corner and press Enter.`
        : 'Box cancelled.';
      drawMarkers();
    } else if (event.key === 'Escape') {
      pair.anchor = null;
      pair.region = null;
      drawMarkers();
    }
  });
  $('left-frame').addEventListener('focus', () => {
    if (pair.arrays) showHover(pair.crosshair, frameShown() === 'raw');
  });
}

on(EVENTS.drawMarkers, drawMarkers);
on(EVENTS.showMatch, showMatch);
on(EVENTS.showRegion, showRegion);
on(EVENTS.findingsLines, findings);
