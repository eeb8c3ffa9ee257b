// Talking to the service: GET with query members, POST of JSON or multipart forms, the
// problem+json answers turned into `{ field, message }` lists, NumPy arrays read from
// /depth-map's NPZ, answers saved as files, and the live stream's WebSocket. Every request the
// page makes goes through here, and so does the access token: a service given tokens answers 401, the page asks for one
// once (a dialog), keeps it for the tab (sessionStorage) and sends it as a bearer token with
// every request after; a token refused is asked for again.

const TOKEN_KEY = 'stereo-distance-token';

function storedToken() {
  try {
    return sessionStorage.getItem(TOKEN_KEY) || '';
  } catch {
    return '';
  }
}

/** `headers` with the tab's token, when it has one. */
function withToken(headers = {}) {
  const token = storedToken();
  return token ? { ...headers, authorization: `Bearer ${token}` } : headers;
}

let asking = null;

/** Asks for a token in the dialog (one question at a time, shared by the requests waiting);
 * resolves true when one was given and kept. `refused` says the last one was not accepted. */
function askForToken(refused) {
  if (asking) return asking;
  asking = new Promise((resolve) => {
    const dialog = document.getElementById('token-dialog');
    const input = document.getElementById('token-input');
    if (!dialog || !input || typeof dialog.showModal !== 'function') {
      resolve(false);
      return;
    }
    document.getElementById('token-why').textContent = refused
      ? 'The service did not accept that token. Enter a current one.'
      : 'This service takes requests with an access token only.';
    input.value = '';
    dialog.addEventListener('close', () => {
      const token = input.value.trim();
      const given = dialog.returnValue === 'use' && token !== '';
      if (given) {
        try {
          sessionStorage.setItem(TOKEN_KEY, token);
        } catch {
          // Storage refused (a private window's quota): the token is not kept.
        }
      }
      input.value = '';
      asking = null;
      resolve(given);
    }, { once: true });
    dialog.showModal();
    input.focus();
  });
  return asking;
}

/** `fetch` with the tab's token, asking for one on a 401 and trying again with it. */
async function fetchWithToken(url, init = {}) {
  for (;;) {
    const had = storedToken();
    const response = await fetch(url, { ...init, headers: withToken(init.headers) });
    if (response.status !== 401 || !(await askForToken(had !== ''))) return response;
  }
}

/** A GET of `path` with `params`, its JSON body (or null) and status. */
export async function call(path, params, signal) {
  const response = await fetchWithToken(`${path}?${params}`, { headers: { accept: 'application/json' }, signal });
  const type = response.headers.get('content-type') || '';
  const body = type.includes('json') ? await response.json() : null;
  return { ok: response.ok, status: response.status, body };
}

/** A POST of JSON, answered in JSON: `{ ok, status, body }`. */
export async function postJson(path, request, signal) {
  const response = await fetchWithToken(path, {
    method: 'POST',
    headers: { 'content-type': 'application/json', accept: 'application/json' },
    body: JSON.stringify(request),
    signal,
  });
  const type = response.headers.get('content-type') || '';
  const body = type.includes('json') ? await response.json() : null;
  return { ok: response.ok, status: response.status, body };
}

/** Sends a multipart form, with the answer's problem as `{ errors }`. */
export async function post(path, query, body, signal) {
  const response = await fetchWithToken(`${path}?${query}`, { method: 'POST', body, signal });
  if (response.ok) return { response, errors: null };
  const type = response.headers.get('content-type') || '';
  const problem = type.includes('json') ? await response.json() : null;
  return { response, errors: problemsOf({ status: response.status, body: problem }) };
}

/** A problem's field errors, or one general error for an answer without them. */
export function problemsOf(answer) {
  const errors = answer.body && Array.isArray(answer.body.errors) ? answer.body.errors : [];
  if (errors.length > 0) return errors;
  const detail = (answer.body && (answer.body.detail || answer.body.title)) || `HTTP ${answer.status}`;
  return [{ field: 'request', message: detail }];
}

/** The sum of a response's Server-Timing durations, ms. */
export function serverTime(response) {
  return (response.headers.get('server-timing') || '').split(',')
    .map((entry) => Number((/dur=([\d.]+)/.exec(entry) || [])[1] || 0))
    .reduce((a, b) => a + b, 0);
}

/** Offers `blob` as a download named `name`. */
export function save(blob, name) {
  const url = URL.createObjectURL(blob);
  const link = document.createElement('a');
  link.href = url;
  link.download = name;
  document.body.append(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(url), 60000);
}

/** A file fetched from this origin (the samples), as a File named `name`. */
export async function fetchFile(path, name) {
  const response = await fetch(path);
  if (!response.ok) throw new Error(`${path} answered ${response.status}`);
  const blob = await response.blob();
  return new File([blob], name, { type: blob.type || 'application/octet-stream' });
}

// NumPy's NPZ as /depth-map writes it: a zip of stored (uncompressed) NPY files.
export function readNpz(buffer) {
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

/** An NPY image: float32 (`<f4`) or boolean (`|b1`, as the stream's `filled`); or the NPZ's
 * others: a string (`<U`, as `projection`) or a float64 list (`<f8`, as `latlon`). */
export function readNpy(buffer) {
  const headerLength = new DataView(buffer).getUint16(8, true);
  const header = new TextDecoder().decode(new Uint8Array(buffer, 10, headerLength));
  if (header.includes("'<U")) {
    const codes = new Uint32Array(buffer.slice(10 + headerLength));
    return String.fromCodePoint(...codes.filter((c) => c !== 0));
  }
  if (header.includes("'<f8'")) return Array.from(new Float64Array(buffer.slice(10 + headerLength)));
  const shape = /'shape': \((\d+), (\d+)\)/.exec(header);
  const float = header.includes("'<f4'");
  if (!(float || header.includes("'|b1'")) || !shape) throw new Error('an array that is not a float32 or boolean image');
  const data = float ? new Float32Array(buffer, 10 + headerLength) : new Uint8Array(buffer, 10 + headerLength);
  return { height: Number(shape[1]), width: Number(shape[2]), data };
}

/** base64url without padding, as a WebSocket protocol entry can hold it. */
function base64url(text) {
  const bytes = new TextEncoder().encode(text);
  let binary = '';
  for (const b of bytes) binary += String.fromCharCode(b);
  return btoa(binary).replace(/\+/g, '-').replace(/\//g, '_').replace(/=+$/, '');
}

/** Opens the WebSocket at `path` on this origin (wss on an HTTPS page), resolved once open.
 * A browser cannot send `Authorization` on a WebSocket, so the tab's token goes as a protocol
 * entry, `bearer.` and its base64url, beside `depth-stream`. A browser learns nothing of a
 * refused upgrade, so after a failure a plain GET asks why: a 401 brings the token dialog as
 * every request does (then the socket is tried again), and anything but 426 (the upgrade that
 * GET lacks) is the answer's problem, thrown. */
export async function openSocket(path) {
  const scheme = location.protocol === 'https:' ? 'wss' : 'ws';
  for (let attempt = 0; attempt < 3; attempt += 1) {
    const token = storedToken();
    const protocols = token ? ['depth-stream', `bearer.${base64url(token)}`] : ['depth-stream'];
    const socket = new WebSocket(`${scheme}://${location.host}${path}`, protocols);
    socket.binaryType = 'arraybuffer';
    const opened = await new Promise((resolve) => {
      socket.addEventListener('open', () => resolve(true), { once: true });
      socket.addEventListener('error', () => resolve(false), { once: true });
    });
    if (opened) return socket;
    const response = await fetchWithToken(path, { headers: { accept: 'application/json' } });
    if (response.status !== 426) {
      const type = response.headers.get('content-type') || '';
      const body = type.includes('json') ? await response.json() : null;
      throw new Error(problemsOf({ status: response.status, body })[0].message);
    }
  }
  throw new Error('the stream could not be opened');
}

/** A multipart POST that reports the upload's progress (`onUpload(fraction)`), as `post`
 * answers: `{ status, ok, blob, json, errors }`. Aborted through `signal` (AbortError). */
export async function postWithProgress(path, query, body, options = {}) {
  for (;;) {
    const had = storedToken();
    const answer = await sendWithProgress(path, query, body, options);
    if (answer.status !== 401 || !(await askForToken(had !== ''))) return answer;
  }
}

function sendWithProgress(path, query, body, { onUpload, signal } = {}) {
  return new Promise((resolve, reject) => {
    const request = new XMLHttpRequest();
    request.open('POST', `${path}?${query}`);
    const token = storedToken();
    if (token) request.setRequestHeader('authorization', `Bearer ${token}`);
    request.responseType = 'blob';
    request.upload.addEventListener('progress', (event) => {
      if (event.lengthComputable && onUpload) onUpload(event.loaded / event.total);
    });
    request.upload.addEventListener('load', () => onUpload && onUpload(1));
    request.addEventListener('error', () => reject(new Error('the service could not be reached')));
    request.addEventListener('abort', () => reject(new DOMException('cancelled', 'AbortError')));
    request.addEventListener('load', async () => {
      const blob = request.response;
      const type = request.getResponseHeader('content-type') || '';
      const json = type.includes('json') ? JSON.parse(await blob.text()) : null;
      const ok = request.status >= 200 && request.status < 300;
      resolve({ status: request.status, ok, blob, json, errors: ok ? null : problemsOf({ status: request.status, body: json }) });
    });
    if (signal) signal.addEventListener('abort', () => request.abort());
    request.send(body);
  });
}

/** A JSON file from this origin (a sample's description). */
export async function fetchJson(path) {
  const response = await fetch(path);
  if (!response.ok) throw new Error(`${path} answered ${response.status}`);
  return response.json();
}
