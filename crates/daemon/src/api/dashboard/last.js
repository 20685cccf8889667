// The customized last of the scan shown in Result (docs/API.md "Lasts"): the girths a fitter
// measured with a tape, a stock last of the shop's collection and what the last is for
// (shoe, wearer, heel) rank the collection for this foot (POST /api/scans/{id}/last/rank) and
// start the job (POST /api/scans/{id}/last); while it runs its record is
// polled; then every comfort rule (foot, target, the last as cut, met) and the last's files
// (STL, IGES, STEP, the curve frame, the report, the picture) are shown, or the reason it
// failed. Uses app.js's helpers (api, el, $, withToken, showError, clearError).
'use strict';

const LAST_POLL_MS = 500;
let lastPoll = null; // the timer polling a running job
let lastScan = null; // the scan the card shows
let lastJob = null; // the job record shown (marks a ranked last that could not be made)
let lastRanked = null; // the request the ranking shown was made for

function lastFileUrl(id, name) {
  return withToken(`/api/scans/${encodeURIComponent(id)}/last/${encodeURIComponent(name)}`);
}

/** Show the card for scan `rec` (Result calls this on every scan it loads). */
async function renderLast(rec) {
  const box = $('last');
  if (lastPoll) clearTimeout(lastPoll);
  lastPoll = null;
  if (lastScan !== rec.id) {
    $('last-ranking').replaceChildren();
    lastRanked = null;
  }
  lastScan = rec.id;
  const measured = (rec.artifacts || []).some((a) => a.name === 'measurements.json');
  box.hidden = !measured || rec.status === 'running';
  if (box.hidden) return;
  const sel = $('last-stock');
  try {
    const { lasts } = await api('GET', '/api/lasts');
    const had = sel.value;
    sel.replaceChildren(...lasts.map((l) => el('option', { value: l.name, text: l.name })));
    if (lasts.some((l) => l.name === had)) sel.value = had;
    $('last-nostock').hidden = lasts.length > 0;
    $('last-nostock').textContent = lasts.length ? '' : 'The stock collection is empty.';
    $('last-form').hidden = lasts.length === 0;
  } catch (e) {
    // 501: no [lasts] stock_dir in the daemon config: say so instead of a form.
    $('last-nostock').textContent = e.message;
    $('last-nostock').hidden = false;
    $('last-form').hidden = true;
  }
  await lastShowJob(rec.id);
}

async function lastShowJob(id) {
  if (id !== lastScan) return;
  const out = $('last-job');
  let job = null;
  try {
    job = await api('GET', `/api/scans/${encodeURIComponent(id)}/last`);
  } catch (e) {
    if (e.status !== 404) showError(e);
  }
  out.replaceChildren();
  lastJob = job;
  lastMarkFailed();
  $('last-make').disabled = job !== null && job.state === 'running';
  if (!job) {
    out.append(el('p', { class: 'small', text: 'No last made for this scan yet.' }));
    return;
  }
  const when = job.finished ? `, ${job.seconds.toFixed(2)} s` : '';
  const r = job.request;
  out.append(el('p', { id: 'last-state', class: 'small', 'data-state': job.state,
    text: `Last ${job.state}${when}: stock ${r.stock}, ${r.shoe} for a ${r.wearer}, heel ${r.heel_mm == null ? "the last's own" : r.heel_mm + ' mm'}` }));
  if (job.state === 'running') {
    lastPoll = setTimeout(() => lastShowJob(id), LAST_POLL_MS);
    return;
  }
  if (job.state === 'failed') {
    out.append(el('p', { class: 'warn', id: 'last-reason', text: job.reason || 'failed' }));
  }
  if (job.rules && job.rules.length) {
    const t = el('table', { class: 'data', id: 'last-rules' },
      el('caption', { text: 'Comfort rules (the last measured by cutting its mesh)' }),
      el('thead', {}, el('tr', {}, ...['Rule', 'Quantity', 'Foot', 'Target', 'Last', 'Met'].map((h) => el('th', { scope: 'col', text: h })))));
    const tb = el('tbody');
    for (const x of job.rules) {
      tb.append(el('tr', {},
        el('td', { text: x.rule }), el('td', { text: x.quantity.replace(/_/g, ' ') }),
        el('td', { class: 'num', text: x.foot_mm.toFixed(1) }), el('td', { class: 'num', text: x.target_mm.toFixed(1) }),
        el('td', { class: 'num', text: x.last_mm.toFixed(1) }),
        x.not_applicable
          ? el('td', { text: 'n/a', title: x.not_applicable })
          : el('td', {
            class: x.met ? 'ok' : 'bad',
            text: !x.met ? `no (${x.error_mm.toFixed(2)})`
              : x.built_up_mm ? `yes; built up ${x.built_up_mm > 0 ? '+' : ''}${x.built_up_mm.toFixed(1)} for the footprint` : 'yes',
          })));
    }
    t.append(tb);
    out.append(t);
  }
  if (job.clearance) {
    out.append(el('p', { class: 'small', text: `Clearance (mm), ${job.clearance}` }));
  }
  if (job.state === 'done' && job.files.length) {
    const span = el('span', { class: 'files', id: 'last-files' });
    job.files.forEach((n, i) => {
      if (i) span.append(' · ');
      span.append(el('a', { href: lastFileUrl(id, n), download: n, text: n }));
    });
    out.append(el('p', { class: 'small' }, 'Last files: ', span));
    if (job.files.includes('customize.png')) {
      // The job's end time in the URL: a new last's picture is not taken from the cache.
      const png = lastFileUrl(id, 'customize.png');
      const src = png + (png.includes('?') ? '&' : '?') + 't=' + encodeURIComponent(job.finished || '');
      out.append(el('img', { id: 'last-picture', alt: 'Side and top views of the stock and the customized last', src }));
    }
  }
}

/** Whether a job's request asked what the ranking was made for (same girths and purpose). */
function lastSameAsk(req, ranked) {
  const g = (x) => JSON.stringify([x.girths.ball, x.girths.instep, x.girths.long_heel, x.girths.ankle]);
  return g(req) === g(ranked) && req.shoe === ranked.shoe && req.wearer === ranked.wearer
    && (req.heel_mm ?? null) === (ranked.heel_mm ?? null);
}

// The ranking is a forecast from the stock's stations; the solve can still fail on a last it
// put first. When the job shown failed on a ranked last for the same request, that row says
// so, cannot be picked, and the form moves to the next last that can.
function lastMarkFailed() {
  const t = $('last-ranking-table');
  const job = lastJob;
  if (!t || !job || job.state !== 'failed' || !lastRanked || !lastSameAsk(job.request, lastRanked)) return;
  const row = [...t.querySelectorAll('tbody tr')].find((r) => r.dataset.name === job.request.stock);
  if (!row || row.dataset.failed) return;
  row.dataset.failed = 'true';
  row.classList.add('muted');
  const notes = row.cells[5];
  notes.className = 'bad';
  // The reason is long (every rule missed, and what would make it possible) and is shown in
  // full under the form: the row says which and points there, the whole text on hover.
  notes.title = job.reason || 'failed';
  notes.textContent = 'could not be made for this foot: the reason is below the form' + (notes.textContent ? `; ${notes.textContent}` : '');
  row.querySelector('button').disabled = true;
  const next = [...t.querySelectorAll('tbody tr')].find((r) => !r.dataset.failed && !r.querySelector('button').disabled);
  const say = next
    ? `${job.request.stock} could not be made; the next last, ${next.dataset.name}, is picked.`
    : `${job.request.stock} could not be made, and no other last in the collection can be: see the notes.`;
  if (next && $('last-stock').value === job.request.stock) $('last-stock').value = next.dataset.name;
  $('last-ranking').append(el('p', { class: 'warn', id: 'last-ranking-next', text: say }));
}

/** The form's girths and what the last is for (the body of both POSTs). */
function lastBody() {
  const num = (k) => Number($(`last-${k}`).value);
  return {
    girths: { ball: num('ball'), instep: num('instep'), long_heel: num('long-heel'), ankle: num('ankle') },
    shoe: $('last-shoe').value,
    wearer: $('last-wearer').value,
    // Empty: the stock last's own heel (null in the request).
    heel_mm: $('last-heel').value === '' ? null : num('heel'),
  };
}

// Rank the collection for this scan and these girths (POST .../last/rank): best first, by
// the largest change any rule asks of the last; a row's button picks that last in the form.
$('last-rank').addEventListener('click', async () => {
  const id = lastScan;
  const out = $('last-ranking');
  if (!id || !$('last-form').reportValidity()) return;
  $('last-rank').disabled = true;
  out.replaceChildren(el('p', { class: 'small', text: 'Ranking the stock lasts…' }));
  try {
    const ask = lastBody();
    const r = await api('POST', `/api/scans/${encodeURIComponent(id)}/last/rank`, ask);
    clearError('POST /api/scans');
    const t = el('table', { class: 'data', id: 'last-ranking-table' },
      el('caption', { text: `Stock lasts for this foot, least change first (${r.lasts.length} in ${r.seconds.toFixed(2)} s)` }),
      el('thead', {}, el('tr', {}, ...['#', 'Last', 'Largest change (mm)', 'At', 'Outline (mm)', 'Notes', ''].map((h) => el('th', { scope: 'col', text: h })))));
    const tb = el('tbody');
    r.lasts.forEach((c, i) => {
      const fin = (v) => (Number.isFinite(v) ? v.toFixed(1) : '-');
      const notes = [...c.cannot, ...c.notes].join('; ');
      const pick = el('button', { type: 'button', text: 'Use', class: 'small' });
      pick.disabled = !c.eligible;
      pick.addEventListener('click', () => { $('last-stock').value = c.name; });
      tb.append(el('tr', { class: c.eligible ? '' : 'muted', 'data-name': c.name },
        el('td', { class: 'num', text: String(i + 1) }), el('td', { text: c.name }),
        el('td', { class: 'num', text: fin(c.largest_change_mm) }), el('td', { text: (c.largest_at || '').replace(/_/g, ' ') }),
        el('td', { class: 'num', text: fin(c.outline_change_mm) }), el('td', { class: c.cannot.length ? 'bad' : 'small', text: notes }),
        el('td', {}, pick)));
    });
    t.append(tb);
    out.replaceChildren(t);
    const best = r.lasts.find((c) => c.eligible);
    if (best) $('last-stock').value = best.name;
    lastRanked = ask;
    lastMarkFailed();
  } catch (e) {
    out.replaceChildren();
    showError(e);
  } finally {
    $('last-rank').disabled = false;
  }
});

$('last-form').addEventListener('submit', async (ev) => {
  ev.preventDefault();
  const id = lastScan;
  if (!id) return;
  const body = { ...lastBody(), stock: $('last-stock').value };
  $('last-make').disabled = true;
  try {
    await api('POST', `/api/scans/${encodeURIComponent(id)}/last`, body);
    clearError('POST /api/scans');
  } catch (e) {
    showError(e);
  }
  await lastShowJob(id);
});
