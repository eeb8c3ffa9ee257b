// What every part of the page shares: element lookup, number formatting for people (the
// API's numbers are exact; this only shortens them), and the page's own state (its mode,
// and where the rig came from).

export const $ = (id) => document.getElementById(id);

/** How long typing must pause before a request. */
export const DEBOUNCE_MS = 300;

/** The page's state across its modes. */
export const page = {
  /** `numbers`, `images` or `calibrate`: what the address's `mode` says. */
  mode: 'numbers',
  /** Whether the person gave a rig (imported, the sample's, typed, or in the address), not
   * the Numbers mode's example, which would label a real scene's depths with a made-up rig. */
  rigTouched: false,
  /** Whether the image size in the fields came from an imported calibration (then a pair of
   * another size is the API's error to show, not something to paper over). */
  sizeFromCalibration: false,
  /** The imported calibration when it describes raw cameras (`{ request, raw }`: what was
   * sent to /calibration and its `raw` answer), else null. */
  calibration: null,
};

export function fmt(value, digits = 6) {
  if (typeof value !== 'number' || !Number.isFinite(value)) return String(value);
  if (value === 0) return '0';
  const magnitude = Math.abs(value);
  if (magnitude >= 1e-4 && magnitude < 1e9) return String(Number(value.toPrecision(digits)));
  return value.toExponential(digits - 1).replace(/\.?0+e/, 'e');
}

export function percent(fraction) {
  return `${fmt(fraction * 100, 3)} %`;
}

export function listItem(text) {
  const item = document.createElement('li');
  item.textContent = text;
  return item;
}
