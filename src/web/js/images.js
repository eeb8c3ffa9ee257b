// Images mode: a pair, its depth map (/depth-map, read as NumPy arrays so that hovering costs
// no request), the downloads, and the project's sample pair. What is found on the pair by a
// click or a box (/match) is in findings.js.

import { fetchFile, post, postJson, readNpz, save, serverTime } from './api.js';
import { colourRange, drawColourBar, drawSigmaBar, sizeCanvas, turbo } from './draw.js';
import { applyRig, forgetUnknown, readForm, rigGiven, rigPart, showErrors, writeForm } from './rig.js';
import { EVENTS, NEEDS_RIG, emit, frameShown, on, pair, rawPair } from './store.js';
import {
  $, DEBOUNCE_MS, clearFieldErrors, fmt, page, percent, setFiles, showFieldErrors,
} from './util.js';

/** Images mode without a rig: say so, and offer the calibration import. */
export function showRigNeeded() {
  const given = rigGiven();
  $('rig-needed').hidden = !(page.mode === 'images' && !given);
  // Once a rig is given, the cards that asked for it invite a click again.
  if (given && $('match-summary').textContent === NEEDS_RIG) emit(EVENTS.showMatch, pair.match);
  if (given && $('region-summary').textContent === NEEDS_RIG) emit(EVENTS.showRegion, pair.region);
}


/** An image request's form. A raw pair goes with its calibration, for the service to
 * rectify (`frame` `raw`), or, for points on the rectified view, as the rectified pair with
 * the rectified rig (`frame` `rectified`); a rectified pair goes with the rig. */
export function pairForm(state, frame = 'raw') {
  const body = new FormData();
  if (rawPair() && frame === 'rectified' && pair.rectifiedFiles.left) {
    body.append('left', pair.rectifiedFiles.left);
    body.append('right', pair.rectifiedFiles.right);
    body.append('rig', rigPart(state));
    return body;
  }
  body.append('left', pair.files.left);
  body.append('right', pair.files.right);
  if (rawPair()) {
    const { request } = page.calibration;
    body.append('calibration', new Blob([request.text], { type: 'text/plain' }), 'calibration');
    if (request.right_text) body.append('right_calibration', new Blob([request.right_text], { type: 'text/plain' }), 'right_calibration');
    if (request.calibration_unit) body.append('calibration_unit', request.calibration_unit);
  } else if (rigGiven(state)) {
    body.append('rig', rigPart(state));
  }
  return body;
}

/** The raw pair rectified by /rectify, to show beside the raw one. */
async function requestRectified(state) {
  pair.rectified = { left: null, right: null };
  pair.rectifiedFiles = { left: null, right: null };
  if (!rawPair()) return;
  // Both images at once: /rectify answers one image a request, from maps it caches.
  await Promise.all(['left', 'right'].map(async (side) => {
    const query = new URLSearchParams({ output: `${side}.png` });
    if (state.projection !== 'pinhole') query.set('projection', state.projection);
    const { response, errors } = await post('/rectify', query, pairForm(state, 'raw'));
    if (errors) return;
    const blob = await response.blob();
    pair.rectifiedFiles[side] = new File([blob], `rectified-${side}.png`, { type: 'image/png' });
    pair.rectified[side] = await createImageBitmap(blob);
  }));
}

/** The raw/rectified toggle, and the depth map's caption, for the pair as it is. */
export function showFrames() {
  const raw = rawPair();
  $('frames').hidden = !(raw && pair.rectified.left !== null);
  captionDepth();
}

/** The depth view's caption: what it shows (the depths, or each one's σ), and over which
 * frame. */
function captionDepth() {
  const a = pair.arrays;
  const shown = !$('show-sigma').checked ? 'Depth map' : 'σ of each disparity';
  const over = a && a.projection === 'latlon'
    ? 'the latitude-longitude rectified left image (azimuth across, elevation down; the service rectified the raw pair)'
    : 'the rectified left image (the service rectified the raw pair)';
  $('depth-caption').textContent = rawPair() ? `${shown}, over ${over}` : shown;
}

/** Shows the raw or the rectified pair (`view`), with the markers where each frame has them. */
export function showView(view) {
  pair.view = view;
  $(`frames-${view}`).checked = true;
  if (view === 'raw' && $('blend').checked) {
    $('blend').checked = false;
    $('blend').dispatchEvent(new Event('change'));
  }
  drawImage('left');
  drawImage('right');
  emit(EVENTS.drawMarkers);
}

export function rangeQuery(state, output = null) {
  const query = new URLSearchParams();
  if (output) query.set('output', output);
  for (const name of ['min_disparity', 'max_disparity']) if (state[name] !== '') query.set(name, state[name]);
  // The projection is the raw pair's rectification; a rectified pair has none to choose.
  if (rawPair() && state.projection !== 'pinhole') query.set('projection', state.projection);
  return query;
}

/** A /depth-map query: the range, the matcher's preset (`accurate` is the API's default,
 * so it is left out), the keep rule's σ when one is typed, and the output. */
function depthQuery(state, output) {
  const query = rangeQuery(state, output);
  if (state.preset !== 'accurate') query.set('preset', state.preset);
  if (state.max_disparity_std !== '') query.set('max_disparity_std', state.max_disparity_std);
  return query;
}

/** Where an image request's problem is shown: next to the file input or range field it
 * names, or in the list under the inputs. */
export const IMAGE_INPUTS = {
  left: 'left_image', right: 'right_image', min_disparity: 'min_disparity', max_disparity: 'max_disparity', preset: 'preset',
  max_disparity_std: 'max_disparity_std', projection: 'projection',
};

export function clearImageErrors() {
  clearFieldErrors(Object.values(IMAGE_INPUTS), 'images-errors');
}

export function showImageErrors(errors) {
  // The rig's members are marked on their fields under Inputs too.
  const rig = errors.filter(({ field }) => field.startsWith('rig.'));
  if (rig.length > 0) showErrors(rig, readForm());
  showFieldErrors(errors, ({ field, message }) => (IMAGE_INPUTS[field] ? { input: IMAGE_INPUTS[field], text: message } : null), 'images-errors');
}

export async function chooseImage(side, file) {
  pair.files[side] = file;
  pair.bitmaps[side] = null;
  if (file) {
    try {
      pair.bitmaps[side] = await createImageBitmap(file);
    } catch {
      // Not an image the browser can show; the service will say what it is.
    }
  }
  drawImage(side);
}

/** A new pair (or one new image): forget the old findings, show the images, and match. */
export async function loadPair(files) {
  pair.rectified = { left: null, right: null };
  pair.rectifiedFiles = { left: null, right: null };
  pair.view = 'raw';
  showFrames();
  for (const [side, file] of Object.entries(files)) await chooseImage(side, file);
  pair.match = null;
  pair.region = null;
  pair.anchor = null;
  pair.arrays = null;
  clearDepth();
  emit(EVENTS.showMatch, null);
  emit(EVENTS.showRegion, null);
  const { left, right } = pair.bitmaps;
  if (left) {
    pair.width = left.width;
    pair.height = left.height;
    pair.crosshair = { x: Math.floor(left.width / 2), y: Math.floor(left.height / 2) };
    if (right && right.width === left.width && right.height === left.height && !page.sizeFromCalibration) {
      const state = readForm();
      state.image_width = String(left.width);
      state.image_height = String(left.height);
      writeForm(state);
    }
  }
  emit(EVENTS.drawMarkers);
  emit(EVENTS.compute);
  await requestDepth();
}

export function drawImage(side) {
  const rectified = rawPair() && pair.view === 'rectified' && pair.rectified[side] !== null;
  const bitmap = rectified ? pair.rectified[side] : pair.bitmaps[side];
  const canvas = $(`${side}-canvas`);
  const width = bitmap ? bitmap.width : 320;
  const height = bitmap ? bitmap.height : 240;
  sizeCanvas(canvas, width, height);
  const context = canvas.getContext('2d');
  context.clearRect(0, 0, width, height);
  if (bitmap) context.drawImage(bitmap, 0, 0);
  $(`${side}-overlay`).setAttribute('viewBox', `0 0 ${width} ${height}`);
  const which = !rawPair() ? '' : rectified ? ' (rectified by the service)' : ' (raw)';
  $(`${side}-caption`).textContent = bitmap
    ? `${side === 'left' ? 'Left' : 'Right'} image${which}, ${width} × ${height}`
    : `${side === 'left' ? 'Left' : 'Right'} image`;
  if (side === 'left' && !pair.arrays) {
    // Until there is a map (which has the rectified frame's size), the left image's size.
    sizeCanvas($('depth-canvas'), width, height);
    sizeCanvas($('blend-canvas'), width, height);
    $('depth-overlay').setAttribute('viewBox', `0 0 ${width} ${height}`);
  }
}

export let depthController = null;
let depthToken = 0;
let depthDebounce = null;

export function scheduleDepth() {
  clearTimeout(depthDebounce);
  if (page.mode !== 'images' || !pair.files.left || !pair.files.right) return;
  document.body.dataset.depth = 'pending';
  depthDebounce = setTimeout(() => requestDepth(), DEBOUNCE_MS);
}

/** Asks /depth-map for the pair's arrays (disparity, depth and each one's σ) once; hovering
 * reads them, so no pixel costs a request. */
export async function requestDepth() {
  clearTimeout(depthDebounce);
  if (!pair.files.left || !pair.files.right) return;
  const state = readForm();
  const token = ++depthToken;
  if (depthController) depthController.abort();
  depthController = new AbortController();
  document.body.dataset.depth = 'computing';
  $('depth-status').textContent = 'Matching the pair…';
  const started = performance.now();
  try {
    const { response, errors } = await post('/depth-map', depthQuery(state, 'arrays.npz'), pairForm(state), depthController.signal);
    if (token !== depthToken) return;
    clearImageErrors();
    if (errors) {
      showImageErrors(errors);
      pair.arrays = null;
      clearDepth();
      $('depth-status').textContent = `No depth map: the service refused the request (${errors.length} ${errors.length === 1 ? 'problem' : 'problems'}).`;
      return;
    }
    const arrays = readNpz(await response.arrayBuffer());
    if (token !== depthToken) return;
    const { width, height } = arrays.disparity;
    pair.width = width;
    pair.height = height;
    pair.unit = state.unit;
    pair.arrays = {
      width,
      height,
      disparity: arrays.disparity.data,
      depth: arrays.depth ? arrays.depth.data : null,
      disparity_std: arrays.disparity_std.data,
      depth_std: arrays.depth_std ? arrays.depth_std.data : null,
      // `pinhole` or `latlon`: what the raw pair was rectified to (`auto` chooses one).
      projection: typeof arrays.projection === 'string' ? arrays.projection : 'pinhole',
    };
    const elapsed = performance.now() - started;
    const server = serverTime(response);
    // What the service warns of (a range that stops short, cameras that look swapped), but
    // the raw pair's rectification, which the status says in its own words.
    const warnings = serviceWarnings(response).filter((w) => !w.startsWith('the raw pair was rectified first'));
    let valid = 0;
    for (const d of pair.arrays.disparity) if (!Number.isNaN(d)) valid += 1;
    const fraction = valid / (width * height);
    if (rawPair()) {
      await requestRectified(state);
      if (token !== depthToken) return;
    }
    showFrames();
    drawDepth();
    $('downloads').hidden = false;
    $('depth-status').dataset.valid = String(fraction);
    $('depth-status').textContent =
      `Depth map ${width} × ${height}: ${percent(fraction)} of the pixels matched, in ${fmt(elapsed, 3)} ms ` +
      `(${fmt(server, 3)} ms of it on the server).` +
      (rawPair() ? ` The service rectified the raw pair first${pair.arrays.projection === 'latlon' ? ' to latitude-longitude' : ''}: the depth map is drawn in the rectified left image's frame.` : '') +
      (warnings.length > 0 ? ` Warnings: ${warnings.join('; ')}.` : '');
  } catch (error) {
    if (error.name === 'AbortError' || token !== depthToken) return;
    $('depth-status').textContent = `No depth map: ${error.message}.`;
  } finally {
    if (token === depthToken) document.body.dataset.depth = 'done';
  }
}

/** The answer's `Stereo-Warnings` header: a JSON array of strings, none when absent or bad. */
function serviceWarnings(response) {
  try {
    const said = JSON.parse(response.headers.get('stereo-warnings') || '[]');
    return Array.isArray(said) ? said.filter((w) => typeof w === 'string') : [];
  } catch {
    return [];
  }
}

export function clearDepth() {
  for (const id of ['depth-canvas', 'blend-canvas']) {
    const canvas = $(id);
    canvas.getContext('2d').clearRect(0, 0, canvas.width, canvas.height);
  }
  const bar = $('colour-bar');
  $('colour-bar-title').textContent = 'No depth map yet.';
  bar.replaceChildren($('colour-bar-title'));
  $('downloads').hidden = true;
  delete $('depth-status').dataset.valid;
}

/** The σ view's fixed scale: σ_d from 0 (blue) to this many pixels and more (red). */
const SIGMA_SCALE_PX = 2;

/** The depth map in Turbo on inverse depth, near warm, beside the left image and in the
 * blend layer over it (where invalid pixels are clear); or, with "Show each pixel's σ", each
 * pixel's σ_d in Turbo on one fixed scale, from sure (blue) to 2 px and more (red), black
 * where there is no depth. σ_d, not σ_Z: σ_Z grows as Z², so its colours would show the
 * distance again; σ_d shows where the matcher is unsure, the same on every pair (the hover
 * gives each pixel's σ_Z). */
export function drawDepth() {
  const a = pair.arrays;
  if (!a) return;
  // The view's tools (blend, σ) once there is a map to use them on.
  $('view-tools').hidden = false;
  const sigma = $('show-sigma').checked;
  // The map has the rectified frame's size, which a latitude-longitude one does not share
  // with the raw images.
  for (const id of ['depth-canvas', 'blend-canvas']) sizeCanvas($(id), a.width, a.height);
  $('depth-overlay').setAttribute('viewBox', `0 0 ${a.width} ${a.height}`);
  const depthImage = new ImageData(a.width, a.height);
  const blendImage = new ImageData(a.width, a.height);
  const paint = (i, t) => {
    const o = i * 4;
    const [r, g, b] = turbo(t);
    depthImage.data.set([r, g, b], o);
    blendImage.data.set([r, g, b, 255], o);
  };
  for (let i = 3; i < depthImage.data.length; i += 4) depthImage.data[i] = 255;
  if (sigma) {
    const values = a.disparity_std;
    let any = false;
    for (let i = 0; i < values.length; i += 1) {
      if (Number.isFinite(values[i])) {
        paint(i, Math.min(1, values[i] / SIGMA_SCALE_PX));
        any = true;
      }
    }
    drawSigmaBar(any ? [0, SIGMA_SCALE_PX] : null, 'px');
  } else {
    const values = a.depth ?? a.disparity.map((d) => (d > 0 ? 1 / d : NaN));
    const range = colourRange(values);
    if (range) {
      const [near, far] = range;
      const span = 1 / near - 1 / far;
      for (let i = 0; i < values.length; i += 1) {
        if (values[i] > 0) paint(i, (1 / values[i] - 1 / far) / span);
      }
    }
    drawColourBar(range, a.depth ? pair.unit : rigGiven() ? null : 'px');
  }
  captionDepth();
  $('depth-canvas').getContext('2d').putImageData(depthImage, 0, 0);
  $('blend-canvas').getContext('2d').putImageData(blendImage, 0, 0);
  emit(EVENTS.drawMarkers);
}

export async function download(output) {
  const line = $('download-status');
  if (!pair.files.left || !pair.files.right) return;
  line.textContent = `Preparing ${output}…`;
  const state = readForm();
  try {
    const { response, errors } = await post('/depth-map', depthQuery(state, output), pairForm(state));
    if (errors) {
      line.textContent = `No ${output}: ${errors.map((e) => `${e.field}: ${e.message}`).join(' ')}`;
      return;
    }
    const blob = await response.blob();
    save(blob, output);
    line.textContent = `Saved ${output} (${fmt(blob.size / 1024, 3)} KiB).`;
  } catch (error) {
    line.textContent = `No ${output}: ${error.message}.`;
  }
}

/** A sample's pair from this origin, put into the file inputs as if chosen there: `where(side)`
 * gives each file's path and name; the answer is `{ left, right }`. */
export async function fetchPair(where) {
  const files = {};
  for (const side of ['left', 'right']) {
    files[side] = await fetchFile(...where(side));
    setFiles(`${side}_image`, [files[side]]);
  }
  return files;
}

/** `/?mode=images&sample=1`: the project's own rendered pair and its rig, matched at once. */
export async function openSample() {
  try {
    // The sample's calibration file, read by /calibration as an imported file is: the rig and,
    // from its ndisp, the search range.
    const text = await (await fetch('/sample/calib.txt')).text();
    const read = await postJson('/calibration', { text });
    if (!read.ok) throw new Error(`/calibration answered ${read.status}`);
    const about = read.body;
    const files = await fetchPair((side) => [`/sample/${side}.png`, `sample-${side}.png`]);
    applyRig(about.rig, about.max_disparity_px);
    page.sizeFromCalibration = false;
    pair.sample = true;
    $('depth-status').textContent = 'The project\'s own rendered scene: a slanted textured wall, '
      + 'a box and a disc in front of it; the disparities are known exactly.';
    await loadPair(files);
  } catch (error) {
    $('depth-status').textContent = `The sample could not be loaded (${error.message}).`;
    emit(EVENTS.compute);
  }
}

/** Forgets the last click's match and box (made with another rig or pair). */
export function forgetFindings() {
  pair.match = null;
  pair.region = null;
  pair.anchor = null;
  emit(EVENTS.showMatch, null);
  emit(EVENTS.showRegion, null);
  emit(EVENTS.drawMarkers);
}

/** The Images mode's controls: the sample link, the file inputs and drops, the search range,
 * the blend and the downloads. */
export function wireImages() {
  $('sample-link').addEventListener('click', (event) => {
    if (event.ctrlKey || event.metaKey || event.shiftKey || event.button !== 0) return;
    event.preventDefault();
    openSample();
  });
  for (const side of ['left', 'right']) {
    $(`${side}_image`).addEventListener('change', (event) => {
      pair.sample = false;
      loadPair({ [side]: event.target.files[0] ?? null });
    });
  }
  // Drops: one file on an input's box is that image; two files anywhere are the pair, in the
  // order of their names (left before right, im0 before im1).
  const imagesSection = $('images');
  imagesSection.addEventListener('dragover', (event) => {
    event.preventDefault();
    const zone = event.target.closest('.drop');
    for (const drop of imagesSection.querySelectorAll('.drop')) drop.classList.toggle('over', drop === zone);
  });
  imagesSection.addEventListener('dragleave', (event) => {
    if (event.target.closest('.drop')) event.target.closest('.drop').classList.remove('over');
  });
  imagesSection.addEventListener('drop', (event) => {
    event.preventDefault();
    for (const drop of imagesSection.querySelectorAll('.drop')) drop.classList.remove('over');
    const files = [...event.dataTransfer.files];
    if (files.length === 0) return;
    pair.sample = false;
    if (files.length >= 2) {
      const [left, right] = files.slice(0, 2).sort((a, b) => a.name.localeCompare(b.name));
      loadPair({ left, right });
      return;
    }
    const zone = event.target.closest('.drop');
    const side = zone && zone.id === 'right_image-field' ? 'right' : 'left';
    loadPair({ [side]: files[0] });
  });
  for (const name of ['min_disparity', 'max_disparity', 'max_disparity_std']) {
    $(name).addEventListener('input', () => {
      scheduleDepth();
      emit(EVENTS.schedule);
    });
  }
  for (const name of ['preset', 'projection']) {
    $(name).addEventListener('change', (event) => {
      forgetUnknown(event.target);
      scheduleDepth();
      emit(EVENTS.schedule);
    });
  }
  for (const view of ['raw', 'rectified']) {
    $(`frames-${view}`).addEventListener('change', () => showView(view));
  }
  $('blend').addEventListener('change', () => {
    const on = $('blend').checked;
    // A raw pair's depth map lies over the rectified left image, not the raw one.
    if (on && rawPair() && pair.view === 'raw') showView('rectified');
    $('views').dataset.blend = String(on);
    $('opacity').disabled = !on;
    $('blend-canvas').style.opacity = on ? String(Number($('opacity').value) / 100) : '0';
  });
  $('show-sigma').addEventListener('change', () => drawDepth());
  $('opacity').addEventListener('input', () => {
    $('blend-canvas').style.opacity = String(Number($('opacity').value) / 100);
  });
  $('downloads').addEventListener('click', (event) => {
    const button = event.target.closest('button[data-output]');
    if (button) download(button.dataset.output);
  });
}

on(EVENTS.scheduleDepth, scheduleDepth);
on(EVENTS.showRigNeeded, showRigNeeded);
on(EVENTS.forgetFindings, forgetFindings);
