// The calculator page: a client of the service's public API (/distance, /table, /chart-data,
// /calibration, /depth-map, /match). It holds no physics and no stereo: it sends what the
// person typed, chose or clicked, shows the answers, draws the chart from /chart-data and the
// depth map from /depth-map's arrays, and puts the API's problem+json errors next to the fields
// they name. The page's state lives in its query string, so the address is a permalink.
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
    'x_left', 'x_right', 'y', 'disparity_error_px', 'doffs', 'cx', 'cy', 'min_disparity', 'max_disparity',
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
    min_disparity: '',
    max_disparity: '',
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
    const params = new URLSearchParams();
    if (mode === 'images') params.set('mode', 'images');
    if (mode === 'images' && pair.sample) params.set('sample', '1');
    params.set('focal_mode', state.focal_mode);
    const feature = mode === 'images' ? ['min_disparity', 'max_disparity'] : ['x_left', 'x_right', 'y'];
    for (const [key, value] of withMembers(rigParams(state), state, feature)) {
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
    // The image endpoints name the rig's members inside their `rig` part.
    if (member.startsWith('rig.')) return inputFor(member.slice(4), state);
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
      // In Images mode the feature is the last click's match; until there is one, only the
      // rig's chart and table are asked for.
      showRigNeeded();
      const noRig = mode === 'images' && !rigGiven(state);
      const measuring = mode === 'numbers' || (matched() && !noRig);
      const distance = measuring
        ? await call('/distance', withMembers(rig, state, ['x_left', 'x_right', 'y']), signal)
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
      const sized = mode === 'numbers' || (!noRig && state.image_width !== '' && state.image_height !== '');
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

  function schedule() {
    clearTimeout(debounce);
    document.body.dataset.state = 'pending';
    debounce = setTimeout(() => compute(), DEBOUNCE_MS);
  }

  // ---------------------------------------------------------------------------------------
  // Results.

  /** Shows a distance answer; without one, `prompt` (when nothing was asked, so nothing is
   * wrong) or the marked-fields warning. */
  function showDistance(answer, state, prompt = null) {
    lastResult = answer;
    // Images mode: the clicked point's distance card, in short, beside its match.
    const short = $('match-distance');
    short.hidden = !(mode === 'images' && answer !== null && pair.match !== null);
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
    $('distance-detail').textContent =
      `${fmt(answer.distance_m)} m · relative error ${percent(answer.relative_error)} for Δd = ${fmt(answer.disparity_error_px)} px`;
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
      answer.point
        ? `3D point (X, Y, Z): (${fmt(answer.point.x)}, ${fmt(answer.point.y)}, ${fmt(answer.point.z)}) ${u}`
        : '3D point: needs cx, cy or the image size',
      answer.range === undefined ? 'Range: needs cx, cy or the image size' : `Range (straight line to the point): ${fmt(answer.range)} ${u}`,
      `Formula: ${answer.formula}`,
      `Warnings: ${answer.warnings.length > 0 ? answer.warnings.map((w) => w.message).join('; ') : 'none'}`,
      ...(mode === 'images' ? findings() : []),
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
    const state = { ...DEFAULTS };
    // A pair on the page keeps its own size, so that it can still be matched.
    if (pair.bitmaps.left) {
      state.image_width = String(pair.width);
      state.image_height = String(pair.height);
    }
    sizeFromCalibration = false;
    // The calculator's example is no one's rig: in Images mode, disparities until one is given.
    rigTouched = false;
    // The last click's match was made with the old rig and filled the feature's fields, which
    // the defaults replace: it is forgotten with them.
    pair.match = null;
    pair.region = null;
    pair.anchor = null;
    showMatch(null);
    showRegion(null);
    drawMarkers();
    writeForm(state);
    $('optional').open = false;
    compute('Defaults restored.');
    scheduleDepth();
  }

  // ---------------------------------------------------------------------------------------
  // Modes: Numbers (the calculator) and Images (a pair, its depth map, clicks and boxes).

  let mode = 'numbers';

  function modeFromQuery(search) {
    return new URLSearchParams(search).get('mode') === 'images' ? 'images' : 'numbers';
  }

  function setMode(next) {
    mode = next;
    document.body.dataset.mode = next;
    $('images').hidden = next !== 'images';
    for (const name of ['numbers', 'images']) {
      const link = $(`mode-${name}`);
      if (name === next) link.setAttribute('aria-current', 'page');
      else link.removeAttribute('aria-current');
    }
  }

  // ---------------------------------------------------------------------------------------
  // Importing a calibration file through /calibration.

  /** Whether the image size in the fields came from an imported calibration (then a pair of
   * another size is the API's error to show, not something to paper over). */
  let sizeFromCalibration = false;

  const FORMAT_NAMES = { middlebury: 'Middlebury', kitti: 'KITTI', ros: 'ROS', opencv: 'OpenCV' };

  /** Fills the rig's fields from a rig in the API's members (what /calibration answers, or the
   * sample's), f in pixels; doffs and the principal point the rig lacks are emptied (their
   * defaults), the image size and the search range are kept unless it gives them. */
  function applyRig(rig, maxDisparity) {
    rigTouched = true;
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
    });
    if (rig.image_width !== undefined) state.image_width = text(rig.image_width);
    if (rig.image_height !== undefined) state.image_height = text(rig.image_height);
    if (maxDisparity !== undefined) state.max_disparity = text(maxDisparity);
    writeForm(state);
  }

  async function importCalibration() {
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
      const response = await fetch('/calibration', {
        method: 'POST',
        headers: { 'content-type': 'application/json', accept: 'application/json' },
        body: JSON.stringify(request),
      });
      const type = response.headers.get('content-type') || '';
      const body = type.includes('json') ? await response.json() : null;
      if (!response.ok) {
        errors.replaceChildren(...problemsOf({ status: response.status, body })
          .map(({ field, message }) => listItem(`${field}: ${message}`)));
        errors.hidden = false;
        $('import-status').textContent = 'Not imported: the service could not read the file.';
        return;
      }
      const rig = body.rig;
      applyRig(rig, body.max_disparity_px);
      sizeFromCalibration = rig.image_width !== undefined;
      const format = FORMAT_NAMES[body.format] ?? body.format;
      const warnings = body.warnings.length > 0 ? ` Warnings: ${body.warnings.join(' ')}` : ' No warnings.';
      $('import-status').textContent =
        `Read as ${format === 'OpenCV' ? 'an' : 'a'} ${format} calibration: f = ${fmt(rig.focal_length_px)} px, B = ${fmt(rig.baseline)} ${rig.unit}.${warnings}`;
      $('import-status').dataset.format = body.format;
      compute(`Imported a ${format} calibration.`);
      if (mode === 'images') requestDepth();
    } catch (error) {
      errors.replaceChildren(listItem(`service: could not be reached (${error.message}).`));
      errors.hidden = false;
    } finally {
      document.body.dataset.import = 'done';
    }
  }

  // ---------------------------------------------------------------------------------------
  // The pair, its depth map (/depth-map, as NumPy arrays), and what was found on it (/match).

  const pair = {
    files: { left: null, right: null },
    bitmaps: { left: null, right: null },
    width: 0,
    height: 0,
    /** The depth map: { width, height, disparity, depth, depth_error } (Float32Array, NaN
     * where invalid) and the unit of the depths. */
    arrays: null,
    unit: 'mm',
    match: null,
    region: null,
    crosshair: { x: 0, y: 0 },
    anchor: null,
    sample: false,
  };

  function matched() {
    return pair.match !== null && pair.match.x_right !== undefined;
  }

  /** Whether the person gave a rig (imported, the sample's, typed, or in the address), not
   * the Numbers mode's example, which would label a real scene's depths with a made-up rig. */
  let rigTouched = false;
  const RIG_INPUTS = ['focal_mode', 'focal', 'sensor_width_mm', 'pixel_size_um', 'baseline', 'unit', 'doffs', 'cx', 'cy'];

  function rigGiven(state = readForm()) {
    return rigTouched || ['focal_mode', 'focal', 'baseline', 'unit'].some((name) => state[name] !== DEFAULTS[name]);
  }

  /** Images mode without a rig: say so, and offer the calibration import. */
  function showRigNeeded() {
    const given = rigGiven();
    $('rig-needed').hidden = !(mode === 'images' && !given);
    // Once a rig is given, the cards that asked for it invite a click again.
    if (given && $('match-summary').textContent === NEEDS_RIG) showMatch(pair.match);
    if (given && $('region-summary').textContent === NEEDS_RIG) showRegion(pair.region);
  }

  const NEEDS_RIG = 'Distances need the rig: import a calibration file or type f and B under Rig.';

  /** The rig part of an image request: the form's rig members, numbers as numbers. */
  function rigPart(state) {
    const rig = {};
    for (const [key, value] of rigParams(state)) {
      const number = Number(value);
      rig[key] = key !== 'unit' && value.trim() !== '' && Number.isFinite(number) ? number : value;
    }
    return JSON.stringify(rig);
  }

  function pairForm(state) {
    const body = new FormData();
    body.append('left', pair.files.left);
    body.append('right', pair.files.right);
    if (rigGiven(state)) body.append('rig', rigPart(state));
    return body;
  }

  function rangeQuery(state, output = null) {
    const query = new URLSearchParams();
    if (output) query.set('output', output);
    for (const name of ['min_disparity', 'max_disparity']) if (state[name] !== '') query.set(name, state[name]);
    return query;
  }

  /** Where an image request's problem is shown: next to the file input or range field it
   * names, or in the list under the inputs. */
  const IMAGE_INPUTS = { left: 'left_image', right: 'right_image', min_disparity: 'min_disparity', max_disparity: 'max_disparity' };

  function clearImageErrors() {
    for (const input of Object.values(IMAGE_INPUTS)) {
      $(input).removeAttribute('aria-invalid');
      $(`${input}-error`).hidden = true;
      $(`${input}-error`).textContent = '';
    }
    $('images-errors').hidden = true;
    $('images-errors-list').replaceChildren();
  }

  function showImageErrors(errors) {
    const general = [];
    // The rig's members are marked on their fields under Inputs too.
    const rig = errors.filter(({ field }) => field.startsWith('rig.'));
    if (rig.length > 0) showErrors(rig, readForm());
    for (const { field, message } of errors) {
      const input = IMAGE_INPUTS[field];
      if (input) {
        const slot = $(`${input}-error`);
        slot.textContent = slot.textContent ? `${slot.textContent} ${message}` : message;
        slot.hidden = false;
        $(input).setAttribute('aria-invalid', 'true');
      } else {
        general.push(listItem(`${field}: ${message}`));
      }
    }
    if (general.length > 0) {
      $('images-errors-list').replaceChildren(...general);
      $('images-errors').hidden = false;
    }
  }

  /** Sends an image request, with the answer's problem as `{ errors }`. */
  async function post(path, query, body, signal) {
    const response = await fetch(`${path}?${query}`, { method: 'POST', body, signal });
    if (response.ok) return { response, errors: null };
    const type = response.headers.get('content-type') || '';
    const problem = type.includes('json') ? await response.json() : null;
    return { response, errors: problemsOf({ status: response.status, body: problem }) };
  }

  async function chooseImage(side, file) {
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
  async function loadPair(files) {
    for (const [side, file] of Object.entries(files)) await chooseImage(side, file);
    pair.match = null;
    pair.region = null;
    pair.anchor = null;
    pair.arrays = null;
    clearDepth();
    showMatch(null);
    showRegion(null);
    const { left, right } = pair.bitmaps;
    if (left) {
      pair.width = left.width;
      pair.height = left.height;
      pair.crosshair = { x: Math.floor(left.width / 2), y: Math.floor(left.height / 2) };
      if (right && right.width === left.width && right.height === left.height && !sizeFromCalibration) {
        const state = readForm();
        state.image_width = String(left.width);
        state.image_height = String(left.height);
        writeForm(state);
      }
    }
    drawMarkers();
    compute();
    await requestDepth();
  }

  function sizeCanvas(canvas, width, height) {
    if (canvas.width !== width) canvas.width = width;
    if (canvas.height !== height) canvas.height = height;
  }

  function drawImage(side) {
    const bitmap = pair.bitmaps[side];
    const canvas = $(`${side}-canvas`);
    const width = bitmap ? bitmap.width : 320;
    const height = bitmap ? bitmap.height : 240;
    sizeCanvas(canvas, width, height);
    const context = canvas.getContext('2d');
    context.clearRect(0, 0, width, height);
    if (bitmap) context.drawImage(bitmap, 0, 0);
    $(`${side}-overlay`).setAttribute('viewBox', `0 0 ${width} ${height}`);
    $(`${side}-caption`).textContent = bitmap
      ? `${side === 'left' ? 'Left' : 'Right'} image, ${width} × ${height}`
      : `${side === 'left' ? 'Left' : 'Right'} image`;
    if (side === 'left') {
      sizeCanvas($('depth-canvas'), width, height);
      sizeCanvas($('blend-canvas'), width, height);
      $('depth-overlay').setAttribute('viewBox', `0 0 ${width} ${height}`);
    }
  }

  // NumPy's NPZ as /depth-map writes it: a zip of stored (uncompressed) NPY files.
  function readNpz(buffer) {
    const view = new DataView(buffer);
    const arrays = {};
    let at = 0;
    while (at + 30 <= buffer.byteLength && view.getUint32(at, true) === 0x04034b50) {
      const method = view.getUint16(at + 8, true);
      const size = view.getUint32(at + 18, true);
      const nameLength = view.getUint16(at + 26, true);
      const extra = view.getUint16(at + 28, true);
      const name = new TextDecoder().decode(new Uint8Array(buffer, at + 30, nameLength));
      const start = at + 30 + nameLength + extra;
      if (method !== 0) throw new Error(`${name} is compressed`);
      arrays[name.replace(/\.npy$/, '')] = readNpy(buffer.slice(start, start + size));
      at = start + size;
    }
    return arrays;
  }

  function readNpy(buffer) {
    const headerLength = new DataView(buffer).getUint16(8, true);
    const header = new TextDecoder().decode(new Uint8Array(buffer, 10, headerLength));
    const shape = /'shape': \((\d+), (\d+)\)/.exec(header);
    if (!header.includes("'<f4'") || !shape) throw new Error('an array that is not a float32 image');
    return { height: Number(shape[1]), width: Number(shape[2]), data: new Float32Array(buffer, 10 + headerLength) };
  }

  let depthController = null;
  let depthToken = 0;
  let depthDebounce = null;

  function scheduleDepth() {
    clearTimeout(depthDebounce);
    if (mode !== 'images' || !pair.files.left || !pair.files.right) return;
    document.body.dataset.depth = 'pending';
    depthDebounce = setTimeout(() => requestDepth(), DEBOUNCE_MS);
  }

  /** Asks /depth-map for the pair's arrays (disparity, depth and its error) once; hovering
   * reads them, so no pixel costs a request. */
  async function requestDepth() {
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
      const { response, errors } = await post('/depth-map', rangeQuery(state, 'arrays.npz'), pairForm(state), depthController.signal);
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
        depth_error: arrays.depth_error ? arrays.depth_error.data : null,
      };
      const elapsed = performance.now() - started;
      const server = (response.headers.get('server-timing') || '').split(',')
        .map((entry) => Number((/dur=([\d.]+)/.exec(entry) || [])[1] || 0))
        .reduce((a, b) => a + b, 0);
      let valid = 0;
      for (const d of pair.arrays.disparity) if (!Number.isNaN(d)) valid += 1;
      const fraction = valid / (width * height);
      drawDepth();
      $('downloads').hidden = false;
      $('depth-status').dataset.valid = String(fraction);
      $('depth-status').textContent =
        `Depth map ${width} × ${height}: ${percent(fraction)} of the pixels matched, in ${fmt(elapsed, 3)} ms ` +
        `(${fmt(server, 3)} ms of it on the server).`;
    } catch (error) {
      if (error.name === 'AbortError' || token !== depthToken) return;
      $('depth-status').textContent = `No depth map: ${error.message}.`;
    } finally {
      if (token === depthToken) document.body.dataset.depth = 'done';
    }
  }

  // Google's Turbo colour map (Mikhailov 2019), its published polynomial: t in [0, 1], blue
  // to red, as the service's own preview.png.
  const TURBO = [
    [0.13572138, 4.6153926, -42.66032258, 132.13108234, -152.94239396, 59.28637943],
    [0.09140261, 2.19418839, 4.84296658, -14.18503333, 4.27729857, 2.82956604],
    [0.1066733, 12.64194608, -60.58204836, 110.36276771, -89.90310912, 27.34824973],
  ];

  function turbo(t) {
    const x = Math.min(1, Math.max(0, t));
    return TURBO.map((c) => {
      const v = c[0] + x * (c[1] + x * (c[2] + x * (c[3] + x * (c[4] + x * c[5]))));
      return Math.round(Math.min(1, Math.max(0, v)) * 255);
    });
  }

  function clearDepth() {
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

  /** The near and far ends of the colours: the 1st and 99th percentiles of the valid values. */
  function colourRange(values) {
    // Percentiles from at most about 200 000 pixels, evenly spread: enough for a colour scale.
    const stride = Math.max(1, Math.floor(values.length / 200000));
    const valid = [];
    for (let i = 0; i < values.length; i += stride) if (Number.isFinite(values[i]) && values[i] > 0) valid.push(values[i]);
    valid.sort((a, b) => a - b);
    if (valid.length === 0) return null;
    const at = (q) => valid[Math.min(valid.length - 1, Math.floor(q * valid.length))];
    const [near, far] = [at(0.01), at(0.99)];
    return far > near ? [near, far] : [near, near * 1.01 + 1e-9];
  }

  /** The depth map in Turbo on inverse depth, near warm, beside the left image and in the
   * blend layer over it (where invalid pixels are clear). */
  function drawDepth() {
    const a = pair.arrays;
    const values = a.depth ?? a.disparity.map((d) => (d > 0 ? 1 / d : NaN));
    const range = colourRange(values);
    const depthImage = new ImageData(a.width, a.height);
    const blendImage = new ImageData(a.width, a.height);
    if (range) {
      const [near, far] = range;
      const span = 1 / near - 1 / far;
      for (let i = 0; i < values.length; i += 1) {
        const z = values[i];
        const o = i * 4;
        depthImage.data[o + 3] = 255;
        if (!(z > 0)) continue;
        const [r, g, b] = turbo((1 / z - 1 / far) / span);
        depthImage.data.set([r, g, b], o);
        blendImage.data.set([r, g, b, 255], o);
      }
    }
    $('depth-canvas').getContext('2d').putImageData(depthImage, 0, 0);
    $('blend-canvas').getContext('2d').putImageData(blendImage, 0, 0);
    drawColourBar(range, a.depth ? pair.unit : rigGiven() ? null : 'px');
    drawMarkers();
  }

  function drawColourBar(range, unit) {
    const bar = $('colour-bar');
    const title = $('colour-bar-title');
    bar.replaceChildren(title);
    if (!range || !unit) {
      title.textContent = 'No depths: the rig is not valid.';
      return;
    }
    // Without a rig the colours are the disparities': labelled d = 1 / (the inverse shown).
    const px = unit === 'px';
    const label = (z) => fmt(px ? 1 / z : z, 4);
    const [near, far] = range;
    const [left, right] = [10, 310];
    const at = (z) => left + ((1 / z - 1 / far) / (1 / near - 1 / far)) * (right - left);
    const gradient = svg('linearGradient', { id: 'turbo-gradient', x1: 0, x2: 1, y1: 0, y2: 0 });
    for (let i = 0; i <= 16; i += 1) {
      const [r, g, b] = turbo(i / 16);
      gradient.append(svg('stop', { offset: i / 16, 'stop-color': `rgb(${r},${g},${b})` }));
    }
    const defs = svg('defs');
    defs.append(gradient);
    bar.append(defs, svg('rect', { x: left, y: 2, width: right - left, height: 12, fill: 'url(#turbo-gradient)' }));
    // Inverse depth crowds the far ticks together: a label needs 34 units of its own.
    let last = -Infinity;
    for (const z of linearTicks(near, far, 7).sort((p, q) => at(p) - at(q))) {
      const x = at(z);
      if (x - last < 34) continue;
      last = x;
      bar.append(svg('line', { class: 'tick', x1: x, x2: x, y1: 14, y2: 18 }));
      bar.append(svg('text', { x, y: 28, 'text-anchor': 'middle' }, label(z)));
    }
    bar.append(svg('text', { x: (left + right) / 2, y: 42, 'text-anchor': 'middle' }, px
      ? 'Disparity (px), far = blue, near = red'
      : `Depth (${unit}), far = blue, near = red`));
    title.textContent = px
      ? `Disparity colour bar: ${label(far)} px (blue) to ${label(near)} px (red); distances need the rig.`
      : `Depth colour bar: ${fmt(far, 4)} ${unit} (blue) to ${fmt(near, 4)} ${unit} (red).`;
    bar.dataset.unit = unit;
  }

  /** The image pixel under a pointer event in `frame`. */
  function pixelAt(event, frame) {
    const rect = frame.getBoundingClientRect();
    const x = Math.floor(((event.clientX - rect.left) * pair.width) / rect.width);
    const y = Math.floor(((event.clientY - rect.top) * pair.height) / rect.height);
    return { x: Math.min(pair.width - 1, Math.max(0, x)), y: Math.min(pair.height - 1, Math.max(0, y)) };
  }

  /** The distance under the pointer, from the arrays fetched once. */
  function showHover({ x, y }) {
    const a = pair.arrays;
    const hover = $('hover');
    if (!a) return;
    const i = y * a.width + x;
    const d = a.disparity[i];
    const z = a.depth ? a.depth[i] : NaN;
    hover.dataset.x = String(x);
    hover.dataset.y = String(y);
    if (Number.isFinite(z)) {
      hover.textContent = `(${x}, ${y}): ${fmt(z, 5)} ${pair.unit} ± ${fmt(a.depth_error[i], 3)} ${pair.unit}, d = ${fmt(d, 4)} px`;
    } else if (Number.isFinite(d)) {
      hover.textContent = rigGiven()
        ? `(${x}, ${y}): d = ${fmt(d, 4)} px, no depth (check the rig)`
        : `(${x}, ${y}): d = ${fmt(d, 4)} px. ${NEEDS_RIG}`;
    } else {
      hover.textContent = `(${x}, ${y}): no reliable match here; click for /match's best guess and why`;
    }
  }

  function overlayShapes(id, shapes) {
    $(id).replaceChildren(...shapes);
  }

  /** Markers in image pixels: the match on the left image and the depth map, its partner and
   * row (the epipolar line) on the right image, the box, and the keyboard's crosshair. */
  function drawMarkers() {
    const r = Math.max(4, Math.max(pair.width, pair.height) / 60);
    const left = [];
    const right = [];
    const c = pair.crosshair;
    const crosshair = svg('g', { class: 'crosshair', id: 'crosshair', 'data-x': c.x, 'data-y': c.y });
    crosshair.append(
      svg('line', { x1: c.x + 0.5, x2: c.x + 0.5, y1: c.y + 0.5 - 2 * r, y2: c.y + 0.5 + 2 * r }),
      svg('line', { y1: c.y + 0.5, y2: c.y + 0.5, x1: c.x + 0.5 - 2 * r, x2: c.x + 0.5 + 2 * r }),
    );
    const box = pair.region ?? (pair.anchor ? boxOf(pair.anchor, c) : null);
    const shapes = [];
    if (box) {
      const attributes = { x: box.x, y: box.y, width: box.width, height: box.height };
      shapes.push(svg('rect', { ...attributes, class: 'box' }), svg('rect', { ...attributes, class: 'box-core', id: 'box' }));
    }
    const m = pair.match;
    if (m) {
      const at = { cx: m.x + 0.5, cy: m.y + 0.5, r };
      shapes.push(svg('circle', { ...at, class: 'marker' }), svg('circle', { ...at, class: 'marker-core', id: 'left-marker' }));
      right.push(svg('line', { class: 'epipolar', id: 'epipolar', x1: 0, x2: pair.width, y1: m.y + 0.5, y2: m.y + 0.5 }));
      if (m.x_right !== undefined) {
        const there = { cx: m.x_right + 0.5, cy: m.y + 0.5, r, 'data-x': m.x_right, 'data-y': m.y };
        right.push(svg('circle', { ...there, class: 'marker' }), svg('circle', { ...there, class: 'marker-core', id: 'right-marker' }));
      }
    }
    left.push(...shapes, crosshair);
    overlayShapes('left-overlay', left);
    overlayShapes('depth-overlay', shapes.map((s) => s.cloneNode(true)).map((s) => {
      s.removeAttribute('id');
      return s;
    }));
    overlayShapes('right-overlay', right);
  }

  function boxOf(a, b) {
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

  function showMatch(m) {
    const values = $('match-values');
    if (m === null) {
      $('match-summary').textContent = 'Click the left image (or press Enter on it) for a match.';
      values.hidden = true;
      return;
    }
    const meaning = STATUS_MEANING[m.status] ?? m.status;
    $('match-summary').textContent = m.x_right !== undefined
      ? `(${m.x}, ${m.y}) in the left image is at x = ${fmt(m.x_right, 7)} px in the right image: ${m.status}, ${meaning}.`
      : `(${m.x}, ${m.y}): no match, ${m.status}: ${meaning}.`;
    $('match-left').textContent = `(${m.x}, ${m.y}) px`;
    $('match-x-right').textContent = m.x_right !== undefined ? `${fmt(m.x_right, 7)} px` : '–';
    $('match-disparity').textContent = m.disparity_px !== undefined ? `${fmt(m.disparity_px, 6)} px` : '–';
    const statusCell = $('match-status');
    statusCell.textContent = m.status;
    statusCell.className = m.status === 'ok' ? 'status-ok' : 'status-other';
    $('match-confidence').textContent = fmt(m.confidence, 3);
    values.hidden = false;
  }

  function showRegion(r) {
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
      `± ${fmt(r.depth_error, 3)} ${u} at its centre, d = ${fmt(r.disparity_px, 5)} px, ${percent(r.valid_fraction)} of its pixels valid.`;
  }

  /** The lines "Copy results" adds in Images mode. */
  function findings() {
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
  async function find(parts, what) {
    const state = readForm();
    const body = pairForm(state);
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
  function askForRig() {
    $('match-summary').textContent = NEEDS_RIG;
    $('region-summary').textContent = NEEDS_RIG;
    status.textContent = NEEDS_RIG;
    showRigNeeded();
    drawMarkers();
  }

  async function matchAt(x, y) {
    if (!pair.files.left || !pair.files.right) return;
    pair.crosshair = { x, y };
    if (!rigGiven()) {
      askForRig();
      return;
    }
    $('match-summary').textContent = `Matching (${x}, ${y})…`;
    const found = await find({ points: [{ x, y }] }, 'match');
    if (!found) return;
    const m = found.answer.matches[0];
    pair.match = m;
    showMatch(m);
    drawMarkers();
    if (m.x_right !== undefined) {
      $('x_left').value = String(m.x);
      $('x_right').value = String(m.x_right);
      $('y').value = String(m.y);
    }
    await compute(`Matched (${x}, ${y}): ${m.status}.`);
  }

  async function measureRegion(a, b) {
    if (!pair.files.left || !pair.files.right) return;
    const box = boxOf(a, b);
    pair.region = box;
    pair.anchor = null;
    if (!rigGiven()) {
      askForRig();
      return;
    }
    drawMarkers();
    $('region-summary').textContent = `Measuring the box at (${box.x}, ${box.y}), ${box.width} × ${box.height} px…`;
    const found = await find({ regions: [box] }, 'region');
    if (!found) return;
    pair.region = { ...found.answer.regions[0], unit: found.answer.unit };
    showRegion(pair.region);
    drawMarkers();
    status.textContent = pair.region.distance !== undefined
      ? `Region: median ${fmt(pair.region.distance)} ${pair.region.unit}.`
      : 'Region: no distance.';
  }

  async function download(output) {
    const line = $('download-status');
    if (!pair.files.left || !pair.files.right) return;
    line.textContent = `Preparing ${output}…`;
    const state = readForm();
    try {
      const { response, errors } = await post('/depth-map', rangeQuery(state, output), pairForm(state));
      if (errors) {
        line.textContent = `No ${output}: ${errors.map((e) => `${e.field}: ${e.message}`).join(' ')}`;
        return;
      }
      const blob = await response.blob();
      const url = URL.createObjectURL(blob);
      const link = document.createElement('a');
      link.href = url;
      link.download = output;
      document.body.append(link);
      link.click();
      link.remove();
      setTimeout(() => URL.revokeObjectURL(url), 60000);
      line.textContent = `Saved ${output} (${fmt(blob.size / 1024, 3)} KiB).`;
    } catch (error) {
      line.textContent = `No ${output}: ${error.message}.`;
    }
  }

  /** `/?mode=images&sample=1`: the project's own rendered pair and its rig, matched at once. */
  async function openSample() {
    try {
      // The sample's calibration file, read by /calibration as an imported file is: the rig and,
      // from its ndisp, the search range.
      const text = await (await fetch('/sample/calib.txt')).text();
      const read = await fetch('/calibration', {
        method: 'POST',
        headers: { 'content-type': 'application/json', accept: 'application/json' },
        body: JSON.stringify({ text }),
      });
      if (!read.ok) throw new Error(`/calibration answered ${read.status}`);
      const about = await read.json();
      const files = {};
      for (const side of ['left', 'right']) {
        const blob = await (await fetch(`/sample/${side}.png`)).blob();
        files[side] = new File([blob], `sample-${side}.png`, { type: 'image/png' });
        const transfer = new DataTransfer();
        transfer.items.add(files[side]);
        $(`${side}_image`).files = transfer.files;
      }
      applyRig(about.rig, about.max_disparity_px);
      sizeFromCalibration = false;
      pair.sample = true;
      $('depth-status').textContent = 'The project\'s own rendered scene: a slanted textured wall, '
        + 'a box and a disc in front of it; the disparities are known exactly.';
      await loadPair(files);
    } catch (error) {
      $('depth-status').textContent = `The sample could not be loaded (${error.message}).`;
      compute();
    }
  }

  // Wiring of the Images mode.

  for (const name of ['numbers', 'images']) {
    $(`mode-${name}`).addEventListener('click', (event) => {
      if (event.ctrlKey || event.metaKey || event.shiftKey || event.button !== 0) return;
      event.preventDefault();
      setMode(name);
      compute();
      if (name === 'images' && pair.files.left && pair.files.right && !pair.arrays) requestDepth();
    });
  }
  $('sample-link').addEventListener('click', (event) => {
    if (event.ctrlKey || event.metaKey || event.shiftKey || event.button !== 0) return;
    event.preventDefault();
    openSample();
  });
  $('import-button').addEventListener('click', importCalibration);
  $('calibration_file').addEventListener('change', async (event) => {
    const file = event.target.files[0];
    if (!file) return;
    $('calibration_text').value = await file.text();
    importCalibration();
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
  for (const name of ['min_disparity', 'max_disparity']) {
    $(name).addEventListener('input', () => {
      scheduleDepth();
      schedule();
    });
  }
  $('blend').addEventListener('change', () => {
    const on = $('blend').checked;
    $('views').dataset.blend = String(on);
    $('opacity').disabled = !on;
    $('blend-canvas').style.opacity = on ? String(Number($('opacity').value) / 100) : '0';
  });
  $('opacity').addEventListener('input', () => {
    $('blend-canvas').style.opacity = String(Number($('opacity').value) / 100);
  });
  $('downloads').addEventListener('click', (event) => {
    const button = event.target.closest('button[data-output]');
    if (button) download(button.dataset.output);
  });

  // Pointing: hover reads the arrays; a click matches; a drag measures a box.
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
      showHover(at);
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
      showHover(pair.crosshair);
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
    if (pair.arrays) showHover(pair.crosshair);
  });

  // ---------------------------------------------------------------------------------------
  // Wiring.

  form.addEventListener('input', (event) => {
    if (RIG_INPUTS.includes(event.target.id)) rigTouched = true;
    if (event.target.matches('input[type="text"]')) {
      schedule();
      scheduleDepth();
    }
  });
  form.addEventListener('change', (event) => {
    if (event.target.id === 'calibration_unit') return;
    if (RIG_INPUTS.includes(event.target.id)) rigTouched = true;
    if (event.target.tagName === 'SELECT') forgetUnknown(event.target);
    if (event.target.id === 'focal_mode' && event.target.value in FOCAL_MODES) showFocalMode(event.target.value);
    if (event.target.id === 'unit') showUnit(event.target.value);
    if (event.target.tagName === 'SELECT') {
      compute();
      scheduleDepth();
    }
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
  if (mode === 'images' && new URLSearchParams(location.search).get('sample') === '1') {
    openSample();
  } else {
    compute();
  }
})();
