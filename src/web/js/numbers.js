// Numbers mode: the calculator. The form goes to /distance, /chart-data and /table, and
// their answers are shown as the distance card, the chart and the table; the address always
// holds the state, and the buttons copy, reset and link it.

import { call, problemsOf } from './api.js';
import { showChart } from './draw.js';
import {
  CHART_POINTS, DEFAULTS, choiceErrors, clearErrors, readForm, rigGiven, rigParams, showErrors, withMembers,
  writeForm,
} from './rig.js';
import { EVENTS, NEEDS_RIG, emit, matched, on, pair } from './store.js';
import { $, DEBOUNCE_MS, fmt, listItem, page, percent } from './util.js';

const results = $('results');
const status = $('status');

/** The page's own address for a state: the API's members plus the view settings. */
export function permalink(state) {
  const params = new URLSearchParams();
  if (page.mode !== 'numbers') params.set('mode', page.mode);
  if (page.mode === 'images' && pair.sample) params.set('sample', '1');
  params.set('focal_mode', state.focal_mode);
  const feature = page.mode === 'images' ? ['min_disparity', 'max_disparity', 'max_disparity_std'] : ['x_left', 'x_right', 'y'];
  for (const [key, value] of withMembers(rigParams(state), state, feature)) {
    params.set(key, value);
  }
  params.set('rows', state.rows);
  params.set('scale', state.scale);
  if (page.mode === 'images' && state.preset !== 'accurate') params.set('preset', state.preset);
  if (page.mode === 'images' && state.projection !== 'pinhole') params.set('projection', state.projection);
  return `${location.pathname}?${params}`;
}

/** The match whose σ_d is the clicked point's error bar: Images mode, a match with a σ_d,
 * and no Δd typed in the form (a Δd the user types is theirs, and named so). */
function sigmaMatch(state) {
  const m = pair.match;
  return page.mode === 'images' && state.disparity_error_px === '' && matched() && m.disparity_std_px !== undefined
    ? m
    : null;
}

/** /distance's members: the feature, and in Images mode the match's σ_d as its Δd, so that
 * its `depth_error` is the one error bar σ_Z that /match answers as `distance_std`. */
function distanceParams(rig, state) {
  const params = withMembers(rig, state, ['x_left', 'x_right', 'y']);
  const m = sigmaMatch(state);
  if (m) params.set('disparity_error_px', String(m.disparity_std_px));
  return params;
}

let generation = 0;
let inFlight = null;
let debounce = null;
let lastResult = null;

/** Sends the form to the API and shows what comes back (after `note`, if given, in the
 * status line); older answers are dropped. */
export async function compute(note = '') {
  clearTimeout(debounce);
  const state = readForm();
  const token = ++generation;
  if (inFlight) inFlight.abort();
  inFlight = new AbortController();
  const { signal } = inFlight;
  const refused = choiceErrors(state);
  if (refused.length > 0) {
    // Nothing is computed in a choice nobody made; the address keeps what was asked.
    clearErrors();
    const fields = showErrors(refused, state);
    showDistance(null, state);
    showChart(null, false);
    showTable(null, new URLSearchParams());
    status.textContent = (note ? `${note} ` : '') +
      `No distance: ${fields} ${fields === 1 ? 'choice needs' : 'choices need'} attention.`;
    document.body.dataset.state = 'done';
    return;
  }
  const address = permalink(state);
  history.replaceState(null, '', address);
  $('permalink').href = address;
  results.setAttribute('aria-busy', 'true');
  document.body.dataset.state = 'computing';
  try {
    const rig = rigParams(state);
    // In Images mode the feature is the last click's match; until there is one, only the
    // rig's chart and table are asked for.
    emit(EVENTS.showRigNeeded);
    const noRig = page.mode === 'images' && !rigGiven(state);
    const measuring = page.mode === 'numbers' || (matched() && !noRig);
    const distance = measuring
      ? await call('/distance', distanceParams(rig, state), signal)
      : { ok: false, status: 0, body: null, unasked: true };
    // The chart marks, and the table follows, the measured feature only when it is valid.
    const measured = distance.ok ? ['x_left', 'x_right'] : [];
    const chartParams = withMembers(rig, state, measured);
    chartParams.set('points', String(CHART_POINTS));
    const tableParams = withMembers(rig, state, measured.slice(0, 1));
    tableParams.set('steps', state.rows);
    // In Images mode the image size comes with the pair: until then the rig's chart and
    // table (which need it) are not asked for.
    // Without a rig there is no chart or table of it either.
    const sized = page.mode === 'numbers' || (!noRig && state.image_width !== '' && state.image_height !== '');
    const unasked = { ok: false, status: 0, body: null, unasked: true };
    const [chart, table] = sized
      ? await Promise.all([call('/chart-data', chartParams, signal), call('/table', tableParams, signal)])
      : [unasked, unasked];
    if (token !== generation) return;
    clearErrors();
    const errors = [distance, chart, table].filter((a) => !a.ok && !a.unasked).flatMap(problemsOf);
    const fields = showErrors(errors, state);
    // Nothing asked is nothing wrong: a prompt, not the marked-fields warning.
    const prompt = !distance.unasked ? null : noRig ? NEEDS_RIG : pair.match
      ? `No distance: ${pair.match.status.replace('_', ' ')}.`
      : 'Click the left image for a distance.';
    showDistance(distance.ok ? distance.body : null, state, prompt);
    showChart(chart.ok ? chart.body : null, state.scale === 'log');
    showTable(table.ok ? table.body : null, tableParams);
    const chartSvg = new URLSearchParams(chartParams);
    chartSvg.delete('points');
    $('chart-svg-link').href = `/chart.svg?${chartSvg}`;
    status.textContent = (note ? `${note} ` : '') + (distance.ok
      ? `Distance ${fmt(distance.body.distance)} ${distance.body.unit} ± ${fmt(distance.body.depth_error)} ${distance.body.unit}.`
      : distance.unasked && fields === 0
        ? noRig ? NEEDS_RIG : 'Rig ready; click the left image for a distance.'
        : `No distance: ${fields} ${fields === 1 ? 'field needs' : 'fields need'} attention.`);
  } catch (error) {
    if (error.name === 'AbortError' || token !== generation) return;
    clearErrors();
    showErrors([{ field: 'service', message: `could not be reached (${error.message}).` }], state);
    showDistance(null, state);
    status.textContent = 'The service could not be reached.';
  } finally {
    if (token === generation) {
      results.removeAttribute('aria-busy');
      document.body.dataset.state = 'done';
    }
  }
}

export function schedule() {
  clearTimeout(debounce);
  document.body.dataset.state = 'pending';
  debounce = setTimeout(() => compute(), DEBOUNCE_MS);
}


/** Images mode, a clicked point's distance: its error bar from the match (σ_Z of the match's
 * σ_d with the rig's σ_f and σ_B), split into what the matching and the calibration add. */
function showErrorSplit(answer) {
  const split = $('error-split');
  const m = pair.match;
  split.hidden = !(page.mode === 'images' && m && m.distance_std !== undefined
    && m.disparity_px !== undefined && Math.abs(m.disparity_px - answer.disparity_px) < 1e-6);
  if (split.hidden) return;
  const unit = answer.unit;
  const terms = answer.depth_error_terms;
  const calibration = Math.hypot(terms.focal_length, terms.baseline);
  const matching = Math.sqrt(Math.max(0, m.distance_std ** 2 - calibration ** 2));
  split.dataset.matching = String(matching);
  split.dataset.calibration = String(calibration);
  split.textContent = `From the match: ± ${fmt(m.distance_std, 3)} ${unit} in all, of which ` +
    `matching ± ${fmt(matching, 3)} ${unit} (σ_d = ${fmt(m.disparity_std_px, 3)} px) and ` +
    `calibration ± ${fmt(calibration, 3)} ${unit} (σ_f, σ_B).`;
}

/** What the error bar stands on: `sigma` (the match's σ_d with the rig's σ_f and σ_B) or
 * `fixed` (a Δd: the one typed, or the calculator's default). */
function basisOf(state) {
  return sigmaMatch(state) ? 'sigma' : 'fixed';
}

function basisText(answer, state) {
  if (basisOf(state) === 'sigma') {
    return `(± is σ: the match's σ_d = ${fmt(answer.disparity_error_px, 3)} px with the rig's σ_f and σ_B)`;
  }
  const typed = state.disparity_error_px !== '';
  return `for a fixed Δd = ${fmt(answer.disparity_error_px)} px (${typed ? 'typed' : 'the default'})`;
}

/** Shows a distance answer; without one, `prompt` (when nothing was asked, so nothing is
 * wrong) or the marked-fields warning. */
export function showDistance(answer, state, prompt = null) {
  lastResult = answer;
  // Images mode: the clicked point's distance card, in short, beside its match.
  const short = $('match-distance');
  short.hidden = !(page.mode === 'images' && answer !== null && pair.match !== null);
  if (!short.hidden) {
    short.textContent = `Distance ${fmt(answer.distance, 5)} ${answer.unit} ± ${fmt(answer.depth_error, 3)} ${answer.unit}, ` +
      `range ${fmt(answer.range, 5)} ${answer.unit} (the Distance card below has the rest).`;
  }
  const wrong = answer === null && prompt === null;
  results.classList.toggle('invalid', wrong);
  const mini = $('mini-result');
  mini.classList.toggle('invalid', wrong);
  mini.textContent = answer !== null
    ? `Z = ${fmt(answer.distance)} ${answer.unit} ± ${fmt(answer.depth_error)} ${answer.unit}`
    : prompt ?? 'No distance: see the marked fields.';
  if (answer === null) {
    $('distance').textContent = '–';
    $('depth-error').textContent = '';
    $('distance-detail').textContent = prompt ?? 'Correct the marked fields to see a distance.';
    for (const id of ['disparity_px', 'effective_disparity_px', 'focal_length_px', 'normalized_x', 'projection_factor', 'point', 'range']) {
      $(id).textContent = '–';
    }
    $('warnings').replaceChildren(listItem('None.'));
    $('formula').textContent = 'Z = B·f / |d + doffs|';
    return;
  }
  const unit = answer.unit;
  $('distance').textContent = `${fmt(answer.distance)} ${unit}`;
  $('depth-error').textContent = `± ${fmt(answer.depth_error)} ${unit}`;
  $('depth-error').dataset.basis = basisOf(state);
  $('distance-detail').textContent =
    `${fmt(answer.distance_m)} m · relative error ${percent(answer.relative_error)} ${basisText(answer, state)}`;
  showErrorSplit(answer);
  $('disparity_px').textContent = `${fmt(answer.disparity_px)} px`;
  $('effective_disparity_px').textContent = `${fmt(answer.effective_disparity_px)} px`;
  $('focal_length_px').textContent = state.focal_mode === 'px'
    ? `${fmt(answer.focal_length_px)} px`
    : `${fmt(answer.focal_length_px)} px (converted)`;
  $('normalized_x').textContent = fmt(answer.normalized_x);
  $('projection_factor').textContent = `${fmt(answer.projection_factor)} px/${unit}`;
  // Without a principal point (no cx, cy or image size) the service answers the depth alone.
  const p = answer.point;
  $('point').textContent = p ? `(${fmt(p.x)}, ${fmt(p.y)}, ${fmt(p.z)}) ${unit}` : '– (needs cx, cy or the image size)';
  $('range').textContent = answer.range === undefined ? '–' : `${fmt(answer.range)} ${unit}`;
  const warnings = answer.warnings.map((w) => {
    const item = listItem(w.message);
    item.className = 'warning';
    item.dataset.code = w.code;
    return item;
  });
  $('warnings').replaceChildren(...(warnings.length > 0 ? warnings : [listItem('None.')]));
  $('formula').textContent = answer.formula;
}

/** The plain-text summary "Copy results" puts on the clipboard. */
function summary(answer) {
  const u = answer.unit;
  const lines = [
    `Stereo distance: ${fmt(answer.distance)} ${u} ± ${fmt(answer.depth_error)} ${u} (${fmt(answer.distance_m)} m; relative error ${percent(answer.relative_error)} ${basisText(answer, readForm())})`,
    `Disparity d: ${fmt(answer.disparity_px)} px (effective d + doffs: ${fmt(answer.effective_disparity_px)} px)`,
    `Focal length: ${fmt(answer.focal_length_px)} px`,
    `Baseline: ${fmt(answer.baseline)} ${u}`,
    `Normalized x: ${fmt(answer.normalized_x)}`,
    `Projection factor f/B: ${fmt(answer.projection_factor)} px/${u}`,
    answer.point
      ? `3D point (X, Y, Z): (${fmt(answer.point.x)}, ${fmt(answer.point.y)}, ${fmt(answer.point.z)}) ${u}`
      : '3D point: needs cx, cy or the image size',
    answer.range === undefined ? 'Range: needs cx, cy or the image size' : `Range (straight line to the point): ${fmt(answer.range)} ${u}`,
    `Formula: ${answer.formula}`,
    `Warnings: ${answer.warnings.length > 0 ? answer.warnings.map((w) => w.message).join('; ') : 'none'}`,
    ...(page.mode === 'images' ? emit(EVENTS.findingsLines).flat() : []),
    `Permalink: ${location.href}`,
  ];
  return `${lines.join('\n')}\n`;
}


function showTable(data, params) {
  const body = $('table-body');
  $('csv').href = `/table.csv?${new URLSearchParams(params)}`;
  if (data === null) {
    body.replaceChildren();
    $('table-caption').textContent = 'No table until the rig is valid.';
    $('csv').setAttribute('aria-disabled', 'true');
    return;
  }
  $('csv').removeAttribute('aria-disabled');
  body.replaceChildren(
    ...data.rows.map((row) => {
      const tr = document.createElement('tr');
      for (const value of [row.distance, row.disparity_px, row.normalized_x, row.projection_factor, row.depth_error]) {
        const td = document.createElement('td');
        td.textContent = fmt(value);
        tr.append(td);
      }
      return tr;
    }),
  );
  $('table-caption').textContent =
    `${data.rows.length} disparities for f = ${fmt(data.focal_length_px)} px, B = ${fmt(data.baseline)} ${data.unit}, ` +
    `Δd = ${fmt(data.disparity_error_px)} px; normalized x of the right image's x with x_left = ${fmt(data.x_left)} px held.`;
}


export async function copyText(text) {
  if (navigator.clipboard && window.isSecureContext) {
    try {
      await navigator.clipboard.writeText(text);
      return true;
    } catch {
      // Not allowed here (no permission or no focus): fall back to a selection copy.
    }
  }
  const area = document.createElement('textarea');
  area.value = text;
  area.setAttribute('readonly', '');
  area.className = 'offscreen';
  document.body.append(area);
  area.select();
  let copied = false;
  try {
    copied = document.execCommand('copy');
  } catch {
    copied = false;
  }
  area.remove();
  return copied;
}

export async function copyResults() {
  const button = $('copy');
  if (lastResult === null) {
    status.textContent = 'Nothing to copy yet: correct the marked fields first.';
    return;
  }
  const text = summary(lastResult);
  const copied = await copyText(text);
  button.focus();
  status.textContent = copied
    ? 'Copied the results to the clipboard.'
    : 'The browser refused the clipboard; select and copy the results by hand.';
}

export function reset() {
  const state = { ...DEFAULTS };
  // A pair on the page keeps its own size, so that it can still be matched.
  if (pair.bitmaps.left) {
    state.image_width = String(pair.width);
    state.image_height = String(pair.height);
  }
  page.sizeFromCalibration = false;
  // The calculator's example is no one's rig: in Images mode, disparities until one is given.
  page.rigTouched = false;
  // The last click's match was made with the old rig and filled the feature's fields, which
  // the defaults replace: it is forgotten with them.
  emit(EVENTS.forgetFindings);
  page.calibration = null;
  writeForm(state);
  $('optional').open = false;
  compute('Defaults restored.');
  emit(EVENTS.scheduleDepth);
}

on(EVENTS.compute, compute);
on(EVENTS.schedule, schedule);
