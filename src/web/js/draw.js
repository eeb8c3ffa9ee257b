// Drawing: SVG elements, the chart from /chart-data, the Turbo colours of the depth map and
// its colour bar, and sizing canvases. It draws what the API answered and computes nothing.

import { $, fmt } from './util.js';

// The chart, drawn in SVG from /chart-data.


const SVG_NS = 'http://www.w3.org/2000/svg';
const WIDTH = 520;
const HEIGHT = 380;

export function svg(name, attributes = {}, text = null) {
  const node = document.createElementNS(SVG_NS, name);
  for (const [key, value] of Object.entries(attributes)) node.setAttribute(key, String(value));
  if (text !== null) node.textContent = text;
  return node;
}

/** A step of 1, 2 or 5 × 10ⁿ giving about `target` intervals across `span`. */
export function niceStep(span, target) {
  const raw = span / target;
  const magnitude = 10 ** Math.floor(Math.log10(raw));
  const ratio = raw / magnitude;
  const step = (ratio <= 1 ? 1 : ratio <= 2 ? 2 : ratio <= 5 ? 5 : 10) * magnitude;
  return Number.isFinite(step) && step > 0 ? step : 1;
}

/** A map from [min, max] onto the pixels [from, to], linear or logarithmic. */
export function scaleOf(min, max, from, to, log = false) {
  const f = log ? Math.log10 : (v) => v;
  const [a, b] = [f(min), f(max)];
  const at = (v) => from + ((to - from) * (f(v) - a)) / (b - a || 1);
  at.min = min;
  at.max = max;
  at.log = log;
  return at;
}

export function linearTicks(min, max, target = 6) {
  const step = niceStep(max - min, target);
  const ticks = [];
  for (let v = Math.ceil(min / step) * step; v <= max + step * 1e-9 && ticks.length < 15; v += step) {
    ticks.push(Number(v.toPrecision(12)));
  }
  return ticks;
}

export function logTicks(min, max) {
  const first = Math.ceil(Math.log10(min) - 1e-9);
  const last = Math.floor(Math.log10(max) + 1e-9);
  const every = Math.max(1, Math.ceil((last - first + 1) / 8));
  const ticks = [];
  for (let e = first; e <= last; e += every) ticks.push(10 ** e);
  return ticks;
}

/** [min, max] of a nice y range: from 0 to a tick for a linear axis, whole decades for a log one. */
export function yRange(values, log) {
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

export function polyline(points, x, y, cls) {
  const coordinates = points
    .filter((p) => Number.isFinite(p.y) && (!y.log || p.y > 0))
    .map((p) => `${x(p.x).toFixed(1)},${y(p.y).toFixed(1)}`);
  return svg('polyline', { class: `line ${cls}`, points: coordinates.join(' '), 'data-count': coordinates.length });
}

export function showChart(data, log) {
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

// The depth map's colours.

// Google's Turbo colour map (Mikhailov 2019), its published polynomial: t in [0, 1], blue
// to red, as the service's own preview.png.
const TURBO = [
  [0.13572138, 4.6153926, -42.66032258, 132.13108234, -152.94239396, 59.28637943],
  [0.09140261, 2.19418839, 4.84296658, -14.18503333, 4.27729857, 2.82956604],
  [0.1066733, 12.64194608, -60.58204836, 110.36276771, -89.90310912, 27.34824973],
];

export function turbo(t) {
  const x = Math.min(1, Math.max(0, t));
  return TURBO.map((c) => {
    const v = c[0] + x * (c[1] + x * (c[2] + x * (c[3] + x * (c[4] + x * c[5]))));
    return Math.round(Math.min(1, Math.max(0, v)) * 255);
  });
}

/** The near and far ends of the colours: the 1st and 99th percentiles of the valid values. */
export function colourRange(values) {
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

/** The colour bar's strip, from x = BAR_LEFT to BAR_RIGHT of its 320 units. */
const BAR_LEFT = 10;
const BAR_RIGHT = 310;
/** The colour bars' viewBox width: a label is kept inside it. */
const BAR_WIDTH = 320;
/** Half a 10 px label's width per character, near enough for digits. */
const HALF_CHAR = 3.1;

/** Turbo across the colour bar (its gradient named `id`) with `ticks`, [x, label] pairs, each
 * label given 34 units of its own. */
function turboStrip(bar, id, ticks) {
  const gradient = svg('linearGradient', { id, x1: 0, x2: 1, y1: 0, y2: 0 });
  for (let i = 0; i <= 16; i += 1) {
    const [r, g, b] = turbo(i / 16);
    gradient.append(svg('stop', { offset: i / 16, 'stop-color': `rgb(${r},${g},${b})` }));
  }
  const defs = svg('defs');
  defs.append(gradient);
  bar.append(defs, svg('rect', { x: BAR_LEFT, y: 2, width: BAR_RIGHT - BAR_LEFT, height: 12, fill: `url(#${id})` }));
  let last = -Infinity;
  for (const [x, label] of ticks.sort((p, q) => p[0] - q[0])) {
    if (x < BAR_LEFT - 0.5 || x > BAR_RIGHT + 0.5 || x - last < 34) continue;
    last = x;
    bar.append(svg('line', { class: 'tick', x1: x, x2: x, y1: 14, y2: 18 }));
    // A label at an end is set against the edge instead of centred on its tick and cut
    // ("10000" at the left end read "0000").
    const half = label.length * HALF_CHAR;
    const [at, anchor] = x - half < 0 ? [0, 'start'] : x + half > BAR_WIDTH ? [BAR_WIDTH, 'end'] : [x, 'middle'];
    bar.append(svg('text', { x: at, y: 28, 'text-anchor': anchor }, label));
  }
}

/** The depth map's colour bar (the element `id`, its title `${id}-title`): Turbo on inverse
 * depth from `range`'s far (blue) to near (red) in `unit`, or disparities for `px`. */
export function drawColourBar(range, unit, id = 'colour-bar') {
  const bar = $(id);
  const title = $(`${id}-title`);
  bar.replaceChildren(title);
  bar.dataset.kind = 'depth';
  if (!range || !unit) {
    title.textContent = 'No depths: the rig is not valid.';
    return;
  }
  // Without a rig the colours are the disparities': labelled d = 1 / (the inverse shown).
  const px = unit === 'px';
  const label = (z) => fmt(px ? 1 / z : z, 4);
  const [near, far] = range;
  const at = (z) => BAR_LEFT + ((1 / z - 1 / far) / (1 / near - 1 / far)) * (BAR_RIGHT - BAR_LEFT);
  // Inverse depth crowds the far ticks together: a label needs 34 units of its own.
  turboStrip(bar, `${id}-turbo`, linearTicks(near, far, 7).map((z) => [at(z), label(z)]));
  bar.append(svg('text', { x: (BAR_LEFT + BAR_RIGHT) / 2, y: 42, 'text-anchor': 'middle' }, px
    ? 'Disparity (px), far = blue, near = red'
    : `Depth (${unit}), far = blue, near = red`));
  title.textContent = px
    ? `Disparity colour bar: ${label(far)} px (blue) to ${label(near)} px (red); distances need the rig.`
    : `Depth colour bar: ${fmt(far, 4)} ${unit} (blue) to ${fmt(near, 4)} ${unit} (red).`;
  bar.dataset.unit = unit;
}

/** The σ map's colour bar: Turbo from `lo` (sure, blue) to `hi` and more (unsure, red), in
 * `unit`; black is no depth. */
export function drawSigmaBar(range, unit) {
  const bar = $('colour-bar');
  const title = $('colour-bar-title');
  bar.replaceChildren(title);
  bar.dataset.kind = 'sigma';
  bar.dataset.unit = unit;
  if (!range) {
    title.textContent = 'No σ: no pixel is valid.';
    return;
  }
  const [lo, hi] = range;
  const at = (v) => BAR_LEFT + ((v - lo) / (hi - lo)) * (BAR_RIGHT - BAR_LEFT);
  turboStrip(bar, 'sigma-gradient', linearTicks(lo, hi, 6).map((v) => [at(v), fmt(v, 3)]));
  const what = unit === 'px' ? 'σ of each disparity (px)' : `σ of each depth (${unit})`;
  bar.append(svg('text', { x: (BAR_LEFT + BAR_RIGHT) / 2, y: 42, 'text-anchor': 'middle' },
    `${what}; black: no depth`));
  title.textContent = `${what}: ${fmt(lo, 3)} (blue) to ${fmt(hi, 3)} and more (red); black: no depth.`;
}

export function sizeCanvas(canvas, width, height) {
  if (canvas.width !== width) canvas.width = width;
  if (canvas.height !== height) canvas.height = height;
}
