// What a calibration looks like on the page: the RMS and epipolar error with plain verdicts,
// a bar per view (left and right RMS; a view whose board was not found marked with the
// reason; a click leaves it out), each view's thumbnail with its corners and residual
// arrows, the coverage of each image, the advice, and the parameters with their σ. It draws
// /calibrate's answer and computes nothing of the calibration itself.

import { svg } from './draw.js';
import { $, fmt, listItem } from './util.js';

/** A verdict in plain words for an error in px: under 0.5 good, under 1 fair, else poor. */
export function verdict(px) {
  if (!(px >= 0)) return { word: 'unknown', text: 'not measured' };
  if (px < 0.5) return { word: 'good', text: 'good: under 0.5 px' };
  if (px < 1) return { word: 'fair', text: 'fair: between 0.5 and 1 px; look at the views with the largest bars' };
  return { word: 'poor', text: 'poor: 1 px or more; leave out the worst views or take new ones' };
}

function showVerdict(id, label, px, note) {
  const v = verdict(px);
  const box = $(id);
  box.className = `verdict verdict-${v.word}`;
  box.dataset.value = String(px);
  const strong = document.createElement('strong');
  strong.textContent = `${label}: ${fmt(px, 3)} px`;
  const line = document.createElement('span');
  line.textContent = ` ${v.text}. ${note}`;
  box.replaceChildren(strong, line);
}

/** What each board type's picture says: its title (read aloud) and its caption. */
const BOARD_PICTURES = {
  chessboard: {
    title: 'A board of 6 × 4 squares has 5 × 3 inner corners: the points where four squares meet, marked with circles; the board\'s outer corners do not count.',
    caption: 'Inner corners are where four squares meet (circles): a board of 10 × 7 squares has 9 × 6.',
    label: '6 × 4 squares: 5 × 3 inner corners',
  },
  charuco: {
    title: 'A ChArUco board of 6 × 4 squares: an ArUco marker in each white square, and 5 × 3 corners where four squares meet, numbered 0 to 14 row by row as OpenCV numbers them.',
    caption: 'A ChArUco board is given by its squares (6 × 4 here, OpenCV\'s squaresX × squaresY), not its corners; its markers sit in the white squares and name the corners around them, so a view with part of the board counts.',
    label: '6 × 4 squares: corners 0–14',
  },
};

/** A marker's 4 × 4 cells for the picture: a fixed pattern per marker, as a printed board
 * has (illustration only; the service reads the real dictionaries). */
function markerCells(id) {
  let bits = (id * 2654435761) >>> 0;
  const cells = [];
  for (let k = 0; k < 16; k += 1) {
    cells.push((bits & 1) === 1);
    bits = (bits >>> 1) | ((bits & 1) << 31);
    bits ^= bits >>> 7;
  }
  return cells;
}

/** The board picture beside the board's fields: 6 × 4 squares with their 5 × 3 inner corners
 * circled, a ChArUco board's with a marker in each white square and the corners' ids. */
export function drawBoardPicture(picture, type) {
  const about = BOARD_PICTURES[type] ?? BOARD_PICTURES.chessboard;
  picture.replaceChildren(svg('title', { id: 'inner-corners-title' }, about.title));
  picture.dataset.board = type;
  const size = 30;
  const [x0, y0] = [20, 20];
  let marker = 0;
  for (let j = 0; j < 4; j += 1) {
    for (let i = 0; i < 6; i += 1) {
      const black = (i + j) % 2 === 0;
      picture.append(svg('rect', { x: x0 + i * size, y: y0 + j * size, width: size, height: size, class: black ? 'square-black' : 'square-white' }));
      if (type !== 'charuco' || black) continue;
      // A marker of 6 × 6 cells: a black border round 4 × 4 bits.
      const cell = 3.5;
      const [mx, my] = [x0 + i * size + (size - 6 * cell) / 2, y0 + j * size + (size - 6 * cell) / 2];
      picture.append(svg('rect', { x: mx, y: my, width: 6 * cell, height: 6 * cell, class: 'marker' }));
      markerCells(marker).forEach((white, k) => {
        if (white) picture.append(svg('rect', { x: mx + (1 + (k % 4)) * cell, y: my + (1 + Math.floor(k / 4)) * cell, width: cell, height: cell, class: 'marker-bit' }));
      });
      marker += 1;
    }
  }
  for (let j = 1; j < 4; j += 1) {
    for (let i = 1; i < 6; i += 1) {
      const [cx, cy] = [x0 + i * size, y0 + j * size];
      picture.append(svg('circle', { cx, cy, r: 5, class: 'inner-corner' }));
      if (type === 'charuco') picture.append(svg('text', { x: cx + 4, y: cy - 5, class: 'corner-id' }, String((j - 1) * 5 + (i - 1))));
    }
  }
  picture.append(svg('text', { x: 110, y: 154, 'text-anchor': 'middle' }, about.label));
  return about.caption;
}

/** ", 24 and 17 corners" for a ChArUco view (which may show part of its board), else "". */
function cornerCounts(calibration, view) {
  if (calibration.summary.board?.type !== 'charuco') return '';
  const counts = [view.corners_found_left ?? 0, view.corners_found_right ?? 0];
  return `, ${counts[0]} and ${counts[1]} of ${calibration.summary.board.columns * calibration.summary.board.rows} corners`;
}

/** The answer's view for pair `i`, or null when it was left out. */
function viewOf(calibration, i) {
  const k = calibration.sent.indexOf(i);
  return k < 0 ? null : calibration.summary.views[k];
}

/** The bars: each pair's left and right RMS, a failed view's cross and reason, a left-out
 * view greyed; each is a button that leaves it out or puts it back. */
function drawBars(calibration) {
  const chart = $('view-bars');
  const n = calibration.pairs.length;
  const slot = 40;
  const [left, top, bottom] = [60, 12, 40];
  const width = Math.max(320, left + n * slot + 10);
  const height = 200;
  chart.setAttribute('viewBox', `0 0 ${width} ${height}`);
  chart.replaceChildren();
  const rms = calibration.summary.views.flatMap((v) => [v.rms_left, v.rms_right]).filter((r) => r >= 0);
  const top_value = Math.max(0.05, ...rms) * 1.25;
  const y = (value) => height - bottom - ((height - bottom - top) * value) / top_value;
  for (const tick of [0, top_value / 2, top_value]) {
    chart.append(svg('line', { class: 'grid', x1: left, x2: width - 10, y1: y(tick), y2: y(tick) }));
    chart.append(svg('text', { x: left - 6, y: y(tick) + 4, 'text-anchor': 'end' }, fmt(tick, 2)));
  }
  chart.append(svg('text', { x: 12, y: (height - bottom) / 2, transform: `rotate(-90 12 ${(height - bottom) / 2})`, 'text-anchor': 'middle' }, 'RMS (px)'));
  // The verdicts' "good" line, when the bars reach near it.
  if (top_value > 0.5) chart.append(svg('line', { class: 'threshold', x1: left, x2: width - 10, y1: y(0.5), y2: y(0.5) }));
  calibration.pairs.forEach((pair, i) => {
    const x = left + i * slot;
    const view = viewOf(calibration, i);
    const out = calibration.excluded.has(i);
    const group = svg('g', {
      class: `view-bar${out ? ' excluded' : ''}${view && view.status !== 'used' ? ' failed' : ''}`,
      role: 'button',
      tabindex: 0,
      'data-view': i,
      'data-status': out ? 'excluded' : view.status,
      'aria-pressed': String(out),
    });
    let label;
    if (out) {
      label = `View ${i + 1} (${pair.name}): left out by you; click to put it back`;
    } else if (view.status === 'used') {
      label = `View ${i + 1} (${pair.name}): left ${fmt(view.rms_left, 3)} px, right ${fmt(view.rms_right, 3)} px${cornerCounts(calibration, view)}; click to leave it out`;
    } else {
      const why = view.status === 'outlier' ? 'an outlier, far above the others' : view.reasons.join('; ');
      label = `View ${i + 1} (${pair.name}): not used, ${why}; click to leave it out`;
    }
    group.setAttribute('aria-label', label);
    group.append(svg('title', {}, label));
    group.append(svg('rect', { class: 'hit', x: x + 2, y: top, width: slot - 4, height: height - bottom - top }));
    if (out) {
      group.append(svg('text', { class: 'mark', x: x + slot / 2, y: y(0) - 6, 'text-anchor': 'middle' }, 'out'));
    } else if (view.status === 'board_not_found') {
      group.append(svg('text', { class: 'mark failed-mark', x: x + slot / 2, y: y(0) - 6, 'text-anchor': 'middle' }, '✕'));
    } else {
      for (const [k, value] of [view.rms_left, view.rms_right].entries()) {
        if (!(value >= 0)) continue;
        group.append(svg('rect', { class: k === 0 ? 'bar-left' : 'bar-right', x: x + 6 + k * 14, y: y(value), width: 13, height: y(0) - y(value) }));
      }
      if (view.status === 'outlier') group.append(svg('text', { class: 'mark failed-mark', x: x + slot / 2, y: top + 10, 'text-anchor': 'middle' }, '!'));
    }
    group.append(svg('text', { x: x + slot / 2, y: height - bottom + 16, 'text-anchor': 'middle' }, String(i + 1)));
    chart.append(group);
  });
  chart.append(svg('rect', { class: 'bar-left', x: left, y: height - 14, width: 10, height: 10 }));
  chart.append(svg('text', { x: left + 14, y: height - 5 }, 'left'));
  chart.append(svg('rect', { class: 'bar-right', x: left + 50, y: height - 14, width: 10, height: 10 }));
  chart.append(svg('text', { x: left + 64, y: height - 5 }, 'right (view number below each pair)'));
  const problems = [];
  calibration.pairs.forEach((pair, i) => {
    const view = viewOf(calibration, i);
    if (!view || view.status === 'used') return;
    const item = listItem(view.status === 'outlier'
      ? `View ${i + 1} (${pair.name}): left out as an outlier, its error far above the others' (left ${fmt(view.rms_left, 3)} px, right ${fmt(view.rms_right, 3)} px).`
      : `View ${i + 1} (${pair.name}): the board was not found. ${view.reasons.join('; ')}.`);
    item.dataset.view = String(i);
    problems.push(item);
  });
  $('view-problems').replaceChildren(...problems);
}

/** Each camera's coverage: the corners of the views used over the image, the cells of a 4 × 4
 * grid no corner reached shaded. */
function drawCoverage(calibration) {
  const { summary } = calibration;
  const [w, h] = [summary.image_width, summary.image_height];
  const figures = [];
  for (const side of ['left', 'right']) {
    const cover = summary.coverage[side];
    if (!cover) continue;
    const picture = svg('svg', { viewBox: `0 0 ${w} ${h}`, class: 'coverage-picture', role: 'img', id: `coverage-${side}` });
    picture.append(svg('rect', { class: 'image', x: 0, y: 0, width: w, height: h }));
    const reached = new Set();
    const dots = [];
    for (const view of summary.views) {
      if (view.status !== 'used') continue;
      for (const [x, y] of view[`corners_${side}`] ?? []) {
        reached.add(Math.min(3, Math.floor((y / h) * 4)) * 4 + Math.min(3, Math.floor((x / w) * 4)));
        dots.push(svg('circle', { class: 'corner-dot', cx: x, cy: y, r: w / 220 }));
      }
    }
    let empty = 0;
    for (let cell = 0; cell < 16; cell += 1) {
      const [cx, cy] = [cell % 4, Math.floor(cell / 4)];
      const box = { x: (cx * w) / 4, y: (cy * h) / 4, width: w / 4, height: h / 4 };
      if (!reached.has(cell)) {
        empty += 1;
        picture.append(svg('rect', { ...box, class: 'empty-cell' }));
      }
      picture.append(svg('rect', { ...box, class: 'cell' }));
    }
    // The projection σ as a heat map: green where the calibration places a point to a tenth
    // of a pixel, red from a pixel up (a log scale between).
    const uncertainty = summary.projection_uncertainty?.[side];
    if (uncertainty) {
      const rows = uncertainty.grid.length;
      uncertainty.grid.forEach((row, j) => row.forEach((sigma, i) => {
        const cols = row.length;
        const box = { x: (i * w) / cols, y: (j * h) / rows, width: w / cols, height: h / rows };
        const t = sigma === null ? 1 : Math.min(1, Math.max(0, Math.log10(sigma / 0.1)));
        const cell = svg('rect', { ...box, class: 'sigma-cell', fill: `hsl(${Math.round(120 * (1 - t))}, 70%, 45%)` });
        cell.append(svg('title', {}, sigma === null ? 'σ unknown here' : `σ ${fmt(sigma, 2)} px`));
        picture.append(cell);
      }));
      picture.dataset.sigmaMedian = String(uncertainty.median_px);
    }
    picture.append(...dots);
    picture.dataset.empty = String(empty);
    const words = `${side === 'left' ? 'Left' : 'Right'} camera: corners in ${16 - empty} of 16 cells, x ${fmt(cover.x[0] * 100, 3)}–${fmt(cover.x[1] * 100, 3)} % and y ${fmt(cover.y[0] * 100, 3)}–${fmt(cover.y[1] * 100, 3)} % of the image`;
    picture.append(svg('title', {}, words));
    const figure = document.createElement('figure');
    const caption = document.createElement('figcaption');
    // What the map means (issue 69): the σ of where a point fixed to the boards projects, from
    // how the parameters scatter when the views change, so that what the lens model cannot fit
    // counts beside the corners' noise; told apart, with what to do when the model's part wins.
    const modelWins = uncertainty?.model_error_dominates;
    if (uncertainty) picture.dataset.modelError = String(modelWins);
    const sigmaWords = uncertainty
      ? ` Projection σ at ${fmt(summary.projection_uncertainty.distance, 3)} ${summary.board.unit}: median ${fmt(uncertainty.median_px, 2)} px`
        + ` (the corners' noise ${fmt(uncertainty.noise_median_px, 2)} px, what the lens model cannot fit ${fmt(uncertainty.model_median_px, 2)} px),`
        + ` worst ${fmt(uncertainty.worst_px, 2)} px (green under 0.1 px, red from 1 px).`
        + (modelWins
          ? ' Model error dominates: more views of the same kind will not lower it; try the rational_polynomial model, add views with the board near the edges and corners, and check that the board is flat.'
          : '')
        + ' On real photographs, calibrations from disjoint halves of the views differ by about this σ (0.9–1.0 times it; mrcal\'s own map, 2.3–2.9 times).'
      : '';
    caption.textContent = `${words}${empty > 0 ? `; ${empty} empty ${empty === 1 ? 'cell' : 'cells'} shaded` : ''}.${sigmaWords}`;
    figure.append(picture, caption);
    figures.push(figure);
  }
  $('coverage').replaceChildren(...figures);
}

/** A scale for the residual arrows: 1, 2 or 5 × 10ⁿ, so that the largest residual is drawn
 * about a sixteenth of the image's width long. */
function arrowScale(calibration) {
  let largest = 0;
  for (const view of calibration.summary.views) {
    for (const side of ['left', 'right']) {
      for (const [dx, dy] of view[`residuals_${side}`] ?? []) largest = Math.max(largest, Math.hypot(dx, dy));
    }
  }
  if (largest === 0) return 1;
  const raw = calibration.summary.image_width / 16 / largest;
  const magnitude = 10 ** Math.floor(Math.log10(raw));
  const ratio = raw / magnitude;
  return (ratio >= 5 ? 5 : ratio >= 2 ? 2 : 1) * magnitude;
}

/** Each view's left and right image, small, with its corners and residual arrows. */
async function drawThumbs(calibration) {
  const scale = arrowScale(calibration);
  $('thumbs').dataset.scale = String(scale);
  $('thumbs-help').textContent = 'The corners found (green) and each corner\'s residual, the model\'s projection minus '
    + `the corner, as a red arrow drawn ${fmt(scale, 3)} times its length: a 0.1 px residual is ${fmt(0.1 * scale, 3)} px long on the image.`;
  const figures = [];
  for (const [i, pair] of calibration.pairs.entries()) {
    const view = viewOf(calibration, i);
    const figure = document.createElement('figure');
    figure.className = 'thumb';
    figure.dataset.view = String(i);
    for (const side of ['left', 'right']) {
      const canvas = document.createElement('canvas');
      let bitmap = null;
      try {
        bitmap = await createImageBitmap(pair[side]);
      } catch {
        // The browser cannot show it; the service said what it is.
      }
      const w = bitmap ? bitmap.width : 640;
      const h = bitmap ? bitmap.height : 480;
      const s = 200 / w;
      canvas.width = 200;
      canvas.height = Math.round(h * s);
      canvas.setAttribute('aria-label', `View ${i + 1}, ${side} image`);
      const context = canvas.getContext('2d');
      if (bitmap) context.drawImage(bitmap, 0, 0, canvas.width, canvas.height);
      if (view) {
        context.fillStyle = '#43a047';
        for (const [x, y] of view[`corners_${side}`] ?? []) context.fillRect(x * s - 1.5, y * s - 1.5, 3, 3);
        context.strokeStyle = '#e53935';
        context.lineWidth = 1.5;
        const corners = view[`corners_${side}`] ?? [];
        for (const [k, [dx, dy]] of (view[`residuals_${side}`] ?? []).entries()) {
          const [x, y] = corners[k];
          context.beginPath();
          context.moveTo(x * s, y * s);
          context.lineTo((x + scale * dx) * s, (y + scale * dy) * s);
          context.stroke();
        }
      }
      figure.append(canvas);
    }
    const caption = document.createElement('figcaption');
    const out = calibration.excluded.has(i);
    caption.textContent = out
      ? `${i + 1}. ${pair.name}: left out`
      : view.status === 'used'
        ? `${i + 1}. ${pair.name}: ${fmt(view.rms_left, 3)} / ${fmt(view.rms_right, 3)} px, tilted ${fmt(view.tilt_deg, 3)}°${cornerCounts(calibration, view)}`
        : `${i + 1}. ${pair.name}: ${view.status === 'outlier' ? 'outlier' : 'board not found'}`;
    figure.append(caption);
    figures.push(figure);
  }
  $('thumbs').replaceChildren(...figures);
}

const COEFFICIENTS = {
  plumb_bob: ['k1', 'k2', 'p1', 'p2', 'k3'],
  rational_polynomial: ['k1', 'k2', 'p1', 'p2', 'k3', 'k4', 'k5', 'k6'],
  equidistant: ['k1', 'k2', 'k3', 'k4'],
};

const withStd = (value, std, digits = 6) => (std === undefined ? fmt(value, digits) : `${fmt(value, digits)} ± ${fmt(std, 2)}`);

/** The parameters with their standard deviations: each camera's, the pose between them and
 * the rectified rig. */
function drawParameters(summary) {
  const table = $('parameters');
  let columns = 3;
  const row = (cells, header = false) => {
    const tr = document.createElement('tr');
    cells.forEach((text, k) => {
      const cell = document.createElement(header || k === 0 ? 'th' : 'td');
      if (!header && k === 0) cell.scope = 'row';
      // A value of the pair (T, R, the rig) spans both cameras' columns.
      if (cells.length === 2 && columns === 3 && k === 1) cell.colSpan = 2;
      cell.textContent = text;
      tr.append(cell);
    });
    return tr;
  };
  const cameras = [summary.left, summary.right].filter(Boolean);
  columns = cameras.length + 1;
  const rows = [row(['Parameter', 'Left camera', ...(summary.right ? ['Right camera'] : [])], true)];
  const k = (camera) => camera.camera_matrix;
  rows.push(row(['fx (px)', ...cameras.map((c) => withStd(k(c)[0][0], c.std.fx))]));
  rows.push(row(['fy (px)', ...cameras.map((c) => withStd(k(c)[1][1], c.std.fy))]));
  rows.push(row(['cx (px)', ...cameras.map((c) => withStd(k(c)[0][2], c.std.cx))]));
  rows.push(row(['cy (px)', ...cameras.map((c) => withStd(k(c)[1][2], c.std.cy))]));
  (COEFFICIENTS[summary.model] ?? []).forEach((name, n) => {
    rows.push(row([name, ...cameras.map((c) => withStd(c.distortion[n], c.std.distortion[n], 4))]));
  });
  rows.push(row(['RMS (px)', ...cameras.map((c) => fmt(c.rms, 3))]));
  const unit = summary.board.unit;
  if (summary.translation) {
    const t = summary.translation;
    const ts = summary.translation_std;
    rows.push(row([`T (${unit}), X_right = R·X_left + T`, t.map((v, n) => withStd(v, ts[n], 5)).join(', ')]));
    const r = summary.rotation;
    const angle = Math.acos(Math.min(1, Math.max(-1, (r[0][0] + r[1][1] + r[2][2] - 1) / 2)));
    const rs = summary.rotation_std_deg;
    rows.push(row(['R: angle (°), with its σ about x, y and z', `${fmt((angle * 180) / Math.PI, 4)}° (σ ${rs.map((v) => fmt(v, 2)).join(' / ')}°)`]));
  }
  if (summary.rig) {
    const rig = summary.rig;
    rows.push(row(['Rectified f (px)', withStd(rig.focal_length_px, rig.focal_length_std_px)]));
    rows.push(row([`Rectified baseline B (${rig.unit})`, withStd(rig.baseline, rig.baseline_std)]));
  }
  table.replaceChildren(...rows);
  table.dataset.focal = String(summary.rig?.focal_length_px ?? '');
  table.dataset.baseline = String(summary.rig?.baseline ?? '');
}

/** Shows /calibrate's answer for the pairs `calibration.sent`; the promise is the
 * thumbnails', drawn last. */
export function showCalibration(calibration) {
  const { summary } = calibration;
  const used = summary.views.filter((v) => v.status === 'used').length;
  const failed = summary.views.filter((v) => v.status === 'board_not_found').length;
  const outliers = summary.views.filter((v) => v.status === 'outlier').length;
  const out = calibration.excluded.size;
  showVerdict('rms-verdict', 'RMS reprojection error', summary.rms, 'How far, on average, the calibrated model puts each corner from where it was found.');
  if (summary.determined === false) {
    // A low RMS over views that do not constrain the lens fits the corners and nothing more.
    const box = $('rms-verdict');
    box.className = 'verdict verdict-poor';
    box.dataset.determined = 'false';
    const strong = document.createElement('strong');
    strong.textContent = `Not determined (RMS ${fmt(summary.rms, 3)} px)`;
    const line = document.createElement('span');
    line.textContent = ' The views do not constrain the model: the RMS only says that it fits these corners. See the advice below.';
    box.replaceChildren(strong, line);
  }
  if (summary.epipolar_error !== undefined) {
    showVerdict('epipolar-verdict', 'Epipolar error', summary.epipolar_error, 'How far each corner lies from the line its partner in the other image says it must be on: what matching will suffer.');
  } else {
    $('epipolar-verdict').replaceChildren(document.createTextNode('Epipolar error: needs both cameras.'));
  }
  const views = $('views-verdict');
  views.dataset.used = String(used);
  views.textContent = `${used} of ${calibration.pairs.length} views used`
    + `${out > 0 ? `, ${out} left out by you` : ''}${failed > 0 ? `, ${failed} without the board` : ''}`
    + `${outliers > 0 ? `, ${outliers} left out as ${outliers === 1 ? 'an outlier' : 'outliers'}` : ''}.`;
  const cross = summary.cross_validation;
  if (cross) {
    views.dataset.consistent = String(cross.consistent);
    views.dataset.ratio = String(cross.ratio);
    const apart = `two halves of the views ${fmt(cross.median_px, 2)} px apart, ${fmt(cross.ratio, 2)} times the ${fmt(cross.predicted_median_px, 2)} px their σ predict`;
    views.textContent += cross.consistent
      ? ` Cross-validation: consistent (${apart}; 0.7–1.4 is consistent).`
      : cross.ratio > 1.4
        ? ` Cross-validation: not consistent (${apart}): the model does not fit these views alike; take more views, try the rational_polynomial model, or check that the board is flat.`
        : ` Cross-validation: not consistent (${apart}): the σ is cautious for these views; halves of few views scatter more than the whole.`;
  }
  drawBars(calibration);
  drawCoverage(calibration);
  const advice = summary.warnings.map((w) => listItem(w));
  for (const side of ['left', 'right']) {
    const empty = Number($(`coverage-${side}`)?.dataset.empty ?? 0);
    if (empty > 0) {
      advice.push(listItem(`The ${side} image has ${empty} of 16 cells without a corner (shaded under "Where the corners landed"): `
        + 'add views with the board there, so that the lens is measured where it distorts most.'));
    }
  }
  $('calibration-advice').replaceChildren(...(advice.length > 0 ? advice : [listItem('None: enough views, tilted, and corners all over both images.')]));
  drawParameters(summary);
  // A rig, its rectification and the right camera's file need both cameras' images.
  const stereo = summary.rig !== undefined;
  $('use-calibration').disabled = !stereo;
  $('calibration-results').querySelector("button[data-output='ros-right.yaml']").disabled = !stereo;
  $('calibration-download-status').textContent = stereo ? '' : 'Only the left camera was calibrated: a rig needs right images too.';
  const results = $('calibration-results');
  const fresh = results.hidden;
  results.hidden = false;
  // A first answer below the fold is brought up (the form fills a laptop's first screen); a
  // view left out and calibrated again stays where the person clicked.
  if (fresh && results.getBoundingClientRect().top > window.innerHeight * 0.6) {
    results.scrollIntoView({ block: 'start' });
  }
  return drawThumbs(calibration);
}

/** Bar clicks and keys: leave a view out, or put it back (`toggleView`, with the view's
 * index). */
export function wireBars(toggleView) {
  const chart = $('view-bars');
  const act = (event) => {
    const group = event.target.closest('.view-bar');
    if (group) toggleView(Number(group.dataset.view));
  };
  chart.addEventListener('click', act);
  chart.addEventListener('keydown', (event) => {
    if (event.key !== 'Enter' && event.key !== ' ') return;
    event.preventDefault();
    act(event);
  });
}
