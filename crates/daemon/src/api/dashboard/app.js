// footscand dashboard: plain JavaScript against the daemon's HTTP API. No build step, no
// external URLs. GET /api/status is polled every 2 s; while a scan or a calibration runs the
// page also follows the event stream (progress, state) and polls the live laser image. An idle
// page holds no open connection, so idle dashboards cost the daemon nothing.
'use strict';

const TOKEN_KEY = 'footscand.token';
const PREVIEW_WIDTH = 480; // px asked of /api/preview.png (16..=1280)
const PREVIEW_PERIOD_MS = 200; // about 5 frames a second while a scan runs
const STATUS_PERIOD_MS = 2000;
const TERMINAL = new Set(['complete', 'complete with warnings', 'side mismatch', 'rescan', 'failed', 'cancelled']);
// The quality gate's verdicts (docs/method.md section 3.3) as the operator should read them.
const VERDICT = {
  'complete with warnings': 'complete with warnings',
  'side mismatch': 'side mismatch: confirm the side',
  rescan: 'failed: rescan before the patient leaves',
};
/** A state as a CSS class name ("complete with warnings" -> st-complete-with-warnings). */
function stClass(state) {
  return 'st-' + String(state).replace(/[^a-z]+/g, '-');
}

const $ = (id) => document.getElementById(id);

// ---------------------------------------------------------------- token and requests

/** The bearer token: from the URL fragment `#token=...` (then removed from the address bar so
 * it is not bookmarked or shared), else from sessionStorage. */
function readToken() {
  const m = location.hash.match(/(?:^#|&)token=([^&]*)/);
  if (m) {
    sessionStorage.setItem(TOKEN_KEY, decodeURIComponent(m[1]));
    history.replaceState(null, '', location.pathname + location.search);
  }
  return sessionStorage.getItem(TOKEN_KEY) || '';
}
let token = readToken();

/** A URL for places that cannot send headers (EventSource, img, download links). */
function withToken(path) {
  if (!token) return path;
  return path + (path.includes('?') ? '&' : '?') + 'access_token=' + encodeURIComponent(token);
}

function authHeaders(extra) {
  const h = Object.assign({}, extra || {});
  if (token) h.Authorization = 'Bearer ' + token;
  return h;
}

class ApiError extends Error {
  constructor(message, status) {
    super(message);
    this.status = status;
  }
}

/** Turn a failed response into an ApiError carrying the daemon's {"error": ...} text. */
async function responseError(method, path, r) {
  let detail = '';
  const text = await r.text().catch(() => '');
  try {
    const j = JSON.parse(text);
    detail = j && typeof j.error === 'string' ? j.error : text;
  } catch (_) {
    detail = text;
  }
  if (r.status === 401) {
    $('token-form').hidden = false;
  }
  let msg = `${method} ${path}: HTTP ${r.status} ${r.statusText}` + (detail ? ` — ${detail}` : '');
  if (r.status === 401) msg += ' (enter the token in the header, or open the page as /#token=...)';
  return new ApiError(msg, r.status);
}

async function request(method, path, body) {
  const opts = { method, headers: authHeaders(), cache: 'no-store' };
  // Every state-changing request says JSON (the daemon refuses others: a cross-site form
  // cannot send this header).
  if (method !== 'GET') opts.headers['Content-Type'] = 'application/json';
  if (body !== undefined) opts.body = JSON.stringify(body);
  let r;
  try {
    r = await fetch(path, opts);
  } catch (e) {
    throw new ApiError(`${method} ${path}: daemon not reachable (${e.message})`, 0);
  }
  if (!r.ok) throw await responseError(method, path, r);
  return r;
}

async function api(method, path, body) {
  const r = await request(method, path, body);
  return r.json();
}

// ---------------------------------------------------------------- errors

let errorKey = null;

function showError(err) {
  const text = err instanceof Error ? err.message : String(err);
  errorKey = text;
  $('error-text').textContent = text;
  $('error').hidden = false;
}

/** Clear the banner only if it still shows the error of this source (a later success of the
 * same request proves it is over; other errors stay until dismissed). */
function clearError(prefix) {
  if (errorKey !== null && errorKey.startsWith(prefix)) {
    $('error').hidden = true;
    errorKey = null;
  }
}

$('error-close').addEventListener('click', () => {
  $('error').hidden = true;
  errorKey = null;
});

// ---------------------------------------------------------------- small DOM helpers

function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === undefined || v === null || v === false) continue;
    if (k === 'text') e.textContent = v;
    else if (k === 'onclick') e.addEventListener('click', v);
    else e.setAttribute(k, v === true ? '' : String(v));
  }
  for (const c of children) {
    if (c === null || c === undefined) continue;
    e.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return e;
}

function badge(ok, yes, no) {
  return el('span', { class: 'badge ' + (ok ? 'ok' : 'bad'), text: ok ? yes : no });
}

function stateBadge(state) {
  return el('span', { class: 'badge ' + stClass(state), text: state });
}

function fmtInt(n) {
  return typeof n === 'number' ? n.toLocaleString('en-US') : '–';
}

function fmtTime(s) {
  if (!s) return '–';
  const d = new Date(s);
  if (isNaN(d.getTime())) return s;
  return d.toISOString().slice(0, 19).replace('T', ' ');
}

function fmtBytes(n) {
  if (typeof n !== 'number') return '';
  if (n < 1024) return n + ' B';
  if (n < 1024 * 1024) return (n / 1024).toFixed(1) + ' KiB';
  return (n / 1024 / 1024).toFixed(1) + ' MiB';
}

function fileUrl(id, name) {
  return withToken(`/api/scans/${encodeURIComponent(id)}/files/${encodeURIComponent(name)}`);
}

// ---------------------------------------------------------------- status

let current = null; // Progress of the running (or last) scan
let calibrating = null;
let resultId = null;

async function refreshStatus() {
  let s;
  try {
    s = await api('GET', '/api/status');
  } catch (e) {
    showError(e);
    return;
  }
  clearError('GET /api/status');
  $('version').textContent = 'v' + s.version;
  $('backend').textContent = 'backend: ' + s.backend;
  renderDevices(s.devices || {});
  renderCalibration(s.calibration, s.calibrating);
  renderFleet(s.fleet);
  renderRetention(s.archive && s.archive.retention);
  if (s.scan) onProgress(s.scan);
  else {
    $('st-scan').textContent = 'none';
    setRunning(false);
  }
}

function renderDevices(d) {
  const cam = d.camera;
  const camDd = $('st-camera');
  camDd.replaceChildren();
  if (cam) {
    camDd.append(
      badge(cam.connected, 'connected', 'disconnected'), ' ',
      `${cam.name} — ${cam.width}×${cam.height} ${cam.format}`,
    );
  } else camDd.textContent = 'unknown';
  const sl = d.slider;
  const slDd = $('st-slider');
  slDd.replaceChildren();
  if (sl) {
    const x = typeof sl.x_mm === 'number' ? `, x ${sl.x_mm.toFixed(2)} mm` : '';
    slDd.append(badge(sl.connected, 'connected', 'disconnected'), ' ', `${sl.name} — ${sl.state}${x}`);
  } else slDd.textContent = 'unknown';
}

/** The fleet line: backlog, last push, last error (shown only when [fleet] is on). */
function renderFleet(f) {
  const dd = $('st-fleet');
  $('st-fleet-dt').hidden = dd.hidden = !f;
  if (!f) return;
  dd.replaceChildren(
    badge(f.state !== 'retrying', f.state, f.state), ' ',
    el('span', { title: f.target }, `${f.scanner} (${f.clinic}): ${fmtInt(f.backlog)} waiting, ${fmtInt(f.pushed)} pushed`),
  );
  if (f.rejected) dd.append(`, ${fmtInt(f.rejected)} rejected`);
  if (f.last_push) dd.append(el('br'), `last push ${fmtTime(f.last_push)}`);
  if (f.last_error && (f.state === 'retrying' || f.rejected)) {
    dd.append(el('br'), `last error ${fmtTime(f.last_error_at)}: ${f.last_error}`);
  }
}

/** The archive's last retention run ([archive] keep_raw_days, keep_days, max_gb): what it
 * dropped, and the protected scans it kept against a rule (shown only once a run was made). */
function renderRetention(r) {
  const dd = $('st-retention');
  $('st-retention-dt').hidden = dd.hidden = !r;
  if (!r) return;
  const mb = (b) => (b / 1e6).toFixed(1) + ' MB';
  const freed = r.dropped.reduce((a, d) => a + d.bytes, 0);
  const whole = r.dropped.filter((d) => d.what === 'scan').length;
  const raw = r.dropped.length - whole;
  const problem = r.over_max_gb || (r.errors && r.errors.length > 0);
  dd.replaceChildren(
    badge(!problem, 'ok', r.over_max_gb ? 'over max_gb' : 'errors'), ' ',
    `${fmtTime(r.at)}: ${fmtInt(whole)} scans and the raw data of ${fmtInt(raw)} dropped (${mb(freed)}); ` +
      `${fmtInt(r.scans - whole)} scans, ${mb(r.bytes_after)}`,
  );
  if (r.kept_total) {
    const list = r.kept.slice(0, 20).map((k) => `${k.id} (${k.protected_by.join(', ')}; due by ${k.rule})`);
    dd.append(el('br'), el('span', { title: list.join('\n') }, `${fmtInt(r.kept_total)} protected scans kept against a rule`));
  }
  for (const e of (r.errors || []).slice(0, 3)) dd.append(el('br'), `error: ${e}`);
}

function renderCalibration(cal, calib) {
  const dd = $('st-calibration');
  dd.replaceChildren();
  if (cal) {
    dd.append(el('span', { title: cal.path || '' }, `${cal.method}, ${fmtTime(cal.date)}`));
  } else {
    dd.append('none loaded');
  }
  calibrating = calib && calib.state === 'running' ? calib : null;
  if (calib) {
    dd.append(el('br'), `${calib.kind === 'verify' ? 'daily check' : 'calibration'} ${calib.id}: `, stateBadge(calib.state));
    if (calib.reason) dd.append(' ', calib.reason);
  }
  updateButtons();
}

// ---------------------------------------------------------------- progress and state

function onProgress(p) {
  const prev = current;
  current = Object.assign({}, current && current.id === p.id ? current : {}, p);
  const running = current.state === 'running';
  const dd = $('st-scan');
  dd.replaceChildren(el('code', { text: current.id }), ' ', stateBadge(current.state));
  if (current.reason) dd.append(' ', current.reason);

  const bar = $('progress');
  const exp = current.expected_frames;
  if (typeof exp === 'number' && exp > 0) {
    bar.max = exp;
    bar.value = Math.min(current.frames || 0, exp);
  } else if (running) {
    bar.removeAttribute('value'); // indeterminate
  }
  if (current.state === 'complete') bar.value = bar.max;
  const pct = typeof exp === 'number' && exp > 0 ? ` ${Math.round(100 * Math.min(1, (current.frames || 0) / exp))} %` : '';
  $('progress-label').textContent = `Scan ${current.id}: ${current.state}${running ? pct : ''}`;
  const parts = [];
  // The plan is nominal (travel / step + 1): the camera may deliver a frame more or fewer.
  // Progress never reads past the plan; once the scan has ended the real count shows alone.
  if (typeof current.frames === 'number') {
    parts.push(running && typeof exp === 'number' && exp > 0
      ? `${fmtInt(Math.min(current.frames, exp))} / ${fmtInt(exp)} frames`
      : `${fmtInt(current.frames)} frames`);
  }
  if (typeof current.points === 'number') parts.push(`${fmtInt(current.points)} points`);
  if (typeof current.dropped === 'number') parts.push(`${fmtInt(current.dropped)} dropped`);
  if (typeof current.elapsed_s === 'number') parts.push(`${current.elapsed_s.toFixed(1)} s`);
  let detail = parts.join(', ');
  if (current.reason) detail += ` — ${current.reason}`;
  $('progress-detail').textContent = detail;
  bar.className = stClass(current.state);

  // The archive row of this scan counts along while it runs.
  const row = document.querySelector(`#scans tr[data-scan-id="${CSS.escape(current.id)}"]`);
  if (row && running) {
    row.querySelector('td.frames').textContent = fmtInt(current.frames);
    row.querySelector('td.points').textContent = fmtInt(current.points);
  }
  setRunning(running);
  const ended = !running && (!prev || prev.id !== current.id || prev.state === 'running');
  if (ended && TERMINAL.has(current.state)) onScanEnded(current.id);
}

let endedSeen = null;
function onScanEnded(id) {
  if (endedSeen === id) return;
  endedSeen = id;
  refreshScans();
  loadResult(id);
  drawPreviewOnce();
}

function onState(s) {
  onProgress(Object.assign({}, current && current.id === s.id ? current : { id: s.id }, s));
  if (s.state === 'running') refreshStatus();
}

function setRunning(running) {
  if (running) startPreview();
  else stopPreview();
  updateButtons();
}

function updateButtons() {
  const running = !!current && current.state === 'running';
  $('start').disabled = running || !!calibrating;
  $('cancel').disabled = !running;
  followEvents(running || !!calibrating);
}

// ---------------------------------------------------------------- start and cancel

const SUBJECT_RE = /^[A-Za-z0-9._-]{1,64}$/;

$('start-form').addEventListener('submit', async (ev) => {
  ev.preventDefault();
  const subject = $('subject').value.trim();
  const side = (document.querySelector('input[name=side]:checked') || {}).value;
  const notes = $('notes').value;
  if (!SUBJECT_RE.test(subject)) {
    $('subject').setAttribute('aria-invalid', 'true');
    showError(`Subject id "${subject}" is not valid: use 1 to 64 characters of A-Z a-z 0-9 . _ -`);
    $('subject').focus();
    return;
  }
  $('subject').removeAttribute('aria-invalid');
  $('start').disabled = true;
  try {
    const r = await api('POST', '/api/scans', { subject, side, notes });
    clearError('POST /api/scans');
    clearError('Subject id');
    onProgress({ id: r.id, state: 'running', frames: 0, expected_frames: null, points: 0, dropped: 0, elapsed_s: 0, reason: null });
    refreshStatus();
    refreshScans();
  } catch (e) {
    showError(e);
  } finally {
    updateButtons();
  }
});

$('cancel').addEventListener('click', async () => {
  if (!current) return;
  $('cancel').disabled = true;
  try {
    const r = await api('POST', `/api/scans/${encodeURIComponent(current.id)}/cancel`);
    $('progress-label').textContent = `Scan ${r.id}: ${r.state}…`;
  } catch (e) {
    showError(e);
    updateButtons();
  }
});

$('token-form').addEventListener('submit', (ev) => {
  ev.preventDefault();
  token = $('token-input').value.trim();
  sessionStorage.setItem(TOKEN_KEY, token);
  $('token-input').value = '';
  $('token-form').hidden = true;
  $('error').hidden = true;
  errorKey = null;
  if (es) connectEvents();
  refreshAll();
});

// ---------------------------------------------------------------- events

let es = null;
let eventsWanted = false;
let retryMs = 1000;

/** Open the stream while something runs, close it when idle (the status poll notices a scan
 * started by another client within STATUS_PERIOD_MS). */
function followEvents(want) {
  eventsWanted = want;
  if (want && !es) connectEvents();
  else if (!want && es) {
    es.close();
    es = null;
    setLink('idle', true);
  }
}

function setLink(text, ok) {
  const l = $('link');
  l.textContent = 'events: ' + text;
  l.className = 'pill ' + (ok ? 'ok' : 'bad');
}

function connectEvents() {
  if (es) es.close();
  es = null;
  if (!eventsWanted) return;
  es = new EventSource(withToken('/api/events'));
  es.addEventListener('open', () => {
    setLink('live', true);
    retryMs = 1000;
    refreshStatus(); // catch up on what happened while disconnected
  });
  es.addEventListener('progress', (e) => onProgress(JSON.parse(e.data)));
  es.addEventListener('state', (e) => onState(JSON.parse(e.data)));
  es.addEventListener('calibration', (e) => {
    const c = JSON.parse(e.data);
    refreshStatus();
    if (c.state === 'failed') showError(`calibration ${c.id} (${c.method}) failed: ${c.reason}`);
  });
  // 'error' is both the daemon's event (with data) and the stream's own failure (without).
  es.addEventListener('error', (e) => {
    if (typeof e.data === 'string') {
      let d;
      try {
        d = JSON.parse(e.data);
      } catch (_) {
        d = { id: '?', reason: e.data };
      }
      showError(`scan ${d.id}: ${d.reason}`);
      return;
    }
    setLink('reconnecting…', false);
    if (es && es.readyState === EventSource.CLOSED) {
      // The browser gave up (e.g. HTTP 401 or the daemon went away): retry with backoff.
      const delay = retryMs;
      retryMs = Math.min(retryMs * 2, 15000);
      setTimeout(connectEvents, delay);
    }
  });
}

// ---------------------------------------------------------------- live preview

let previewGen = 0;
let previewOn = false;

function startPreview() {
  if (previewOn) return;
  previewOn = true;
  const gen = ++previewGen;
  (async () => {
    while (previewOn && gen === previewGen) {
      const t0 = performance.now();
      await drawPreview();
      const wait = Math.max(20, PREVIEW_PERIOD_MS - (performance.now() - t0));
      await new Promise((res) => setTimeout(res, wait));
    }
  })();
}

function stopPreview() {
  previewOn = false;
}

async function drawPreviewOnce() {
  if (!previewOn) await drawPreview();
}

async function drawPreview() {
  try {
    const path = `/api/preview.png?width=${PREVIEW_WIDTH}`;
    let r;
    try {
      r = await fetch(path, { headers: authHeaders(), cache: 'no-store' });
    } catch (e) {
      throw new ApiError(`GET ${path}: daemon not reachable (${e.message})`, 0);
    }
    if (r.status === 404) {
      $('frame-info').textContent = 'No frame yet (no scan has run since the daemon started)';
      return;
    }
    if (!r.ok) throw await responseError('GET', path, r);
    const seq = r.headers.get('X-Frame-Seq');
    const age = r.headers.get('X-Frame-Age-Ms');
    const bmp = await createImageBitmap(await r.blob());
    let line = null;
    try {
      line = await api('GET', '/api/preview/line');
    } catch (e) {
      if (e.status !== 404) throw e;
    }
    const c = $('frame');
    if (c.width !== bmp.width || c.height !== bmp.height) {
      c.width = bmp.width;
      c.height = bmp.height;
    }
    const g = c.getContext('2d');
    g.drawImage(bmp, 0, 0);
    let detected = 0;
    if (line && Array.isArray(line.cols)) {
      detected = countRows(line);
      if ($('overlay').checked) drawLine(g, line, c.width, c.height);
      drawProfile(line);
    }
    const rows = line && line.cols ? line.cols.length : 0;
    const info = `frame ${seq ?? '?'}, ${age ?? '?'} ms old at response; line found on ${detected} of ${rows} rows`;
    $('frame-info').textContent = info;
    c.setAttribute('aria-label', `Latest camera frame with the detected laser line: ${info}`);
    clearError('GET /api/preview');
  } catch (e) {
    showError(e);
  }
}

function countRows(line) {
  return line.cols.filter((c) => c !== null && c !== undefined).length;
}

/** Overlay the detected column per row (full-resolution pixels) on the downscaled frame: thin
 * and translucent, so the laser light under it stays visible where detection disagrees. */
function drawLine(g, line, w, h) {
  const sx = w / line.width;
  const sy = h / line.height;
  g.strokeStyle = 'rgba(255, 45, 85, 0.75)';
  g.lineWidth = 1;
  g.beginPath();
  let pen = false;
  line.cols.forEach((col, row) => {
    if (col === null || col === undefined) {
      pen = false;
      return;
    }
    const x = col * sx;
    const y = (row + 0.5) * sy;
    if (pen) g.lineTo(x, y);
    else g.moveTo(x, y);
    pen = true;
  });
  g.stroke();
}

function niceStep(raw) {
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  for (const m of [1, 2, 2.5, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

/** Column against row: how far the line is displaced along the image, row by row. */
function drawProfile(line) {
  const c = $('profile');
  const g = c.getContext('2d');
  const W = c.width;
  const H = c.height;
  const m = { l: 48, r: 10, t: 10, b: 30 };
  g.clearRect(0, 0, W, H);
  g.fillStyle = '#ffffff';
  g.fillRect(0, 0, W, H);
  const pts = [];
  line.cols.forEach((col, row) => {
    if (col !== null && col !== undefined) pts.push([row, col]);
  });
  g.font = '11px system-ui, sans-serif';
  g.fillStyle = '#333';
  g.textAlign = 'left'; // the context keeps the last call's alignment
  if (pts.length === 0) {
    g.fillText('no line detected in this frame', m.l, H / 2);
    return;
  }
  let lo = Math.min(...pts.map((p) => p[1]));
  let hi = Math.max(...pts.map((p) => p[1]));
  if (hi - lo < 4) {
    lo -= 2;
    hi += 2;
  }
  const pad = 0.05 * (hi - lo);
  lo -= pad;
  hi += pad;
  const X = (row) => m.l + (row / line.height) * (W - m.l - m.r);
  const Y = (col) => m.t + (1 - (col - lo) / (hi - lo)) * (H - m.t - m.b);
  // Axes and ticks.
  g.strokeStyle = '#888';
  g.lineWidth = 1;
  g.beginPath();
  g.moveTo(m.l, m.t);
  g.lineTo(m.l, H - m.b);
  g.lineTo(W - m.r, H - m.b);
  g.stroke();
  g.textAlign = 'right';
  const ys = niceStep((hi - lo) / 4);
  for (let v = Math.ceil(lo / ys) * ys; v <= hi; v += ys) {
    g.fillText(String(Math.round(v)), m.l - 4, Y(v) + 4);
    g.strokeStyle = '#eee';
    g.beginPath();
    g.moveTo(m.l + 1, Y(v));
    g.lineTo(W - m.r, Y(v));
    g.stroke();
  }
  g.textAlign = 'center';
  const xs = niceStep(line.height / 5);
  for (let v = 0; v <= line.height; v += xs) g.fillText(String(v), X(v), H - m.b + 14);
  g.fillText('image row', (m.l + W - m.r) / 2, H - 3);
  g.save();
  g.translate(11, (m.t + H - m.b) / 2);
  g.rotate(-Math.PI / 2);
  g.fillText('column (px)', 0, 0);
  g.restore();
  // The profile.
  g.strokeStyle = '#0a5bd3';
  g.lineWidth = 1.5;
  g.beginPath();
  let prevRow = -2;
  for (const [row, col] of pts) {
    if (row === prevRow + 1) g.lineTo(X(row), Y(col));
    else g.moveTo(X(row), Y(col));
    prevRow = row;
  }
  g.stroke();
}

// ---------------------------------------------------------------- result of a scan

const MEASURES = [
  // key, label, unit, decimals
  ['foot_length_mm', 'Foot length', 'mm', 1],
  ['ball_width_mm', 'Ball width', 'mm', 1],
  ['midfoot_width_mm', 'Mid-foot width', 'mm', 1],
  ['heel_width_mm', 'Heel width', 'mm', 1],
  ['arch_height_mm', 'Arch height', 'mm', 1],
  ['arch_index', 'Arch index', '', 3],
  ['axis_angle_deg', 'Axis angle', '°', 1],
  ['contact_area_mm2', 'Contact area', 'mm²', 0],
  ['contact_thirds_mm2', 'Contact, thirds heel→toe', 'mm²', 0],
];
// Shown in the note under the table, not as rows.
const MEASURE_NOTES = new Set(['cell_mm']);

function fmtNum(v, d) {
  return v.toLocaleString('en-US', { minimumFractionDigits: d, maximumFractionDigits: d });
}

function measureRow(key, label, value, unit, d) {
  let text;
  if (Array.isArray(value)) text = value.map((v) => fmtNum(v, d)).join(' / ');
  else text = fmtNum(value, d);
  if (unit) text += ' ' + unit;
  return el('tr', {},
    el('th', { scope: 'row', text: label }),
    el('td', { class: 'num', 'data-key': key, 'data-value': JSON.stringify(value), text }));
}

async function loadResult(id) {
  let rec;
  try {
    rec = await api('GET', `/api/scans/${encodeURIComponent(id)}`);
  } catch (e) {
    showError(e);
    return;
  }
  resultId = id;
  const names = new Set((rec.artifacts || []).map((a) => a.name));
  $('result-id').textContent = `${rec.subject}, ${rec.side} foot, ${VERDICT[rec.status] || rec.status}`;
  $('result-id').className = stClass(rec.status);
  $('result').dataset.scanId = rec.id;
  $('result-empty').hidden = true;

  for (const [name, img, fig] of [['heightmap.png', 'heightmap', 'heightmap-fig'], ['plantar.png', 'plantar', 'plantar-fig'], ['deviation.png', 'deviation', 'deviation-fig']]) {
    if (names.has(name)) {
      $(img).src = fileUrl(rec.id, name);
      $(fig).hidden = false;
    } else {
      $(img).removeAttribute('src');
      $(fig).hidden = true;
    }
  }

  const tbody = $('measurements').querySelector('tbody');
  tbody.replaceChildren();
  const m = rec.measurements;
  const warn = $('result-warnings');
  warn.hidden = true;
  if (m && typeof m === 'object') {
    const known = new Set(MEASURE_NOTES);
    for (const [key, label, unit, d] of MEASURES) {
      known.add(key);
      const v = m[key];
      if (typeof v === 'number' || (Array.isArray(v) && v.every((x) => typeof x === 'number'))) {
        tbody.append(measureRow(key, label, v, unit, d));
      }
    }
    // Scalars added to measurements.json later still show, under their own key.
    for (const [key, v] of Object.entries(m)) {
      if (!known.has(key) && typeof v === 'number') tbody.append(measureRow(key, key, v, '', 3));
    }
    const note = [];
    if (m.side) note.push(`${m.side} foot`);
    if (typeof m.cell_mm === 'number') note.push(`footprint cells ${m.cell_mm} mm`);
    if (m.heights_from) note.push(`heights from the ${m.heights_from}`);
    $('measurements-note').textContent = note.join('; ');
    $('measurements').hidden = false;
    if (Array.isArray(m.warnings) && m.warnings.length) {
      warn.textContent = 'Warnings: ' + m.warnings.join('; ');
      warn.hidden = false;
    }
  } else {
    $('measurements').hidden = true;
    $('measurements-note').textContent = rec.status === 'complete' ? 'No measurements for this scan.' : '';
  }
  if (rec.reason) {
    warn.textContent = `Scan ${VERDICT[rec.status] || rec.status}: ${rec.reason}` + (warn.hidden ? '' : ' — ' + warn.textContent);
    warn.hidden = false;
  }

  renderSideConfirm(rec);

  const files = $('result-files');
  files.replaceChildren();
  for (const c of rec.history || []) {
    files.append(el('p', { class: 'small history', text: `Corrected ${fmtTime(c.at)}: ${c.field} ${c.from ?? '–'} → ${c.to ?? '–'} (${c.why})` }));
  }
  const s = rec.summary;
  if (s && typeof s === 'object') {
    const bits = [];
    if (typeof s.frames === 'number') bits.push(`${fmtInt(s.frames)} frames`);
    if (typeof s.dropped_frames === 'number') bits.push(`${fmtInt(s.dropped_frames)} dropped`);
    if (typeof s.points === 'number') bits.push(`${fmtInt(s.points)} points`);
    if (typeof s.seconds === 'number') bits.push(`${s.seconds.toFixed(1)} s`);
    if (bits.length) files.append(el('p', { class: 'small', text: 'Scan: ' + bits.join(', ') }));
  }
  if ((rec.artifacts || []).length) files.append(el('p', { class: 'small' }, 'Download: ', artifactLinks(rec)));
  if (names.has('measurements.json')) {
    files.append(el('p', { class: 'small' }, el('a', { id: 'report-link', href: withToken(`/api/scans/${encodeURIComponent(rec.id)}/report.pdf`), target: '_blank', text: 'Printable report (PDF, foot at 1:1)' })));
  }
  if (typeof renderLast === 'function') await renderLast(rec);
  if (typeof renderInsole === 'function') await renderInsole(rec);
}

/** A "side mismatch" scan: the operator confirms the side the scan shows or keeps theirs
 * (POST /api/scans/{id}/side); the record is corrected and the change kept in its history. */
function renderSideConfirm(rec) {
  let box = $('side-confirm');
  if (!box) {
    box = el('div', { id: 'side-confirm', class: 'warn', role: 'group', 'aria-label': 'Confirm the side' });
    $('result-warnings').after(box);
  }
  box.replaceChildren();
  box.hidden = rec.status !== 'side mismatch';
  if (box.hidden) return;
  const side = rec.summary && rec.summary.quality && rec.summary.quality.side;
  const seen = side && side.detected;
  const choose = async (value) => {
    try {
      await api('POST', `/api/scans/${encodeURIComponent(rec.id)}/side`, { side: value });
      clearError('POST /api/scans');
      await loadResult(rec.id);
      await refreshScans();
    } catch (e) {
      showError(e);
    }
  };
  box.append(el('p', { text: `Saved as the ${rec.side} foot, but the scan looks like the ${seen || 'other'} foot. Look at the foot, then:` }));
  if (seen === 'left' || seen === 'right') {
    box.append(el('button', { type: 'button', id: 'confirm-scan-side', onclick: () => choose(seen) }, `It is the ${seen} foot`));
    box.append(' ');
  }
  box.append(el('button', { type: 'button', id: 'keep-chosen-side', onclick: () => choose(rec.side) }, `Keep ${rec.side}`));
}

function artifactLinks(rec) {
  const span = el('span', { class: 'files' });
  (rec.artifacts || []).forEach((a, i) => {
    if (i) span.append(' · ');
    span.append(el('a', { href: fileUrl(rec.id, a.name), download: a.name, title: `${a.content_type}, ${fmtBytes(a.bytes)}`, text: a.name }));
  });
  return span;
}

// ---------------------------------------------------------------- archive

// The table pages (GET /api/scans?limit=&before=, docs/API.md): the newest SCAN_PAGE scans
// matching the search, then "Older scans" appends the next page by its cursor, so the page
// never loads the whole archive.
const SCAN_PAGE = 50;
let scansNext = null; // the cursor of the next page, null on the last one

function scanQuery(before) {
  const q = new URLSearchParams({ limit: String(SCAN_PAGE) });
  const subject = $('scan-subject').value.trim();
  if (subject) q.set('subject', subject);
  if ($('scan-status').value) q.set('status', $('scan-status').value);
  if ($('scan-side').value) q.set('side', $('scan-side').value);
  if (before) q.set('before', before);
  return '/api/scans?' + q;
}

function scanRow(r) {
  const details = el('details', {}, el('summary', { text: 'files' }));
  details.addEventListener('toggle', async () => {
    if (!details.open || details.dataset.loaded) return;
    try {
      const rec = await api('GET', `/api/scans/${encodeURIComponent(r.id)}`);
      details.dataset.loaded = '1';
      details.append(rec.artifacts && rec.artifacts.length ? artifactLinks(rec) : el('span', { text: 'none' }));
    } catch (e) {
      showError(e);
    }
  });
  return el('tr', { 'data-scan-id': r.id, 'data-status': r.status },
    el('td', { text: fmtTime(r.started) }),
    el('td', { text: r.subject }),
    el('td', { text: r.side }),
    el('td', {}, stateBadge(r.status)),
    el('td', { class: 'reason', text: r.reason || '' }),
    el('td', { class: 'num frames', text: fmtInt(r.frames) }),
    el('td', { class: 'num points', text: fmtInt(r.points) }),
    el('td', {}, el('button', {
      type: 'button', class: 'link-btn', title: 'Show this scan in Result',
      'aria-label': `Show scan ${r.id}`, onclick: () => loadResult(r.id),
    }, el('code', { text: r.id }))),
    el('td', {}, details));
}

function scansShowMore() {
  const n = $('scans').querySelectorAll('tbody tr[data-scan-id]').length;
  $('scans-more').hidden = !scansNext;
  $('scans-caption').textContent = n ? `${n} scan${n === 1 ? '' : 's'} shown, newest first${scansNext ? '; older ones follow' : ''}` : '';
}

async function refreshScans() {
  let page;
  try {
    page = await api('GET', scanQuery(null));
  } catch (e) {
    showError(e);
    return;
  }
  clearError('GET /api/scans');
  const list = page.items;
  scansNext = page.next;
  const tbody = $('scans').querySelector('tbody');
  tbody.replaceChildren();
  const searched = $('scan-subject').value.trim() || $('scan-status').value || $('scan-side').value;
  if (!list.length) {
    tbody.append(el('tr', {}, el('td', { colspan: 9, text: searched ? 'No scan found.' : 'No scans archived yet.' })));
  }
  for (const r of list) tbody.append(scanRow(r));
  scansShowMore();
  // When the first view's archive table is drawn (the archive bench reads it).
  performance.mark('scans-shown');
  // No scan known to the daemon since it started: show the newest finished one.
  if (resultId === null && current === null && !searched) {
    const done = list.find((r) => r.status === 'complete') || list.find((r) => TERMINAL.has(r.status));
    if (done) loadResult(done.id);
  }
}

async function olderScans() {
  if (!scansNext) return;
  let page;
  try {
    page = await api('GET', scanQuery(scansNext));
  } catch (e) {
    showError(e);
    return;
  }
  clearError('GET /api/scans');
  scansNext = page.next;
  const tbody = $('scans').querySelector('tbody');
  for (const r of page.items) tbody.append(scanRow(r));
  scansShowMore();
}

// ---------------------------------------------------------------- start

async function refreshAll() {
  await refreshStatus();
  await refreshScans();
  drawPreviewOnce();
}

$('refresh').addEventListener('click', refreshScans);
$('scans-more').addEventListener('click', olderScans);
$('scan-search').addEventListener('submit', (ev) => {
  ev.preventDefault();
  refreshScans();
});
$('overlay').addEventListener('change', drawPreviewOnce);
setLink('idle', true);
refreshAll();
setInterval(refreshStatus, STATUS_PERIOD_MS);
