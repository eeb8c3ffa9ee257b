// What every part of the page shares: element lookup, number formatting for people (the
// API's numbers are exact; this only shortens them), and the page's own state (its mode,
// and where the rig came from).

export const $ = (id) => document.getElementById(id);

/** How long typing must pause before a request. */
export const DEBOUNCE_MS = 300;

/** The page's state across its modes. */
export const page = {
  /** `numbers`, `images`, `calibrate` or `live`: what the address's `mode` says. */
  mode: 'numbers',
  /** Whether the person gave a rig (imported, the sample's, typed, or in the address), not
   * the Numbers mode's example, which would label a real scene's depths with a made-up rig. */
  rigTouched: false,
  /** Whether the image size in the fields came from an imported calibration (then a pair of
   * another size is the API's error to show, not something to paper over). */
  sizeFromCalibration: false,
  /** The imported calibration when it describes raw cameras (`{ request }`: what was sent to
   * /calibration, for the image routes' `calibration` parts), else null. */
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

/** Clears the errors shown next to `inputs` (each its `aria-invalid` and `{id}-error` slot)
 * and in the box `box` (its list `{box}-list`). */
export function clearFieldErrors(inputs, box) {
  for (const id of inputs) {
    $(id).removeAttribute('aria-invalid');
    $(`${id}-error`).hidden = true;
    $(`${id}-error`).textContent = '';
  }
  $(box).hidden = true;
  $(`${box}-list`).replaceChildren();
}

/** Shows the API's `errors`: each next to the input `place(error)` names (`{ input, text }`),
 * marked `aria-invalid`, several joined in its slot; those it places nowhere (null) listed in
 * the box `box` as `field: message`. */
export function showFieldErrors(errors, place, box) {
  const general = [];
  for (const error of errors) {
    const at = place(error);
    if (at) {
      const slot = $(`${at.input}-error`);
      slot.textContent = slot.textContent ? `${slot.textContent} ${at.text}` : at.text;
      slot.hidden = false;
      $(at.input).setAttribute('aria-invalid', 'true');
    } else {
      general.push(listItem(`${error.field}: ${error.message}`));
    }
  }
  if (general.length > 0) {
    $(`${box}-list`).replaceChildren(...general);
    $(box).hidden = false;
  }
}

/** Puts `files` into the file input `id`, as if chosen there (the samples' files). */
export function setFiles(id, files) {
  const transfer = new DataTransfer();
  for (const file of files) transfer.items.add(file);
  $(id).files = transfer.files;
}
