// The state the page's modes share, below all of them: the image pair and what was found on
// it, and the mode's requests to one another as named events, so that a mode imports only
// what lies under it (this file, api.js, draw.js, rig.js, util.js) and never another mode.

import { page } from './util.js';

export const pair = {
  files: { left: null, right: null },
  bitmaps: { left: null, right: null },
  width: 0,
  height: 0,
  /** The depth map: { width, height, disparity, depth, disparity_std, depth_std }
   * (Float32Array, NaN where invalid; depth and depth_std null without a rig) and the unit of
   * the depths. */
  arrays: null,
  unit: 'mm',
  match: null,
  region: null,
  crosshair: { x: 0, y: 0 },
  anchor: null,
  sample: false,
  /** With a calibration of raw cameras: the pair the service rectified (bitmaps, and the
   * PNG files /rectify answered), and which of the two is shown, `raw` or `rectified`. */
  rectified: { left: null, right: null },
  rectifiedFiles: { left: null, right: null },
  view: 'raw',
};

/** Whether the pair is raw frames the service rectifies: a calibration of raw cameras was
 * imported (or came from Calibrate mode). */
export function rawPair() {
  return page.calibration !== null;
}

/** The frame clicks and boxes are in: `plain` for a rectified pair, else the view shown. */
export function frameShown() {
  return rawPair() ? pair.view : 'plain';
}

export function matched() {
  return pair.match !== null && pair.match.x_right !== undefined;
}

export const NEEDS_RIG = 'Distances need the rig: import a calibration file or type f and B under Rig.';

const handlers = new Map();

/** Handles the event `name` with `fn` (a mode offering what others may ask of it). */
export function on(name, fn) {
  if (!handlers.has(name)) handlers.set(name, []);
  handlers.get(name).push(fn);
}

/** Asks every handler of `name`; their answers, in the order they were registered. */
export function emit(name, ...args) {
  return (handlers.get(name) ?? []).map((fn) => fn(...args));
}

/** The events the modes answer: who handles each, and what it does. */
export const EVENTS = {
  /** numbers.js: the distance for the form (an optional note). */
  compute: 'compute',
  /** numbers.js: the distance after typing pauses. */
  schedule: 'schedule',
  /** images.js: a new depth map after typing pauses. */
  scheduleDepth: 'schedule-depth',
  /** images.js: say whether Images mode lacks the rig. */
  showRigNeeded: 'show-rig-needed',
  /** images.js: forget the last click's match and box. */
  forgetFindings: 'forget-findings',
  /** findings.js: draw the markers over the images. */
  drawMarkers: 'draw-markers',
  /** findings.js: show a match (or none). */
  showMatch: 'show-match',
  /** findings.js: show a box's distance (or none). */
  showRegion: 'show-region',
  /** findings.js: the lines "Copy results" adds in Images mode. */
  findingsLines: 'findings-lines',
  /** calibrate.js: the `board` part of the board set in Calibrate mode (JSON text). */
  boardPart: 'board-part',
  /** calibrate.js: take these files (`live_N_left.jpg`, `live_N_right.jpg`) as the pairs and
   * calibrate them; "Use this calibration" then goes back to `from` (a mode's name). */
  calibratePairs: 'calibrate-pairs',
};
