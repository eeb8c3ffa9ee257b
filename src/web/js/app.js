// The page's entry (loaded as `<script type="module">`): its modes (Numbers, Images), each
// a module of its own, switched in place and kept in the address; and the wiring of the
// form every mode shares. Every number comes from the service's API: the page computes
// nothing itself.

import { openSample, pair, requestDepth, scheduleDepth, wireImages } from './images.js';
import { wirePointing } from './findings.js';
import { compute, copyResults, copyText, reset, schedule } from './numbers.js';
import {
  FOCAL_MODES, RIG_INPUTS, forgetUnknown, forgetUnknownScale, importCalibration, showFocalMode, showUnit, stateFromQuery, writeForm,
} from './rig.js';
import { $, page } from './util.js';

const MODES = ['numbers', 'images'];
const status = $('status');

function modeFromQuery(search) {
  const asked = new URLSearchParams(search).get('mode');
  return MODES.includes(asked) ? asked : 'numbers';
}

function setMode(next) {
  page.mode = next;
  document.body.dataset.mode = next;
  $('images').hidden = next !== 'images';
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

for (const name of MODES) {
  $(`mode-${name}`).addEventListener('click', (event) => {
    if (event.ctrlKey || event.metaKey || event.shiftKey || event.button !== 0) return;
    event.preventDefault();
    setMode(name);
    compute();
    if (name === 'images' && pair.files.left && pair.files.right && !pair.arrays) requestDepth();
  });
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
  compute();
});

setMode(modeFromQuery(location.search));
writeForm(stateFromQuery(location.search));
if (page.mode === 'images' && new URLSearchParams(location.search).get('sample') === '1') {
  openSample();
} else {
  compute();
}
