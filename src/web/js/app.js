// The page's entry (loaded as `<script type="module">`): its modes (Numbers, Images,
// Calibrate, Live), each a module of its own, switched in place and kept in the address; and the wiring of the
// form every mode shares. Every number comes from the service's API: the page computes
// nothing itself.

import { openCalibrationSample, readCalibrateQuery, rememberCalibrate, wireCalibrate } from './calibrate.js';
import { wireCheck } from './check.js';
import { fetchPair, loadPair, openSample, requestDepth, scheduleDepth, wireImages } from './images.js';
import { wirePointing } from './findings.js';
import { enterLive, leaveLive, nameInUse, useLiveCalibration, wireLive } from './live.js';
import { compute, copyResults, copyText, permalink, reset, schedule } from './numbers.js';
import {
  FOCAL_MODES, RIG_INPUTS, forgetUnknown, forgetUnknownScale, importCalibration, readForm, showFocalMode, showUnit,
  stateFromQuery, writeForm,
} from './rig.js';
import { EVENTS, emit, pair } from './store.js';
import { $, page } from './util.js';

const MODES = ['numbers', 'images', 'calibrate', 'live'];
const status = $('status');

function modeFromQuery(search) {
  const asked = new URLSearchParams(search).get('mode');
  return MODES.includes(asked) ? asked : 'numbers';
}

function setMode(next) {
  if (page.mode === 'live' && next !== 'live') leaveLive();
  page.mode = next;
  document.body.dataset.mode = next;
  $('images').hidden = next !== 'images';
  $('calibrate').hidden = next !== 'calibrate';
  $('live').hidden = next !== 'live';
  if (next === 'live') enterLive();
  for (const name of MODES) {
    const link = $(`mode-${name}`);
    if (name === next) link.setAttribute('aria-current', 'page');
    else link.removeAttribute('aria-current');
  }
}

/** After an imported calibration: the numbers again, and the pair's depth in Images mode. */
function imported(note) {
  compute(note);
  if (page.mode === 'images') requestDepth();
}

/** Shows a mode: Calibrate keeps its own address (the board and the model); the others
 * compute the form, and Images matches its pair if it has not yet. */
function enter(name) {
  setMode(name);
  if (name === 'calibrate') {
    if ($('board_columns').value === '') readCalibrateQuery('');
    rememberCalibrate();
    document.body.dataset.state = 'done';
    return;
  }
  if (name === 'live') {
    // The address keeps the rig under Inputs, so that Back and a reload stream with it.
    history.replaceState(null, '', permalink(readForm()));
    document.body.dataset.state = 'done';
    return;
  }
  compute();
  if (name === 'images' && pair.files.left && pair.files.right && !pair.arrays) requestDepth();
}

for (const name of MODES) {
  $(`mode-${name}`).addEventListener('click', (event) => {
    if (event.ctrlKey || event.metaKey || event.shiftKey || event.button !== 0) return;
    event.preventDefault();
    enter(name);
  });
}

/** "Use this calibration": Images mode with the calibration imported as a file would be (so
 * raw frames are rectified by the service), the rig's σ in its fields, and for the sample its
 * raw pair, matched at once. */
async function useCalibration(summary, yaml, sample, from = null) {
  $('calibration_text').value = yaml;
  $('calibration_right_text').value = '';
  $('calibration_unit').value = '';
  const withSigma = () => {
    const state = readForm();
    state.focal_length_std_px = String(summary.rig.focal_length_std_px ?? '');
    state.baseline_std = String(summary.rig.baseline_std ?? '');
    return state;
  };
  if (from === 'live') {
    // Views grabbed live: back to Live mode, streaming with the calibration at once.
    await importCalibration(async () => writeForm(withSigma()));
    if (!$('import-errors').hidden) return;
    history.pushState(null, '', '/?mode=live');
    setMode('live');
    useLiveCalibration();
    return;
  }
  setMode('images');
  await importCalibration(async (note) => {
    const state = withSigma();
    if (sample) state.max_disparity = String(sample.raw.max_disparity);
    writeForm(state);
    if (sample) {
      const files = await fetchPair((side) => [sample.raw[side], `raw_${side}.png`]);
      $('depth-status').textContent = `The sample's raw pair: a textured wall ${sample.raw.distance} ${sample.raw.unit} from the cameras.`;
      compute(`${note} From Calibrate mode, with its σ.`);
      await loadPair(files);
      return;
    }
    compute(`${note} From Calibrate mode, with its σ.`);
    if (pair.files.left && pair.files.right) requestDepth();
    else $('depth-status').textContent = 'Calibration in use: choose a raw left and right image from these cameras; the service rectifies them.';
  });
  if (!$('import-errors').hidden) $('import').open = true;
}
$('import-button').addEventListener('click', () => importCalibration(imported));
$('calibration_file').addEventListener('change', async (event) => {
  const file = event.target.files[0];
  if (!file) return;
  $('calibration_text').value = await file.text();
  importCalibration(imported);
});
wireImages();
wirePointing();
wireCalibrate(useCalibration);
wireCheck();
/** Live mode's grabbed board views, calibrated in Calibrate mode as chosen files would be. */
function calibrateGrabbed(files) {
  history.pushState(null, '', '/?mode=calibrate');
  enter('calibrate');
  return emit(EVENTS.calibratePairs, files, 'live')[0];
}
wireLive(calibrateGrabbed);


$('calculator').addEventListener('input', (event) => {
  if (RIG_INPUTS.includes(event.target.id)) page.rigTouched = true;
  if (event.target.matches('input[type="text"]')) {
    schedule();
    scheduleDepth();
  }
});
$('calculator').addEventListener('change', (event) => {
  if (event.target.id === 'calibration_unit') return;
  if (RIG_INPUTS.includes(event.target.id)) page.rigTouched = true;
  if (event.target.tagName === 'SELECT') forgetUnknown(event.target);
  if (event.target.id === 'focal_mode' && event.target.value in FOCAL_MODES) showFocalMode(event.target.value);
  if (event.target.id === 'unit') showUnit(event.target.value);
  if (event.target.tagName === 'SELECT') {
    compute();
    scheduleDepth();
  }
});
$('calculator').addEventListener('submit', (event) => {
  event.preventDefault();
  compute();
});
$('rows').addEventListener('change', (event) => {
  forgetUnknown(event.target);
  compute();
});
$('log').addEventListener('change', () => {
  forgetUnknownScale();
  compute();
});
$('reset').addEventListener('click', reset);
$('rig-needed-import').addEventListener('click', () => {
  $('import').open = true;
  $('import').scrollIntoView({ block: 'start' });
  $('calibration_file').focus();
});
$('copy').addEventListener('click', copyResults);
$('permalink').addEventListener('click', async (event) => {
  // A plain click copies the address; a modified click opens it as links do.
  if (event.ctrlKey || event.metaKey || event.shiftKey || event.button !== 0) return;
  event.preventDefault();
  const copied = await copyText(new URL($('permalink').href, location.href).href);
  status.textContent = copied
    ? 'Copied the permalink; the address bar holds it too.'
    : 'The address bar holds the permalink.';
});
window.addEventListener('popstate', () => {
  setMode(modeFromQuery(location.search));
  writeForm(stateFromQuery(location.search));
  if (page.mode === 'live') nameInUse();
  if (page.mode === 'calibrate') readCalibrateQuery(location.search);
  else if (page.mode !== 'live') compute();
});

setMode(modeFromQuery(location.search));
writeForm(stateFromQuery(location.search));
if (page.mode === 'live') nameInUse();
const sample = new URLSearchParams(location.search).get('sample') === '1';
if (page.mode === 'calibrate') {
  readCalibrateQuery(location.search);
  rememberCalibrate();
  document.body.dataset.state = 'done';
  if (sample) openCalibrationSample();
} else if (page.mode === 'images' && sample) {
  openSample();
} else if (page.mode === 'live') {
  document.body.dataset.state = 'done';
} else {
  compute();
}
