// The rig form and the calibration import: the form's fields and the address's query as one
// state, the API's rig members from it, the API's errors next to the fields they name, and a
// calibration file read by /calibration into the fields.

import { postJson, problemsOf } from './api.js';
import { $, fmt, listItem, page } from './util.js';

/** The focal-length forms: the API member the focal field becomes, and its companion. */
export const FOCAL_MODES = {
  px: {
    member: 'focal_length_px',
    label: 'Focal length f (px)',
    help: "The focal length in pixels, fx from the camera's calibration.",
    companion: null,
  },
  'mm-sensor': {
    member: 'focal_length_mm',
    label: 'Focal length f (mm)',
    help: "The lens's focal length in millimetres; add the sensor width to convert it to pixels.",
    companion: 'sensor_width_mm',
  },
  'mm-pitch': {
    member: 'focal_length_mm',
    label: 'Focal length f (mm)',
    help: "The lens's focal length in millimetres; add the pixel pitch to convert it to pixels.",
    companion: 'pixel_size_um',
  },
  fov: {
    member: 'horizontal_fov_deg',
    label: 'Horizontal field of view (°)',
    help: 'The horizontal angle of view, between 0 and 180°: f = (W/2) / tan(HFOV/2).',
    companion: null,
  },
};
const FOCAL_MEMBERS = ['focal_length_px', 'focal_length_mm', 'horizontal_fov_deg'];
const COMPANIONS = ['sensor_width_mm', 'pixel_size_um'];

/** Text inputs named as the API names them (the focal field is `focal`). */
export const TEXT_FIELDS = [
  'focal', 'sensor_width_mm', 'pixel_size_um', 'image_width', 'image_height', 'baseline',
  'x_left', 'x_right', 'y', 'disparity_error_px', 'doffs', 'cx', 'cy', 'min_disparity', 'max_disparity',
  'focal_length_std_px', 'baseline_std', 'max_disparity_std',
];
/** Members every request carries, as they are in the form. */
const RIG_FIELDS = [
  'baseline', 'image_width', 'image_height', 'disparity_error_px', 'doffs', 'cx', 'cy', 'focal_length_std_px', 'baseline_std',
];
export const OPTIONAL_FIELDS = ['y', 'disparity_error_px', 'doffs', 'cx', 'cy', 'focal_length_std_px', 'baseline_std'];

/** Images mode's matcher options, folded away under their summary until one is given, so
 * that the first screen holds the pair and its depth map. */
const MATCHER_FIELDS = ['min_disparity', 'max_disparity', 'max_disparity_std', 'preset', 'projection'];

/** The original calculator's first example, with its focal length read as pixels. */
export const DEFAULTS = Object.freeze({
  focal_mode: 'px',
  focal: '35',
  sensor_width_mm: '',
  pixel_size_um: '',
  baseline: '150',
  unit: 'mm',
  x_left: '400',
  x_right: '350',
  image_width: '800',
  image_height: '600',
  y: '',
  disparity_error_px: '',
  doffs: '',
  cx: '',
  cy: '',
  min_disparity: '',
  max_disparity: '',
  focal_length_std_px: '',
  baseline_std: '',
  max_disparity_std: '',
  rows: '10',
  scale: 'log',
  preset: 'accurate',
  projection: 'pinhole',
});
const UNITS = ['mm', 'cm', 'm', 'in', 'ft'];
const ROWS = ['5', '10', '20', '50'];
/** The permalink members a select (or the log checkbox) holds, with the values it offers.
 * A permalink naming another value is shown as given, with an error next to its control,
 * and nothing is computed in a value nobody chose. */
export const CHOICES = {
  focal_mode: Object.keys(FOCAL_MODES),
  unit: UNITS,
  rows: ROWS,
  scale: ['linear', 'log'],
};
/** The control each choice lives in. */
const CHOICE_INPUTS = { focal_mode: 'focal_mode', unit: 'unit', rows: 'rows', scale: 'log' };
export const CHART_POINTS = 120;


/** A scale from a permalink that is neither linear nor log, until the box is ticked. */
let unknownScale = null;

/** Forgets a permalink's scale that is neither linear nor log (the box was ticked). */
export function forgetUnknownScale() {
  unknownScale = null;
}

export function readForm() {
  const state = {
    focal_mode: $('focal_mode').value, unit: $('unit').value, rows: $('rows').value, preset: $('preset').value,
    projection: $('projection').value,
  };
  for (const name of TEXT_FIELDS) state[name] = $(name).value.trim();
  state.scale = unknownScale ?? ($('log').checked ? 'log' : 'linear');
  return state;
}

/** Selects `value`, adding it as an option marked unknown when the select has no such
 * option, so that the control shows what the permalink said. */
export function choose(select, value) {
  for (const option of select.querySelectorAll('option[data-unknown]')) option.remove();
  if (![...select.options].some((option) => option.value === value)) {
    const option = document.createElement('option');
    option.value = value;
    option.textContent = `${value} (not an option)`;
    option.dataset.unknown = 'true';
    select.append(option);
  }
  select.value = value;
}

/** Removes a select's unknown option once a real one is chosen. */
export function forgetUnknown(select) {
  for (const option of select.querySelectorAll('option[data-unknown]')) {
    if (!option.selected) option.remove();
  }
}

export function writeForm(state) {
  for (const name of ['focal_mode', 'unit', 'rows', 'preset', 'projection']) choose($(name), state[name]);
  unknownScale = CHOICES.scale.includes(state.scale) ? null : state.scale;
  $('log').checked = state.scale === 'log';
  for (const name of TEXT_FIELDS) $(name).value = state[name];
  showFocalMode(state.focal_mode in FOCAL_MODES ? state.focal_mode : state.focal_shown);
  showUnit(UNITS.includes(state.unit) ? state.unit : '?');
  // Optional values given in a permalink should be visible.
  if (OPTIONAL_FIELDS.some((name) => state[name] !== '')) $('optional').open = true;
  if (MATCHER_FIELDS.some((name) => state[name] !== DEFAULTS[name])) $('matcher-options').open = true;
}

/** The state a query string describes; the defaults when it describes none. */
export function stateFromQuery(search) {
  const query = new URLSearchParams(search);
  const known = ['focal_mode', ...FOCAL_MEMBERS, ...COMPANIONS, ...TEXT_FIELDS, 'unit', 'rows', 'scale', 'preset', 'projection'];
  if (![...query.keys()].some((key) => known.includes(key))) return { ...DEFAULTS };
  const state = { ...DEFAULTS };
  for (const name of TEXT_FIELDS) state[name] = '';
  for (const name of TEXT_FIELDS) if (query.has(name) && name !== 'focal') state[name] = query.get(name);
  // Without focal_mode (an API query pasted as it is), the member given tells the mode.
  let mode = query.get('focal_mode');
  let shown = mode;
  if (!(mode in FOCAL_MODES)) {
    if (query.has('horizontal_fov_deg')) shown = 'fov';
    else if (query.has('pixel_size_um')) shown = 'mm-pitch';
    else if (query.has('focal_length_mm')) shown = 'mm-sensor';
    else shown = 'px';
    if (mode === null) mode = shown;
  }
  state.focal_mode = mode;
  state.focal_shown = shown;
  state.focal = query.get(FOCAL_MODES[shown].member) ?? '';
  // Each choice is taken as given, even one the page does not offer: it is refused, with
  // its error, rather than replaced by a default nobody chose.
  for (const name of ['unit', 'rows', 'scale', 'preset', 'projection']) if (query.has(name)) state[name] = query.get(name);
  return state;
}

/** The permalink members the page itself refuses (focal_mode, rows, scale: the API never
 * sees them), worded as the API words its own refusals. The unit goes to the API as given,
 * and its refusal comes back from there. */
export function choiceErrors(state) {
  const errors = [];
  for (const name of ['focal_mode', 'rows', 'scale']) {
    const allowed = CHOICES[name];
    if (allowed.includes(state[name])) continue;
    const list = allowed.length === 2 ? allowed.join(' or ') : `one of ${allowed.join(', ')}`;
    errors.push({ field: name, message: `must be ${list}, got \`${state[name]}\`` });
  }
  return errors;
}

/** The API's rig members for a state: only what the person filled in. */
export function rigParams(state) {
  const mode = FOCAL_MODES[state.focal_mode];
  const params = new URLSearchParams();
  if (state.focal !== '') params.set(mode.member, state.focal);
  if (mode.companion && state[mode.companion] !== '') params.set(mode.companion, state[mode.companion]);
  params.set('unit', state.unit);
  for (const name of RIG_FIELDS) if (state[name] !== '') params.set(name, state[name]);
  return params;
}

export function withMembers(params, state, names) {
  const out = new URLSearchParams(params);
  for (const name of names) if (state[name] !== '') out.set(name, state[name]);
  return out;
}


export function showFocalMode(mode) {
  const spec = FOCAL_MODES[mode];
  $('focal-label').textContent = spec.label;
  $('focal-help').textContent = spec.help;
  for (const companion of COMPANIONS) $(`${companion}-field`).hidden = spec.companion !== companion;
}

export function showUnit(unit) {
  for (const label of document.querySelectorAll('.unit-label')) label.textContent = `(${unit})`;
  for (const label of document.querySelectorAll('.pf-unit')) label.textContent = `(px/${unit})`;
}


/** The input a member of the API refers to, or null if the page has none for it. */
function inputFor(member, state) {
  // The image endpoints name the rig's members inside their `rig` part.
  if (member.startsWith('rig.')) return inputFor(member.slice(4), state);
  if (FOCAL_MEMBERS.includes(member)) return 'focal';
  if (COMPANIONS.includes(member)) return FOCAL_MODES[state.focal_mode].companion === member ? member : null;
  if (member === 'steps') return 'rows';
  if (member in CHOICE_INPUTS) return CHOICE_INPUTS[member];
  if (TEXT_FIELDS.includes(member) || member === 'unit') return member;
  return null;
}

export function clearErrors() {
  for (const name of [...TEXT_FIELDS, ...Object.values(CHOICE_INPUTS)]) {
    $(name).removeAttribute('aria-invalid');
    const slot = $(`${name}-error`);
    if (slot) {
      slot.hidden = true;
      slot.textContent = '';
    }
  }
  $('form-errors').hidden = true;
  $('form-errors-list').replaceChildren();
}

/** Shows `errors` ([{field, message}]) and returns how many fields they name. */
export function showErrors(errors, state) {
  const byInput = new Map();
  const general = [];
  for (const { field, message } of errors) {
    const input = inputFor(field, state);
    const slot = input && $(`${input}-error`);
    if (slot) {
      const messages = byInput.get(input) ?? [];
      if (!messages.includes(message)) messages.push(message);
      byInput.set(input, messages);
    } else if (!general.some((g) => g.field === field && g.message === message)) {
      general.push({ field, message });
    }
  }
  for (const [input, messages] of byInput) {
    $(input).setAttribute('aria-invalid', 'true');
    const slot = $(`${input}-error`);
    slot.textContent = messages.join(' ');
    slot.hidden = false;
    if (OPTIONAL_FIELDS.includes(input)) $('optional').open = true;
    if (MATCHER_FIELDS.includes(input)) $('matcher-options').open = true;
  }
  if (general.length > 0) {
    $('form-errors-list').replaceChildren(
      ...general.map(({ field, message }) => {
        const item = document.createElement('li');
        item.textContent = `${field}: ${message}`;
        return item;
      }),
    );
    $('form-errors').hidden = false;
  }
  return byInput.size + general.length;
}

const FORMAT_NAMES = { middlebury: 'Middlebury', kitti: 'KITTI', ros: 'ROS', opencv: 'OpenCV' };

/** Fills the rig's fields from a rig in the API's members (what /calibration answers, or the
 * sample's), f in pixels; doffs and the principal point the rig lacks are emptied (their
 * defaults), the image size and the search range are kept unless it gives them. */
export function applyRig(rig, maxDisparity) {
  page.rigTouched = true;
  const text = (value) => (value === undefined ? '' : String(value));
  const state = readForm();
  Object.assign(state, {
    focal_mode: 'px',
    focal_shown: 'px',
    focal: text(rig.focal_length_px),
    baseline: text(rig.baseline),
    unit: rig.unit,
    doffs: text(rig.doffs),
    cx: text(rig.cx),
    cy: text(rig.cy),
    focal_length_std_px: text(rig.focal_length_std_px),
    baseline_std: text(rig.baseline_std),
  });
  if (rig.image_width !== undefined) state.image_width = text(rig.image_width);
  if (rig.image_height !== undefined) state.image_height = text(rig.image_height);
  if (maxDisparity !== undefined) state.max_disparity = text(maxDisparity);
  writeForm(state);
}

/** Reads the import box's file through /calibration into the fields, then calls
 * `onImported(note)`. A calibration of raw cameras is kept, so that Images mode can send it
 * with a raw pair for the service to rectify. */
export async function importCalibration(onImported) {
  const errors = $('import-errors');
  errors.hidden = true;
  errors.replaceChildren();
  const text = $('calibration_text').value;
  if (text.trim() === '') {
    errors.replaceChildren(listItem('text: choose or paste a calibration file first.'));
    errors.hidden = false;
    $('import-status').textContent = 'Nothing imported.';
    return;
  }
  const request = { text };
  if ($('calibration_right_text').value.trim() !== '') request.right_text = $('calibration_right_text').value;
  if ($('calibration_unit').value !== '') request.calibration_unit = $('calibration_unit').value;
  $('import-status').textContent = 'Reading the calibration…';
  document.body.dataset.import = 'reading';
  try {
    const { ok, status, body } = await postJson('/calibration', request);
    if (!ok) {
      errors.replaceChildren(...problemsOf({ status, body })
        .map(({ field, message }) => listItem(`${field}: ${message}`)));
      errors.hidden = false;
      $('import-status').textContent = 'Not imported: the service could not read the file.';
      return;
    }
    const rig = body.rig;
    applyRig(rig, body.max_disparity_px);
    page.sizeFromCalibration = rig.image_width !== undefined;
    const format = FORMAT_NAMES[body.format] ?? body.format;
    const warnings = body.warnings.length > 0 ? ` Warnings: ${body.warnings.join(' ')}` : ' No warnings.';
    $('import-status').textContent =
      `Read as ${format === 'OpenCV' ? 'an' : 'a'} ${format} calibration: f = ${fmt(rig.focal_length_px)} px, B = ${fmt(rig.baseline)} ${rig.unit}.${warnings}`;
    $('import-status').dataset.format = body.format;
    page.calibration = body.raw_cameras ? { request } : null;
    onImported(`Imported a ${format} calibration.`);
  } catch (error) {
    errors.replaceChildren(listItem(`service: could not be reached (${error.message}).`));
    errors.hidden = false;
  } finally {
    document.body.dataset.import = 'done';
  }
}

/** Whether the person gave a rig (imported, the sample's, typed, or in the address), not
 * the Numbers mode's example, which would label a real scene's depths with a made-up rig. */
export const RIG_INPUTS = [
  'focal_mode', 'focal', 'sensor_width_mm', 'pixel_size_um', 'baseline', 'unit', 'doffs', 'cx', 'cy', 'focal_length_std_px',
  'baseline_std',
];

export function rigGiven(state = readForm()) {
  return page.rigTouched || ['focal_mode', 'focal', 'baseline', 'unit'].some((name) => state[name] !== DEFAULTS[name]);
}

/** The rig part of an image request: the form's rig members, numbers as numbers. */
export function rigPart(state) {
  const rig = {};
  for (const [key, value] of rigParams(state)) {
    const number = Number(value);
    rig[key] = key !== 'unit' && value.trim() !== '' && Number.isFinite(number) ? number : value;
  }
  return JSON.stringify(rig);
}

