// Calibrate mode: board pairs chosen or dropped (paired by name), the board (a chessboard or
// a ChArUco board, with its picture) and the lens model, sent to /calibrate with progress,
// elapsed time and a cancel; the answer shown by calibrate-view.js; a view left out by a click and the rest calibrated again; the files
// downloaded; and "Use this calibration", which takes the rig and its uncertainty to Images
// mode (or back to Live mode, whose grabbed board views it was given). The service does the calibrating: the page sends the files and shows the answer.

import { fetchFile, fetchJson, postWithProgress, save } from './api.js';
import { drawBoardPicture, showCalibration, wireBars } from './calibrate-view.js';
import { EVENTS, on } from './store.js';
import { $, clearFieldErrors, fmt, page, setFiles, showFieldErrors } from './util.js';

/** The board's text fields and the `board` part's member each is. */
const BOARD_FIELDS = {
  board_columns: 'columns', board_rows: 'rows', squares_x: 'squares_x', squares_y: 'squares_y', square_size: 'square_size', marker_size: 'marker_size',
};
/** Each board type's text fields and their defaults: OpenCV's sample chessboard (10 × 7
 * squares of 25 mm), and the ChArUco board of 8 × 6 squares of 30 mm with 22 mm markers. */
const BOARD_DEFAULTS = {
  chessboard: { board_columns: '9', board_rows: '6', square_size: '25' },
  charuco: { squares_x: '8', squares_y: '6', square_size: '30', marker_size: '22' },
};
const DICTIONARIES = ['DICT_4X4_50', 'DICT_5X5_100', 'DICT_6X6_250', 'DICT_ARUCO_ORIGINAL'];
const MODELS = ['plumb_bob', 'rational_polynomial', 'equidistant'];
const UNITS = ['mm', 'cm', 'm', 'in', 'ft'];

/** What Calibrate mode holds. */
export const calibration = {
  /** The pairs, in the order of their names: `{ name, left: File, right: File }`. */
  pairs: [],
  /** Indices of `pairs` the person left out. */
  excluded: new Set(),
  /** The last answer and the indices of `pairs` it was computed from, in order. */
  summary: null,
  sent: [],
  controller: null,
  /** The sample's `boards.json` when the sample is loaded (its raw pair is the wall). */
  sample: null,
  /** The mode the pairs came from (`live`), which "Use this calibration" goes back to. */
  from: null,
};

// ---------------------------------------------------------------------------------------
// Pairing files by name.

/** Which camera a file's path names, and the rest of the path (the pair's key): `left`/
 * `right` anywhere, `L`/`R` as a token of their own (`L_01`, `img_r3`, `01-R`), or `im0`/
 * `im1` and `cam0`/`cam1` as Middlebury and KITTI name them. */
export function sideOf(path) {
  const name = path.toLowerCase().replace(/\.(png|jpe?g)$/, '');
  const patterns = [
    [/left|right/, (m) => (m === 'left' ? 'left' : 'right')],
    [/(?<=^|[^a-z])[lr](?=$|[^a-z])/, (m) => (m === 'l' ? 'left' : 'right')],
    [/(?<=^|[^a-z])(?:im|cam|image_?)[01](?!\d)/, (m) => (m.endsWith('0') ? 'left' : 'right')],
  ];
  for (const [pattern, side] of patterns) {
    const match = pattern.exec(name);
    if (match) {
      const key = `${name.slice(0, match.index)}*${name.slice(match.index + match[0].length)}`;
      return { side: side(match[0]), key };
    }
  }
  return null;
}

/** Pairs `files` by name: `{ pairs, unpaired }`, the pairs in natural order of their names. */
export function pairFiles(files) {
  const byKey = new Map();
  const unpaired = [];
  for (const file of files) {
    const path = file.webkitRelativePath || file.name;
    if (!/\.(png|jpe?g)$/i.test(path)) {
      unpaired.push(`${path} (not a PNG or JPEG)`);
      continue;
    }
    const found = sideOf(path);
    if (!found) {
      unpaired.push(`${path} (names neither camera)`);
      continue;
    }
    const entry = byKey.get(found.key) ?? {};
    if (entry[found.side]) {
      unpaired.push(`${path} (a second ${found.side} image for ${entry[found.side].name})`);
      continue;
    }
    entry[found.side] = file;
    byKey.set(found.key, entry);
  }
  const pairs = [];
  for (const entry of byKey.values()) {
    if (entry.left && entry.right) {
      pairs.push({ name: `${entry.left.webkitRelativePath || entry.left.name} + ${entry.right.webkitRelativePath || entry.right.name}`, left: entry.left, right: entry.right });
    } else {
      const file = entry.left ?? entry.right;
      unpaired.push(`${file.webkitRelativePath || file.name} (no ${entry.left ? 'right' : 'left'} partner)`);
    }
  }
  const collator = new Intl.Collator(undefined, { numeric: true });
  pairs.sort((a, b) => collator.compare(a.left.webkitRelativePath || a.left.name, b.left.webkitRelativePath || b.left.name));
  return { pairs, unpaired };
}

/** Takes chosen or dropped files as the pairs to calibrate. */
export function choosePairs(files, sample = null, from = null) {
  const { pairs, unpaired } = pairFiles(files);
  calibration.from = from;
  $('use-calibration').textContent = from === 'live' ? 'Use this calibration live' : 'Use this calibration';
  calibration.pairs = pairs;
  calibration.excluded = new Set();
  calibration.summary = null;
  calibration.sample = sample;
  $('calibration-results').hidden = true;
  const line = $('pairing');
  line.dataset.pairs = String(pairs.length);
  line.dataset.unpaired = String(unpaired.length);
  const count = `${pairs.length} ${pairs.length === 1 ? 'pair' : 'pairs'}`;
  line.textContent = unpaired.length === 0
    ? `${count} from ${files.length} files.`
    : `${count}; not paired: ${unpaired.join('; ')}.`;
  $('board_files-error').hidden = true;
  rememberCalibrate();
}

// ---------------------------------------------------------------------------------------
// The request.

/** The board type chosen. */
function boardType() {
  return $('board_type').value === 'charuco' ? 'charuco' : 'chessboard';
}

/** Shows the chosen board type's fields and its picture. */
function showBoardType() {
  const type = boardType();
  for (const field of document.querySelectorAll('#calibrate [data-board]')) field.hidden = field.dataset.board !== type;
  $('board-picture-caption').textContent = drawBoardPicture($('inner-corners-picture'), type);
}

/** The `board` part: numbers as numbers, anything else as typed, for the service to judge. */
function boardPart() {
  const type = boardType();
  const board = type === 'charuco'
    ? { type, dictionary: $('dictionary').value, legacy: $('legacy').checked, unit: $('square_unit').value }
    : { unit: $('square_unit').value };
  for (const id of Object.keys(BOARD_DEFAULTS[type])) {
    const text = $(id).value.trim();
    board[BOARD_FIELDS[id]] = text !== '' && Number.isFinite(Number(text)) ? Number(text) : text;
  }
  return JSON.stringify(board);
}

/** The form of the pairs not left out, and which pairs they are. */
function calibrationForm() {
  const body = new FormData();
  const sent = [];
  calibration.pairs.forEach((pair, i) => {
    if (calibration.excluded.has(i)) return;
    body.append('left', pair.left, pair.left.name);
    body.append('right', pair.right, pair.right.name);
    sent.push(i);
  });
  body.append('board', boardPart());
  return { body, sent };
}

function clearCalibrationErrors() {
  clearFieldErrors([...Object.keys(BOARD_FIELDS), 'dictionary', 'board_files'], 'calibrate-errors');
}

/** The problem's errors next to the board field they name, a view's under the file input
 * with the file's name, and the rest in the list. */
function showCalibrationErrors(errors, sent) {
  const fieldOf = Object.fromEntries(Object.entries(BOARD_FIELDS).map(([id, member]) => [`board.${member}`, id]));
  fieldOf['board.dictionary'] = 'dictionary';
  showFieldErrors(errors, ({ field, message }) => {
    const view = /^(left|right)\[(\d+)\]$/.exec(field);
    const input = fieldOf[field] ?? (view || field === 'left' || field === 'right' ? 'board_files' : null);
    if (!input) return null;
    const file = view ? calibration.pairs[sent[Number(view[2])]]?.[view[1]]?.name ?? field : null;
    return { input, text: view ? `${file} (${field}) ${message}` : message };
  }, 'calibrate-errors');
}

function query(output = null) {
  const q = new URLSearchParams({ model: $('lens_model').value });
  if (output) q.set('output', output);
  else {
    q.set('corners', 'true');
    // Two halves of the views calibrated apart say whether the calibration holds together.
    const sending = calibration.pairs.length - calibration.excluded.size;
    if (sending >= 6) q.set('cross_validate', 'true');
  }
  return q;
}

/** Sends the pairs not left out to /calibrate and shows the answer. */
export async function calibrate() {
  clearCalibrationErrors();
  if (calibration.pairs.length === 0) {
    $('board_files-error').textContent = 'Choose the board pairs first (left and right images, paired by name).';
    $('board_files-error').hidden = false;
    $('board_files').setAttribute('aria-invalid', 'true');
    return;
  }
  if (calibration.controller) calibration.controller.abort();
  const controller = new AbortController();
  calibration.controller = controller;
  const { body, sent } = calibrationForm();
  const status = $('calibrate-status');
  const progress = $('calibrate-progress');
  const started = performance.now();
  let uploaded = 0;
  const elapsed = () => `${fmt((performance.now() - started) / 1000, 2)} s`;
  const tell = () => {
    status.textContent = uploaded < 1
      ? `Sending ${sent.length} pairs: ${Math.round(uploaded * 100)} % (${elapsed()})…`
      : `Finding the corners and calibrating ${sent.length} pairs… ${elapsed()}`;
  };
  const timer = setInterval(tell, 200);
  progress.hidden = false;
  progress.removeAttribute('value');
  $('calibrate-cancel').disabled = false;
  document.body.dataset.calibrate = 'computing';
  tell();
  try {
    const answer = await postWithProgress('/calibrate', query(), body, {
      signal: controller.signal,
      onUpload: (fraction) => {
        uploaded = fraction;
        if (fraction < 1) progress.value = fraction;
        else progress.removeAttribute('value');
        tell();
      },
    });
    if (calibration.controller !== controller) return;
    clearInterval(timer);
    if (!answer.ok) {
      showCalibrationErrors(answer.errors, sent);
      status.textContent = `Not calibrated: the service refused the request (${answer.errors.length} ${answer.errors.length === 1 ? 'problem' : 'problems'}), after ${elapsed()}.`;
      return;
    }
    calibration.summary = answer.json;
    calibration.sent = sent;
    const thumbs = showCalibration(calibration);
    status.textContent = `Calibrated from ${sent.length} pairs in ${elapsed()}: RMS ${fmt(answer.json.rms, 3)} px.`;
    await thumbs;
  } catch (error) {
    if (calibration.controller !== controller) return;
    status.textContent = error.name === 'AbortError'
      ? `Cancelled after ${elapsed()}; nothing was calibrated.`
      : `Not calibrated: ${error.message}.`;
  } finally {
    clearInterval(timer);
    if (calibration.controller === controller) {
      calibration.controller = null;
      progress.hidden = true;
      $('calibrate-cancel').disabled = true;
      document.body.dataset.calibrate = 'done';
    }
  }
}

/** Leaves pair `i` out (or puts it back) and calibrates again. */
export function toggleView(i) {
  if (calibration.excluded.has(i)) calibration.excluded.delete(i);
  else calibration.excluded.add(i);
  calibrate();
}

/** One of /calibrate's files for the same pairs, saved under a name users expect. */
async function download(output) {
  const line = $('calibration-download-status');
  const names = { 'opencv.yml': 'stereo_calibration.yml', 'ros-left.yaml': 'left.yaml', 'ros-right.yaml': 'right.yaml' };
  line.textContent = `Preparing ${names[output]}…`;
  const { body } = calibrationForm();
  try {
    const answer = await postWithProgress('/calibrate', query(output), body);
    if (!answer.ok) {
      line.textContent = `No ${names[output]}: ${answer.errors.map((e) => `${e.field}: ${e.message}`).join(' ')}`;
      return null;
    }
    save(answer.blob, names[output]);
    line.textContent = `Saved ${names[output]} (${fmt(answer.blob.size / 1024, 3)} KiB).`;
    return answer.blob;
  } catch (error) {
    line.textContent = `No ${names[output]}: ${error.message}.`;
    return null;
  }
}

// ---------------------------------------------------------------------------------------
// The address: the board and the model, and the sample.

/** Keeps the board and the model in the address (Calibrate mode only). */
export function rememberCalibrate() {
  if (page.mode !== 'calibrate') return;
  const q = new URLSearchParams({ mode: 'calibrate' });
  if (calibration.sample || (calibration.pairs.length === 0 && new URLSearchParams(location.search).get('sample') === '1')) q.set('sample', '1');
  const type = boardType();
  if (type === 'charuco') q.set('board', type);
  for (const id of Object.keys(BOARD_DEFAULTS[type])) q.set(BOARD_FIELDS[id], $(id).value.trim());
  if (type === 'charuco') {
    q.set('dictionary', $('dictionary').value);
    if ($('legacy').checked) q.set('legacy', 'true');
  }
  q.set('square_unit', $('square_unit').value);
  q.set('model', $('lens_model').value);
  history.replaceState(null, '', `${location.pathname}?${q}`);
}

/** The board and model an address gives (the defaults for the rest). */
export function readCalibrateQuery(search) {
  const q = new URLSearchParams(search);
  const type = q.get('board') === 'charuco' ? 'charuco' : 'chessboard';
  $('board_type').value = type;
  // The other type's defaults first, so the square size shared by both is this type's.
  for (const t of type === 'charuco' ? ['chessboard', 'charuco'] : ['charuco', 'chessboard']) {
    for (const [id, fallback] of Object.entries(BOARD_DEFAULTS[t])) $(id).value = (t === type ? q.get(BOARD_FIELDS[id]) : null) ?? fallback;
  }
  const dictionary = q.get('dictionary');
  $('dictionary').value = DICTIONARIES.includes(dictionary) ? dictionary : 'DICT_4X4_50';
  $('legacy').checked = q.get('legacy') === 'true';
  showBoardType();
  const unit = q.get('square_unit');
  $('square_unit').value = UNITS.includes(unit) ? unit : 'mm';
  const model = q.get('model');
  $('lens_model').value = MODELS.includes(model) ? model : 'plumb_bob';
}

/** `/?mode=calibrate&sample=1`: the project's own rendered board pairs, calibrated at once. */
export async function openCalibrationSample() {
  const status = $('calibrate-status');
  status.textContent = 'Loading the sample board set…';
  try {
    const about = await fetchJson('/sample/boards/boards.json');
    const files = [];
    for (const side of ['left', 'right']) {
      for (const path of about[side]) files.push(await fetchFile(path, path.split('/').pop()));
    }
    $('board_type').value = 'chessboard';
    showBoardType();
    $('board_columns').value = String(about.board.columns);
    $('board_rows').value = String(about.board.rows);
    $('square_size').value = String(about.board.square_size);
    $('square_unit').value = about.board.unit;
    $('lens_model').value = about.model;
    setFiles('board_files', files);
    choosePairs(files, about);
    await calibrate();
  } catch (error) {
    status.textContent = `The sample could not be loaded (${error.message}).`;
  }
}

/** Calibrate mode's controls. `useCalibration(summary, yaml, sample, from)` takes the result
 * to Images mode, or back to Live mode when the pairs were grabbed there. */
export function wireCalibrate(useCalibration) {
  showBoardType();
  $('board_type').addEventListener('change', () => {
    showBoardType();
    rememberCalibrate();
  });
  wireBars(toggleView);
  for (const id of ['board_files', 'board_folder']) {
    $(id).addEventListener('change', (event) => choosePairs([...event.target.files]));
  }
  const section = $('calibrate');
  section.addEventListener('dragover', (event) => {
    event.preventDefault();
    $('board_files-field').classList.add('over');
  });
  section.addEventListener('dragleave', () => $('board_files-field').classList.remove('over'));
  section.addEventListener('drop', (event) => {
    event.preventDefault();
    $('board_files-field').classList.remove('over');
    const files = [...event.dataTransfer.files];
    if (files.length > 0) choosePairs(files);
  });
  for (const id of [...Object.keys(BOARD_FIELDS), 'dictionary', 'legacy', 'square_unit', 'lens_model']) $(id).addEventListener('change', rememberCalibrate);
  $('calibrate-button').addEventListener('click', () => calibrate());
  $('calibrate-cancel').addEventListener('click', () => {
    if (calibration.controller) calibration.controller.abort();
  });
  $('calibrate-sample-link').addEventListener('click', (event) => {
    if (event.ctrlKey || event.metaKey || event.shiftKey || event.button !== 0) return;
    event.preventDefault();
    openCalibrationSample();
  });
  $('calibration-results').addEventListener('click', (event) => {
    const button = event.target.closest('button[data-output]');
    if (button) download(button.dataset.output);
  });
  on(EVENTS.boardPart, () => {
    // Calibrate mode not yet shown: its board is the default one.
    if ($('board_columns').value === '' && $('squares_x').value === '') readCalibrateQuery('');
    return boardPart();
  });
  on(EVENTS.calibratePairs, (files, from) => {
    setFiles('board_files', files);
    choosePairs(files, null, from);
    return calibrate();
  });
  $('use-calibration').addEventListener('click', async () => {
    const line = $('calibration-download-status');
    line.textContent = `Preparing the calibration for ${calibration.from === 'live' ? 'Live' : 'Images'} mode…`;
    const { body } = calibrationForm();
    const answer = await postWithProgress('/calibrate', query('opencv.yml'), body).catch((error) => ({ ok: false, errors: [{ field: 'service', message: error.message }] }));
    if (!answer.ok) {
      line.textContent = `Not used: ${answer.errors.map((e) => `${e.field}: ${e.message}`).join(' ')}`;
      return;
    }
    line.textContent = '';
    useCalibration(calibration.summary, await answer.blob.text(), calibration.sample, calibration.from);
  });
}
