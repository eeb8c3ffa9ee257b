// Calibrate mode's check of a calibration: the calibration file (OpenCV YAML, or the ROS
// pair) and raw pairs of any scene, paired by name, sent to /calibration/check (with the
// board above when the pairs show it); the verdict, the rows before and after over a 3 × 3
// grid of the image, the correction with its σ, and the corrected calibration to download.
// The service does the checking: the page sends the files and shows the answer.

import { postWithProgress, save } from './api.js';
import { pairFiles } from './calibrate.js';
import { EVENTS, emit } from './store.js';
import { $, fmt } from './util.js';

/** What the check holds: the pairs chosen, and the last answer. */
const check = { pairs: [], answer: null };

/** The form: the calibration's file(s), the pairs, and the board when asked. */
function checkForm() {
  const body = new FormData();
  const files = [...$('check_calibration').files];
  // A ROS pair: the file naming the right camera goes second.
  files.sort((a, b) => Number(/right/i.test(a.name)) - Number(/right/i.test(b.name)));
  if (files[0]) body.append('calibration', files[0], files[0].name);
  if (files[1]) body.append('right_calibration', files[1], files[1].name);
  for (const pair of check.pairs) {
    body.append('left', pair.left, pair.left.name);
    body.append('right', pair.right, pair.right.name);
  }
  if ($('check_board').checked) {
    const [board] = emit(EVENTS.boardPart);
    if (board) body.append('board', board);
  }
  return body;
}

/** One grid of row offsets: each cell's mean (px) and its match count, shaded by size. */
function showGrid(id, cells, which) {
  const table = $(id);
  table.replaceChildren();
  for (let row = 0; row < 3; row += 1) {
    const tr = document.createElement('tr');
    for (let column = 0; column < 3; column += 1) {
      const cell = cells.find((c) => c.row === row && c.column === column)?.[which];
      const td = document.createElement('td');
      if (cell && cell.mean !== undefined) {
        td.textContent = `${fmt(cell.mean, 2)} px`;
        td.title = `${cell.matches} matches, RMS ${fmt(cell.rms, 3)} px`;
        const size = Math.min(1, Math.abs(cell.mean) / 0.5);
        td.style.background = `rgba(198, 40, 40, ${(0.08 + 0.6 * size).toFixed(2)})`;
        td.dataset.mean = String(cell.mean);
      } else {
        td.textContent = '–';
        td.title = 'no match here';
      }
      tr.append(td);
    }
    table.append(tr);
  }
}

/** The correction's rows: each estimate with its σ, and what the drift does to a distance. */
function showCorrection(answer) {
  const table = $('check-correction');
  table.replaceChildren();
  const add = (name, text) => {
    const tr = document.createElement('tr');
    const th = document.createElement('th');
    th.textContent = name;
    const td = document.createElement('td');
    td.textContent = text;
    tr.append(th, td);
    table.append(tr);
  };
  const c = answer.correction;
  for (const axis of ['x', 'y', 'z']) {
    const e = c.rotation_deg[axis];
    if (e) add(`Right camera turned about ${axis}`, `${fmt(e.value, 4)}° ± ${fmt(e.std, 2)}°`);
  }
  if (c.focal_ratio) add('Right fy / calibrated fy', `${fmt(c.focal_ratio.value, 6)} ± ${fmt(c.focal_ratio.std, 2)}`);
  if (c.baseline_ratio) add('Baseline / calibrated', `${fmt(c.baseline_ratio.value, 6)} ± ${fmt(c.baseline_ratio.std, 2)}`);
  for (const e of answer.depth_effect) {
    add(`A distance of ${fmt(e.distance, 4)} ${e.unit} reads`, `${fmt(e.error_largest, 3)} ${e.unit} off at most (the calibration's own σ ${fmt(e.calibration_std, 3)})`);
  }
  if (answer.distance) {
    const d = answer.distance;
    add(`Known distances (${d.points} points, ~${fmt(d.median_distance, 4)} ${d.unit})`,
      `error ${fmt(d.before.mean, 3)} ${d.unit} before, ${fmt(d.after.mean, 3)} after`);
  }
  const unseen = $('check-unseen');
  unseen.replaceChildren(...c.unseen.map((text) => {
    const li = document.createElement('li');
    li.textContent = text;
    return li;
  }));
}

/** Sends the check and shows its answer, or names what the service refused. */
async function runCheck() {
  const status = $('check-status');
  for (const id of ['check_calibration', 'check_files']) $(`${id}-error`).hidden = true;
  if ($('check_calibration').files.length === 0 || check.pairs.length === 0) {
    const id = $('check_calibration').files.length === 0 ? 'check_calibration' : 'check_files';
    $(`${id}-error`).textContent = id === 'check_files'
      ? 'Choose raw pairs (left and right images, paired by name).'
      : 'Choose the calibration to check.';
    $(`${id}-error`).hidden = false;
    return;
  }
  document.body.dataset.check = 'computing';
  status.textContent = `Checking against ${check.pairs.length} ${check.pairs.length === 1 ? 'pair' : 'pairs'}…`;
  try {
    const answer = await postWithProgress('/calibration/check', '', checkForm());
    if (!answer.ok) {
      $('check-results').hidden = true;
      $('check-download').hidden = true;
      status.textContent = `Not checked: ${answer.errors.map((e) => `${e.field}: ${e.message}`).join(' ')}`;
      return;
    }
    const json = answer.json;
    check.answer = json;
    $('check-verdict').textContent = json.verdict;
    $('check-verdict').className = `verdict ${json.holds ? 'verdict-good' : 'verdict-poor'}`;
    $('check-results').dataset.holds = String(json.holds);
    showGrid('check-before', json.rows.over_image, 'before_px');
    showGrid('check-after', json.rows.over_image, 'after_px');
    showCorrection(json);
    $('check-results').hidden = false;
    $('check-download').hidden = json.holds;
    status.textContent = `Checked: ${json.matches.reduce((a, b) => a + b, 0)} matches over ${json.matches.length} ${json.matches.length === 1 ? 'pair' : 'pairs'}.`;
  } catch (error) {
    status.textContent = `Not checked: ${error.message}.`;
  } finally {
    document.body.dataset.check = 'done';
  }
}

/** The corrected calibration, as OpenCV's YAML. */
async function downloadCorrected() {
  const answer = await postWithProgress('/calibration/check', 'output=opencv.yml', checkForm()).catch(() => null);
  if (answer && answer.ok) save(answer.blob, 'corrected_calibration.yml');
  else $('check-status').textContent = 'No corrected calibration: check again.';
}

export function wireCheck() {
  $('check_files').addEventListener('change', (event) => {
    const { pairs, unpaired } = pairFiles([...event.target.files]);
    check.pairs = pairs;
    const count = `${pairs.length} ${pairs.length === 1 ? 'pair' : 'pairs'}`;
    $('check-pairing').textContent = unpaired.length === 0 ? `${count}.` : `${count}; not paired: ${unpaired.join('; ')}.`;
  });
  $('check-button').addEventListener('click', () => runCheck());
  $('check-download').addEventListener('click', () => downloadCorrected());
}
