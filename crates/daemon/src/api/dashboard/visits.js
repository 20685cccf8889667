// The visits card: a patient's stay with both feet (docs/API.md "Visits"). Lists the visits,
// newest first, searched by patient and by the clinic's local date; a visit opened shows its
// patient, its time in the clinic's time zone (as the daemon says it: started_local,
// time_zone), its notes (editable, POST /api/visits/{id}/notes), each foot's scan with its
// verdict and links (the scan in Result, its report PDF), the visit's report, and deletes the
// visit with its scans after an explicit confirmation. Uses app.js's helpers (api, el, $,
// stateBadge, VERDICT, stClass, withToken, fileUrl, loadResult, refreshScans, showError,
// clearError, TERMINAL).
'use strict';

let visitOpen = null; // the visit shown, as GET /api/visits/{id} answered

/** "2026-11-25T10:03:00+01:00" -> "2026-11-25 10:03 (+01:00)". */
function visitFmtLocal(s) {
  if (typeof s !== 'string' || s.length < 19) return s || '–';
  return `${s.slice(0, 10)} ${s.slice(11, 16)}` + (s.length > 19 ? ` (${s.slice(19)})` : '');
}

// The list pages as the archive's does (GET /api/visits?limit=&before=): the newest
// VISIT_PAGE visits matching the search, "Older visits" appends the next page.
const VISIT_PAGE = 50;
let visitsNext = null;

function visitQuery(before) {
  const subject = $('visit-subject').value.trim();
  const date = $('visit-date').value;
  const q = new URLSearchParams({ limit: String(VISIT_PAGE) });
  if (subject) q.set('subject', subject);
  if (date) q.set('date', date);
  if (before) q.set('before', before);
  return { path: '/api/visits?' + q, subject, date };
}

function visitRow(v) {
  const open = el('button', {
    type: 'button', class: 'link-btn', 'aria-label': `Open the visit of ${v.patient}, ${visitFmtLocal(v.started_local)}`,
    onclick: () => visitOpenId(v.id),
  }, visitFmtLocal(v.started_local));
  const tr = el('tr', { 'data-visit-id': v.id },
    el('td', {}, open),
    el('td', { text: v.patient }),
    el('td', { class: 'foot-cell', text: v.left ? 'scanned' : '–' }),
    el('td', { class: 'foot-cell', text: v.right ? 'scanned' : '–' }),
    el('td', { class: 'visit-notes-cell', text: v.notes || '' }));
  if (visitOpen && visitOpen.id === v.id) tr.className = 'selected';
  return tr;
}

function visitCaption(what) {
  const n = $('visit-list').querySelectorAll('tbody tr[data-visit-id]').length;
  $('visit-list-caption').textContent = `${n} visit${n === 1 ? '' : 's'}` + (what ? ` (${what})` : '') + ', newest first' +
    (visitsNext ? '; older ones follow' : '');
  $('visits-more').hidden = !visitsNext;
}

function visitWhat(subject, date) {
  return [subject && `patient containing "${subject}"`, date && `on ${date}`].filter(Boolean).join(', ');
}

async function visitRefreshList() {
  const { path, subject, date } = visitQuery(null);
  let page;
  try {
    page = await api('GET', path);
  } catch (e) {
    showError(e);
    return;
  }
  clearError('GET /api/visits');
  const list = page.items;
  visitsNext = page.next;
  const tbody = $('visit-list').querySelector('tbody');
  tbody.replaceChildren();
  const what = visitWhat(subject, date);
  if (list.length) $('visits-zone').textContent = `times in ${list[0].time_zone}`;
  if (!list.length) {
    tbody.append(el('tr', {}, el('td', { colspan: 5, text: what ? 'No visit found.' : 'No visits yet.' })));
  }
  for (const v of list) tbody.append(visitRow(v));
  visitCaption(what);
  performance.mark('visits-shown');
}

async function visitOlder() {
  if (!visitsNext) return;
  const { path, subject, date } = visitQuery(visitsNext);
  let page;
  try {
    page = await api('GET', path);
  } catch (e) {
    showError(e);
    return;
  }
  clearError('GET /api/visits');
  visitsNext = page.next;
  const tbody = $('visit-list').querySelector('tbody');
  for (const v of page.items) tbody.append(visitRow(v));
  visitCaption(visitWhat(subject, date));
}

async function visitOpenId(id) {
  let v;
  try {
    v = await api('GET', `/api/visits/${encodeURIComponent(id)}`);
  } catch (e) {
    showError(e);
    return;
  }
  visitOpen = v;
  $('visit-detail').hidden = false;
  $('visit-detail').dataset.visitId = v.id;
  $('visit-delete-confirm').hidden = true;
  $('visit-delete').disabled = false;
  for (const tr of $('visit-list').querySelectorAll('tbody tr')) {
    tr.className = tr.dataset.visitId === v.id ? 'selected' : '';
  }
  $('visit-title').replaceChildren(`Visit of ${v.patient} `, el('code', { class: 'muted', text: v.id }));
  $('visit-when').textContent = `Started ${visitFmtLocal(v.started_local)}, ${v.time_zone}`;
  $('visits-zone').textContent = `times in ${v.time_zone}`;
  $('visit-notes').value = v.notes || '';
  $('visit-notes-state').textContent = '';
  const [ml, mr] = await Promise.all([visitRenderFoot(v, 'left'), visitRenderFoot(v, 'right')]);
  visitCompare(ml, mr);
  const report = $('visit-report');
  report.replaceChildren();
  if (v.left && v.right) {
    report.append(el('a', {
      id: 'visit-report-link', href: withToken(`/api/visits/${encodeURIComponent(v.id)}/report.pdf`), target: '_blank',
      text: 'Visit report (PDF: both feet at 1:1, the comparison)',
    }));
  } else {
    report.textContent = 'The visit report needs both feet.';
  }
  await visitFillAdd(v);
}

/** The rows of the visit report's table (scanner report.rs render_visit): label, the
 * value of one foot's measurements, decimals. */
const VISIT_ROWS = [
  ['Foot length (mm)', (m) => m.foot_length_mm, 1],
  ['Ball width MT1–MT5 (mm)', (m) => (Array.isArray(m.mt1_head) && Array.isArray(m.mt5_head)
    ? Math.hypot(m.mt1_head[0] - m.mt5_head[0], m.mt1_head[1] - m.mt5_head[1]) : undefined), 1],
  ['Ball width, across axis (mm)', (m) => m.ball_width_mm, 1],
  ['Mid-foot width (mm)', (m) => m.midfoot_width_mm, 1],
  ['Heel width (mm)', (m) => m.heel_width_mm, 1],
  ['Arch height (mm)', (m) => m.arch_height_mm, 1],
  ['Arch index', (m) => m.arch_index, 3],
  ['Axis angle (°)', (m) => m.axis_angle_deg, 1],
];

/** A difference with its sign, "0.0" when it rounds to nothing (not "-0.0"). */
function visitSigned(x, d) {
  if (typeof x !== 'number' || !Number.isFinite(x)) return '–';
  const t = x.toFixed(d);
  if (Number(t) === 0) return (0).toFixed(d);
  return (x > 0 ? '+' : '') + t;
}

/** Both feet's figures and right minus left, as the visit report has them. */
function visitCompare(ml, mr) {
  const box = $('visit-compare');
  box.replaceChildren();
  if (!ml || !mr) {
    box.append(el('p', { class: 'small', text: 'The comparison needs both feet measured.' }));
    return;
  }
  const fmt = (x, d) => (typeof x === 'number' && Number.isFinite(x) ? x.toFixed(d) : '–');
  const t = el('table', { class: 'data', id: 'visit-compare-table' },
    el('caption', { text: 'Both feet (measurements.json) and right minus left' }),
    el('thead', {}, el('tr', {},
      el('th', { scope: 'col', text: 'Measure' }), el('th', { scope: 'col', class: 'num', text: 'Left' }),
      el('th', { scope: 'col', class: 'num', text: 'Right' }), el('th', { scope: 'col', class: 'num', text: 'R − L' }))));
  const body = el('tbody');
  for (const [label, get, d] of VISIT_ROWS) {
    const [l, r] = [get(ml), get(mr)];
    const diff = typeof l === 'number' && typeof r === 'number' ? r - l : undefined;
    body.append(el('tr', {},
      el('th', { scope: 'row', text: label }), el('td', { class: 'num', text: fmt(l, d) }),
      el('td', { class: 'num', text: fmt(r, d) }),
      el('td', { class: 'num diff', text: visitSigned(diff, d) })));
  }
  t.append(body);
  box.append(t);
}

/** One foot of the open visit: its scan's verdict, figures, plantar view, 3D view (view.js
 * draws a canvas.visit-viewer) and links; its measurements, or null. */
async function visitRenderFoot(v, side) {
  const box = $(`visit-foot-${side}`);
  const title = side === 'left' ? 'Left foot' : 'Right foot';
  box.replaceChildren(el('h4', { text: title }));
  const rec = v[`${side}_scan`];
  if (!v[side]) {
    box.append(el('p', { class: 'small', text: 'No scan yet.' }));
    return;
  }
  if (!rec) {
    box.append(el('p', { class: 'warn', text: `Scan ${v[side]} is no longer in the archive.` }));
    return;
  }
  box.dataset.scanId = rec.id;
  box.dataset.status = rec.status;
  const verdict = el('span', { class: 'badge verdict ' + stClass(rec.status), text: VERDICT[rec.status] || rec.status });
  box.append(el('p', {}, verdict));
  if (rec.reason) box.append(el('p', { class: 'small reason', text: rec.reason }));
  // The figures and the plantar view (the scan as it is now).
  let full = null;
  try {
    full = await api('GET', `/api/scans/${encodeURIComponent(rec.id)}`);
  } catch (e) {
    showError(e);
  }
  const m = full && full.measurements;
  if (m && typeof m.foot_length_mm === 'number') {
    const bits = [`length ${m.foot_length_mm.toFixed(1)} mm`];
    if (typeof m.ball_width_mm === 'number') bits.push(`ball width ${m.ball_width_mm.toFixed(1)} mm`);
    box.append(el('p', { class: 'small figures', text: bits.join(', ') }));
  }
  const names = new Set(((full && full.artifacts) || []).map((a) => a.name));
  if (names.has('plantar.png')) {
    box.append(el('img', { src: fileUrl(rec.id, 'plantar.png'), alt: `${title}: plantar view with landmarks`, class: 'visit-plantar' }));
  }
  if (names.has('model.glb')) {
    box.append(el('canvas', {
      class: 'visit-viewer', id: `visit-viewer-${side}`, width: 400, height: 300, 'data-scan-id': rec.id,
      role: 'img', 'aria-label': `${title} in 3D: drag to turn, wheel or pinch to zoom`,
    }));
  }
  const links = el('p', { class: 'small links' });
  links.append(el('a', {
    href: '#result', class: 'scan-link', text: `Scan ${rec.id}`,
    onclick: (ev) => {
      ev.preventDefault();
      loadResult(rec.id);
      $('result').scrollIntoView();
    },
  }));
  if (names.has('measurements.json')) {
    links.append(' · ', el('a', {
      class: 'report-link', href: withToken(`/api/scans/${encodeURIComponent(rec.id)}/report.pdf`), target: '_blank', text: 'Report (PDF)',
    }));
  }
  box.append(links);
  return m && typeof m.foot_length_mm === 'number' ? m : null;
}

/** The patient's ended scans not yet in the visit, for "Add a scan". */
async function visitFillAdd(v) {
  const sel = $('visit-add-scan');
  sel.replaceChildren();
  let scans = [];
  try {
    // The patient's scans only (subject is a prefix search: the exact ones are kept below).
    const q = new URLSearchParams({ subject: v.patient, limit: '500' });
    scans = (await api('GET', '/api/scans?' + q)).items;
  } catch (e) {
    showError(e);
  }
  const mine = scans.filter((s) => s.subject === v.patient && TERMINAL.has(s.status) && s.id !== v.left && s.id !== v.right);
  for (const s of mine) {
    sel.append(el('option', { value: s.id, text: `${s.side}, ${s.status}, ${s.id}` }));
  }
  $('visit-add').hidden = !mine.length;
}

async function visitSaveNotes() {
  if (!visitOpen) return;
  const notes = $('visit-notes').value;
  const state = $('visit-notes-state');
  $('visit-notes-save').disabled = true;
  state.textContent = 'Saving…';
  try {
    const v = await api('POST', `/api/visits/${encodeURIComponent(visitOpen.id)}/notes`, { notes });
    visitOpen.notes = v.notes;
    state.textContent = 'Saved.';
    clearError('POST /api/visits');
    await visitRefreshList();
  } catch (e) {
    state.textContent = 'Not saved.';
    showError(e);
  } finally {
    $('visit-notes-save').disabled = false;
  }
}

function visitAskDelete() {
  if (!visitOpen) return;
  const n = [visitOpen.left, visitOpen.right].filter(Boolean).length;
  $('visit-delete-question').textContent =
    `Delete the visit of ${visitOpen.patient} (${visitFmtLocal(visitOpen.started_local)}) ` +
    (n ? `with its ${n} scan${n === 1 ? '' : 's'} (their files and archive entries)` : '') +
    '? This cannot be undone; it is logged.';
  $('visit-delete-confirm').hidden = false;
  $('visit-delete').disabled = true;
  $('visit-delete-no').focus();
}

async function visitDelete() {
  if (!visitOpen) return;
  const id = visitOpen.id;
  try {
    await api('DELETE', `/api/visits/${encodeURIComponent(id)}`);
  } catch (e) {
    showError(e);
    return;
  }
  visitOpen = null;
  $('visit-detail').hidden = true;
  $('visit-delete-confirm').hidden = true;
  await visitRefreshList();
  await refreshScans();
}

$('visits-more').addEventListener('click', visitOlder);
$('visit-search').addEventListener('submit', (ev) => {
  ev.preventDefault();
  visitRefreshList();
});
$('visit-search-clear').addEventListener('click', () => {
  $('visit-subject').value = '';
  $('visit-date').value = '';
  visitRefreshList();
});
$('visit-new').addEventListener('submit', async (ev) => {
  ev.preventDefault();
  const input = $('visit-new-patient');
  const patient = input.value.trim();
  const ok = /^[A-Za-z0-9._-]{1,64}$/.test(patient);
  input.setAttribute('aria-invalid', ok ? 'false' : 'true');
  if (!ok) {
    showError(`New visit: patient id ${JSON.stringify(patient)} must be 1–64 of A–Z a–z 0–9 . _ -`);
    return;
  }
  try {
    const v = await api('POST', '/api/visits', { patient });
    input.value = '';
    await visitRefreshList();
    await visitOpenId(v.id);
  } catch (e) {
    showError(e);
  }
});
$('visit-add').addEventListener('submit', async (ev) => {
  ev.preventDefault();
  const scan = $('visit-add-scan').value;
  if (!visitOpen || !scan) return;
  try {
    await api('POST', `/api/visits/${encodeURIComponent(visitOpen.id)}/scans`, { scan });
    await visitOpenId(visitOpen.id);
    await visitRefreshList();
  } catch (e) {
    showError(e);
  }
});
$('visit-notes-save').addEventListener('click', visitSaveNotes);
$('visit-delete').addEventListener('click', visitAskDelete);
$('visit-delete-no').addEventListener('click', () => {
  $('visit-delete-confirm').hidden = true;
  $('visit-delete').disabled = false;
});
$('visit-delete-yes').addEventListener('click', visitDelete);
visitRefreshList();
