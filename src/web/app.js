// The calculator page: a client of the service's public API (/distance, /table, /chart-data).
// It holds no physics: it sends what the person typed, shows the answers, draws the chart from
// /chart-data and puts the API's problem+json errors next to the fields they name. The page's
// state lives in its query string, so the address is a permalink.
'use strict';

(() => {
  const $ = (id) => document.getElementById(id);

  /** The focal-length forms: the API member the focal field becomes, and its companion. */
  const FOCAL_MODES = {
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
  const TEXT_FIELDS = [
    'focal', 'sensor_width_mm', 'pixel_size_um', 'image_width', 'image_height', 'baseline',
    'x_left', 'x_right', 'y', 'disparity_error_px', 'doffs', 'cx', 'cy',
  ];
  /** Members every request carries, as they are in the form. */
  const RIG_FIELDS = ['baseline', 'image_width', 'image_height', 'disparity_error_px', 'doffs', 'cx', 'cy'];
  const OPTIONAL_FIELDS = ['y', 'disparity_error_px', 'doffs', 'cx', 'cy'];

  /** The original calculator's first example, with its focal length read as pixels. */
  const DEFAULTS = Object.freeze({
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
    rows: '10',
    scale: 'log',
  });
  const UNITS = ['mm', 'cm', 'm', 'in', 'ft'];
  const ROWS = ['5', '10', '20', '50'];
  /** The permalink members a select (or the log checkbox) holds, with the values it offers.
   * A permalink naming another value is shown as given, with an error next to its control,
   * and nothing is computed in a value nobody chose. */
  const CHOICES = {
    focal_mode: Object.keys(FOCAL_MODES),
    unit: UNITS,
    rows: ROWS,
    scale: ['linear', 'log'],
  };
  /** The control each choice lives in. */
  const CHOICE_INPUTS = { focal_mode: 'focal_mode', unit: 'unit', rows: 'rows', scale: 'log' };
  const CHART_POINTS = 120;
  const DEBOUNCE_MS = 300;

  const form = $('calculator');
  const results = $('results');
  const status = $('status');

  // ---------------------------------------------------------------------------------------
  // State: the form, the query string and the API's parameters.

  /** A scale from a permalink that is neither linear nor log, until the box is ticked. */
  let unknownScale = null;

  function readForm() {
    const state = { focal_mode: $('focal_mode').value, unit: $('unit').value, rows: $('rows').value };
    for (const name of TEXT_FIELDS) state[name] = $(name).value.trim();
    state.scale = unknownScale ?? ($('log').checked ? 'log' : 'linear');
    return state;
  }

  /** Selects `value`, adding it as an option marked unknown when the select has no such
   * option, so that the control shows what the permalink said. */
  function choose(select, value) {
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
  function forgetUnknown(select) {
    for (const option of select.querySelectorAll('option[data-unknown]')) {
      if (!option.selected) option.remove();
    }
  }

  function writeForm(state) {
    for (const name of ['focal_mode', 'unit', 'rows']) choose($(name), state[name]);
    unknownScale = CHOICES.scale.includes(state.scale) ? null : state.scale;
    $('log').checked = state.scale === 'log';
    for (const name of TEXT_FIELDS) $(name).value = state[name];
    showFocalMode(state.focal_mode in FOCAL_MODES ? state.focal_mode : state.focal_shown);
    showUnit(UNITS.includes(state.unit) ? state.unit : '?');
    // Optional values given in a permalink should be visible.
    if (OPTIONAL_FIELDS.some((name) => state[name] !== '')) $('optional').open = true;
  }

  /** The state a query string describes; the defaults when it describes none. */
  function stateFromQuery(search) {
    const query = new URLSearchParams(search);
    const known = ['focal_mode', ...FOCAL_MEMBERS, ...COMPANIONS, ...TEXT_FIELDS, 'unit', 'rows', 'scale'];
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
    for (const name of ['unit', 'rows', 'scale']) if (query.has(name)) state[name] = query.get(name);
    return state;
  }

  /** The permalink members the page itself refuses (focal_mode, rows, scale: the API never
   * sees them), worded as the API words its own refusals. The unit goes to the API as given,
   * and its refusal comes back from there. */
  function choiceErrors(state) {
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
  function rigParams(state) {
    const mode = FOCAL_MODES[state.focal_mode];
    const params = new URLSearchParams();
    if (state.focal !== '') params.set(mode.member, state.focal);
    if (mode.companion && state[mode.companion] !== '') params.set(mode.companion, state[mode.companion]);
    params.set('unit', state.unit);
    for (const name of RIG_FIELDS) if (state[name] !== '') params.set(name, state[name]);
    return params;
  }

  function withMembers(params, state, names) {
    const out = new URLSearchParams(params);
    for (const name of names) if (state[name] !== '') out.set(name, state[name]);
    return out;
  }

  /** The page's own address for a state: the API's members plus the view settings. */
  function permalink(state) {
    const params = new URLSearchParams({ focal_mode: state.focal_mode });
    for (const [key, value] of withMembers(rigParams(state), state, ['x_left', 'x_right', 'y'])) {
      params.set(key, value);
    }
    params.set('rows', state.rows);
    params.set('scale', state.scale);
    return `${location.pathname}?${params}`;
  }

  // ---------------------------------------------------------------------------------------
  // Showing the focal mode and the unit.

  function showFocalMode(mode) {
    const spec = FOCAL_MODES[mode];
    $('focal-label').textContent = spec.label;
    $('focal-help').textContent = spec.help;
    for (const companion of COMPANIONS) $(`${companion}-field`).hidden = spec.companion !== companion;
  }

  function showUnit(unit) {
    for (const label of document.querySelectorAll('.unit-label')) label.textContent = `(${unit})`;
    for (const label of document.querySelectorAll('.pf-unit')) label.textContent = `(px/${unit})`;
  }

  // ---------------------------------------------------------------------------------------
  // Formatting numbers for people (the API's numbers are exact; this only shortens them).

  function fmt(value, digits = 6) {
    if (typeof value !== 'number' || !Number.isFinite(value)) return String(value);
    if (value === 0) return '0';
    const magnitude = Math.abs(value);
    if (magnitude >= 1e-4 && magnitude < 1e9) return String(Number(value.toPrecision(digits)));
    return value.toExponential(digits - 1).replace(/\.?0+e/, 'e');
  }

  function percent(fraction) {
    return `${fmt(fraction * 100, 3)} %`;
  }

  // ---------------------------------------------------------------------------------------
  // Errors: each next to the field it names; the rest in a list under the form.

  /** The input a member of the API refers to, or null if the page has none for it. */
  function inputFor(member, state) {
    if (FOCAL_MEMBERS.includes(member)) return 'focal';
    if (COMPANIONS.includes(member)) return FOCAL_MODES[state.focal_mode].companion === member ? member : null;
    if (member === 'steps') return 'rows';
    if (member in CHOICE_INPUTS) return CHOICE_INPUTS[member];
    if (TEXT_FIELDS.includes(member) || member === 'unit') return member;
    return null;
  }

  function clearErrors() {
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
  function showErrors(errors, state) {
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

  /** A problem's field errors, or one general error for an answer without them. */
  function problemsOf(answer) {
    const errors = answer.body && Array.isArray(answer.body.errors) ? answer.body.errors : [];
    if (errors.length > 0) return errors;
    const detail = (answer.body && (answer.body.detail || answer.body.title)) || `HTTP ${answer.status}`;
    return [{ field: 'request', message: detail }];
  }

  // ---------------------------------------------------------------------------------------
  // Calling the API.

  async function call(path, params, signal) {
    const response = await fetch(`${path}?${params}`, { headers: { accept: 'application/json' }, signal });
    const type = response.headers.get('content-type') || '';
    const body = type.includes('json') ? await response.json() : null;
    return { ok: response.ok, status: response.status, body };
  }

  let generation = 0;
  let inFlight = null;
  let debounce = null;
  let lastResult = null;

  /** Sends the form to the API and shows what comes back (after `note`, if given, in the
   * status line); older answers are dropped. */
  async function compute(note = '') {
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
      const distance = await call('/distance', withMembers(rig, state, ['x_left', 'x_right', 'y']), signal);
      // The chart marks, and the table follows, the measured feature only when it is valid.
      const measured = distance.ok ? ['x_left', 'x_right'] : [];
      const chartParams = withMembers(rig, state, measured);
      chartParams.set('points', String(CHART_POINTS));
      const tableParams = withMembers(rig, state, measured.slice(0, 1));
      tableParams.set('steps', state.rows);
      const [chart, table] = await Promise.all([
        call('/chart-data', chartParams, signal),
        call('/table', tableParams, signal),
      ]);
      if (token !== generation) return;
      clearErrors();
      const errors = [distance, chart, table].filter((a) => !a.ok).flatMap(problemsOf);
      const fields = showErrors(errors, state);
      showDistance(distance.ok ? distance.body : null, state);
      showChart(chart.ok ? chart.body : null, state.scale === 'log');
      showTable(table.ok ? table.body : null, tableParams);
      const chartSvg = new URLSearchParams(chartParams);
      chartSvg.delete('points');
      $('chart-svg-link').href = `/chart.svg?${chartSvg}`;
      status.textContent = (note ? `${note} ` : '') + (distance.ok
        ? `Distance ${fmt(distance.body.distance)} ${distance.body.unit} ± ${fmt(distance.body.depth_error)} ${distance.body.unit}.`
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

  function schedule() {
    clearTimeout(debounce);
    document.body.dataset.state = 'pending';
    debounce = setTimeout(() => compute(), DEBOUNCE_MS);
  }

  // ---------------------------------------------------------------------------------------
  // Results.

  function showDistance(answer, state) {
    lastResult = answer;
    results.classList.toggle('invalid', answer === null);
    const mini = $('mini-result');
    mini.classList.toggle('invalid', answer === null);
    mini.textContent = answer === null
      ? 'No distance: see the marked fields.'
      : `Z = ${fmt(answer.distance)} ${answer.unit} ± ${fmt(answer.depth_error)} ${answer.unit}`;
    if (answer === null) {
      $('distance').textContent = '–';
      $('depth-error').textContent = '';
      $('distance-detail').textContent = 'Correct the marked fields to see a distance.';
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
    $('distance-detail').textContent =
      `${fmt(answer.distance_m)} m · relative error ${percent(answer.relative_error)} for Δd = ${fmt(answer.disparity_error_px)} px`;
    $('disparity_px').textContent = `${fmt(answer.disparity_px)} px`;
    $('effective_disparity_px').textContent = `${fmt(answer.effective_disparity_px)} px`;
    $('focal_length_px').textContent = state.focal_mode === 'px'
      ? `${fmt(answer.focal_length_px)} px`
      : `${fmt(answer.focal_length_px)} px (converted)`;
    $('normalized_x').textContent = fmt(answer.normalized_x);
    $('projection_factor').textContent = `${fmt(answer.projection_factor)} px/${unit}`;
    const p = answer.point;
    $('point').textContent = `(${fmt(p.x)}, ${fmt(p.y)}, ${fmt(p.z)}) ${unit}`;
    $('range').textContent = `${fmt(answer.range)} ${unit}`;
    const warnings = answer.warnings.map((w) => {
      const item = listItem(w.message);
      item.className = 'warning';
      item.dataset.code = w.code;
      return item;
    });
    $('warnings').replaceChildren(...(warnings.length > 0 ? warnings : [listItem('None.')]));
    $('formula').textContent = answer.formula;
  }

  function listItem(text) {
    const item = document.createElement('li');
    item.textContent = text;
    return item;
  }

  /** The plain-text summary "Copy results" puts on the clipboard. */
  function summary(answer) {
    const u = answer.unit;
    const lines = [
      `Stereo distance: ${fmt(answer.distance)} ${u} ± ${fmt(answer.depth_error)} ${u} (${fmt(answer.distance_m)} m; relative error ${percent(answer.relative_error)}, Δd = ${fmt(answer.disparity_error_px)} px)`,
      `Disparity d: ${fmt(answer.disparity_px)} px (effective d + doffs: ${fmt(answer.effective_disparity_px)} px)`,
      `Focal length: ${fmt(answer.focal_length_px)} px`,
      `Baseline: ${fmt(answer.baseline)} ${u}`,
      `Normalized x: ${fmt(answer.normalized_x)}`,
      `Projection factor f/B: ${fmt(answer.projection_factor)} px/${u}`,
      `3D point (X, Y, Z): (${fmt(answer.point.x)}, ${fmt(answer.point.y)}, ${fmt(answer.point.z)}) ${u}`,
      `Range (straight line to the point): ${fmt(answer.range)} ${u}`,
      `Formula: ${answer.formula}`,
      `Warnings: ${answer.warnings.length > 0 ? answer.warnings.map((w) => w.message).join('; ') : 'none'}`,
      `Permalink: ${location.href}`,
    ];
    return `${lines.join('\n')}\n`;
  }

  // ---------------------------------------------------------------------------------------
  // The chart, drawn in SVG from /chart-data.

  const SVG_NS = 'http://www.w3.org/2000/svg';
  const WIDTH = 520;
  const HEIGHT = 380;

  function svg(name, attributes = {}, text = null) {
    const node = document.createElementNS(SVG_NS, name);
    for (const [key, value] of Object.entries(attributes)) node.setAttribute(key, String(value));
    if (text !== null) node.textContent = text;
    return node;
  }

  /** A step of 1, 2 or 5 × 10ⁿ giving about `target` intervals across `span`. */
  function niceStep(span, target) {
    const raw = span / target;
    const magnitude = 10 ** Math.floor(Math.log10(raw));
    const ratio = raw / magnitude;
    const step = (ratio <= 1 ? 1 : ratio <= 2 ? 2 : ratio <= 5 ? 5 : 10) * magnitude;
    return Number.isFinite(step) && step > 0 ? step : 1;
  }

  /** A map from [min, max] onto the pixels [from, to], linear or logarithmic. */
  function scaleOf(min, max, from, to, log = false) {
    const f = log ? Math.log10 : (v) => v;
    const [a, b] = [f(min), f(max)];
    const at = (v) => from + ((to - from) * (f(v) - a)) / (b - a || 1);
    at.min = min;
    at.max = max;
    at.log = log;
    return at;
  }

  function linearTicks(min, max, target = 6) {
    const step = niceStep(max - min, target);
    const ticks = [];
    for (let v = Math.ceil(min / step) * step; v <= max + step * 1e-9 && ticks.length < 15; v += step) {
      ticks.push(Number(v.toPrecision(12)));
    }
    return ticks;
  }

  function logTicks(min, max) {
    const first = Math.ceil(Math.log10(min) - 1e-9);
    const last = Math.floor(Math.log10(max) + 1e-9);
    const every = Math.max(1, Math.ceil((last - first + 1) / 8));
    const ticks = [];
    for (let e = first; e <= last; e += every) ticks.push(10 ** e);
    return ticks;
  }

  /** [min, max] of a nice y range: from 0 to a tick for a linear axis, whole decades for a log one. */
  function yRange(values, log) {
    const finite = values.filter((v) => Number.isFinite(v) && (!log || v > 0));
    if (finite.length === 0) return log ? [1, 10] : [0, 1];
    const max = Math.max(...finite);
    if (log) {
      const min = Math.min(...finite);
      const low = 10 ** Math.floor(Math.log10(min));
      const high = 10 ** Math.ceil(Math.log10(max));
      return [low, high > low ? high : low * 10];
    }
    const step = niceStep(max, 5);
    return [0, Math.ceil(max / step) * step || 1];
  }

  function polyline(points, x, y, cls) {
    const coordinates = points
      .filter((p) => Number.isFinite(p.y) && (!y.log || p.y > 0))
      .map((p) => `${x(p.x).toFixed(1)},${y(p.y).toFixed(1)}`);
    return svg('polyline', { class: `line ${cls}`, points: coordinates.join(' '), 'data-count': coordinates.length });
  }

  function showChart(data, log) {
    const chart = $('chart');
    const title = $('chart-title');
    const desc = $('chart-desc');
    chart.replaceChildren(title, desc);
    if (data === null) {
      desc.textContent = 'No chart: the rig is not valid yet.';
      chart.append(svg('text', { class: 'empty', x: WIDTH / 2, y: HEIGHT / 2, 'text-anchor': 'middle' }, 'No chart until the rig is valid'));
      $('chart-caption').textContent = 'Correct the marked fields to draw the chart.';
      return;
    }
    const series = (name) => data.series.find((s) => s.name === name) ?? { points: [], label: name };
    const distance = series('distance');
    const error = series('depth_error');
    const unit = data.y_axis.unit;
    const margin = { left: 62, right: log ? 20 : 62, top: 52, bottom: 52 };
    const xs = distance.points.map((p) => p.x).concat(data.marker ? [data.marker.x] : []);
    const x = scaleOf(Math.min(...xs), Math.max(...xs), margin.left, WIDTH - margin.right);
    const plotBottom = HEIGHT - margin.bottom;
    let left;
    let right = null;
    if (log) {
      const [low, high] = yRange(distance.points.concat(error.points).map((p) => p.y), true);
      left = scaleOf(low, high, plotBottom, margin.top, true);
    } else {
      const [low, high] = yRange(distance.points.map((p) => p.y), false);
      left = scaleOf(low, high, plotBottom, margin.top);
      const [elow, ehigh] = yRange(error.points.map((p) => p.y), false);
      right = scaleOf(elow, ehigh, plotBottom, margin.top);
    }

    const grid = svg('g', { class: 'grid-lines' });
    const labels = svg('g', { class: 'tick-labels' });
    for (const t of linearTicks(x.min, x.max, 7)) {
      grid.append(svg('line', { class: 'grid', x1: x(t), x2: x(t), y1: margin.top, y2: plotBottom }));
      labels.append(svg('text', { x: x(t), y: plotBottom + 18, 'text-anchor': 'middle' }, fmt(t, 4)));
    }
    for (const t of log ? logTicks(left.min, left.max) : linearTicks(left.min, left.max, 5)) {
      grid.append(svg('line', { class: 'grid', x1: margin.left, x2: WIDTH - margin.right, y1: left(t), y2: left(t) }));
      labels.append(svg('text', { x: margin.left - 8, y: left(t) + 4, 'text-anchor': 'end' }, fmt(t, 4)));
    }
    if (right) {
      for (const t of linearTicks(right.min, right.max, 5)) {
        labels.append(svg('text', { x: WIDTH - margin.right + 8, y: right(t) + 4, 'text-anchor': 'start' }, fmt(t, 4)));
      }
    }
    chart.append(grid);
    chart.append(svg('line', { class: 'axis', x1: margin.left, x2: WIDTH - margin.right, y1: plotBottom, y2: plotBottom }));
    chart.append(svg('line', { class: 'axis', x1: margin.left, x2: margin.left, y1: margin.top, y2: plotBottom }));
    if (right) {
      chart.append(svg('line', { class: 'axis', x1: WIDTH - margin.right, x2: WIDTH - margin.right, y1: margin.top, y2: plotBottom }));
    }
    chart.append(labels);

    // Axis titles, in units.
    chart.append(svg('text', { class: 'axis-title', x: (margin.left + WIDTH - margin.right) / 2, y: HEIGHT - 14, 'text-anchor': 'middle' }, data.x_axis.label));
    const leftTitle = log ? `Length (${unit}), logarithmic` : distance.label;
    const midY = (margin.top + plotBottom) / 2;
    chart.append(svg('text', { class: 'axis-title', x: 16, y: midY, 'text-anchor': 'middle', transform: `rotate(-90 16 ${midY})` }, leftTitle));
    if (right) {
      const rx = WIDTH - 14;
      chart.append(svg('text', { class: 'axis-title', x: rx, y: midY, 'text-anchor': 'middle', transform: `rotate(90 ${rx} ${midY})` }, `Depth error ΔZ (${unit})`));
    }

    chart.append(polyline(distance.points, x, left, 'distance'));
    chart.append(polyline(error.points, x, right ?? left, 'depth-error'));

    // Legend.
    const legend = svg('g', { class: 'legend' });
    [[distance.label, 'distance'], [error.label, 'depth-error']].forEach(([text, cls], i) => {
      const ly = 14 + i * 18;
      legend.append(svg('line', { class: `swatch ${cls}`, x1: margin.left, x2: margin.left + 24, y1: ly, y2: ly }));
      legend.append(svg('text', { x: margin.left + 30, y: ly + 4 }, text));
    });
    chart.append(legend);

    let at = '';
    if (data.marker) {
      const m = data.marker;
      at = `d = ${fmt(m.x)} px, Z = ${fmt(m.y)} ${unit}`;
      const cx = x(m.x);
      const cy = left(m.y);
      const dot = svg('circle', { id: 'chart-marker', class: 'marker', cx, cy, r: 6 });
      dot.append(svg('title', {}, `The measured point: ${at}`));
      chart.append(dot);
      const anchor = cx > WIDTH - 160 ? 'end' : 'start';
      chart.append(svg('text', { class: 'marker-label', x: cx + (anchor === 'start' ? 10 : -10), y: cy - 10, 'text-anchor': anchor }, `d = ${fmt(m.x, 4)} px, Z = ${fmt(m.y, 4)} ${unit}`));
    }
    desc.textContent = `${distance.label} and ${error.label} for disparities from ${fmt(x.min)} px to ${fmt(x.max)} px` +
      `${log ? ', on a logarithmic length axis' : ', depth error on the right axis'}${at ? `; the measured point is at ${at}` : ''}.`;
    $('chart-caption').textContent =
      `Distance (solid) and its error (dashed) against disparity.${at ? ` The dot marks the measured point, ${at}.` : ''}`;
  }

  // ---------------------------------------------------------------------------------------
  // The sample table, from /table (and its CSV from /table.csv).

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

  // ---------------------------------------------------------------------------------------
  // Buttons.

  async function copyText(text) {
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

  async function copyResults() {
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

  function reset() {
    writeForm(DEFAULTS);
    $('optional').open = false;
    compute('Defaults restored.');
  }

  // ---------------------------------------------------------------------------------------
  // Wiring.

  form.addEventListener('input', (event) => {
    if (event.target.matches('input[type="text"]')) schedule();
  });
  form.addEventListener('change', (event) => {
    if (event.target.tagName === 'SELECT') forgetUnknown(event.target);
    if (event.target.id === 'focal_mode' && event.target.value in FOCAL_MODES) showFocalMode(event.target.value);
    if (event.target.id === 'unit') showUnit(event.target.value);
    if (event.target.tagName === 'SELECT') compute();
  });
  form.addEventListener('submit', (event) => {
    event.preventDefault();
    compute();
  });
  $('rows').addEventListener('change', (event) => {
    forgetUnknown(event.target);
    compute();
  });
  $('log').addEventListener('change', () => {
    unknownScale = null;
    compute();
  });
  $('reset').addEventListener('click', reset);
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
    writeForm(stateFromQuery(location.search));
    compute();
  });

  writeForm(stateFromQuery(location.search));
  compute();
})();
