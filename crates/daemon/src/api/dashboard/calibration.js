// The calibration card: the guided calibration wizard and the daily check, over the daemon's
// calibration job (GET /api/calibrations/job; POST /api/calibrations, /api/verify and
// /api/calibrations/{id}/confirm|repeat|abort). Uses app.js's helpers (api, el, $, badge,
// showError, fmtTime). The job is polled every 400 ms while it runs (a step waits for the
// operator for as long as it takes; the page holds no connection meanwhile); the card's status
// line (calibration age, daily-check warning) follows GET /api/status.
'use strict';

const CAL_POLL_MS = 400;
let calJob = null; // the job's view, as last fetched
let calTimer = null;

function calFmtAge(h) {
  if (typeof h !== 'number') return '';
  if (h < 1) return `${Math.round(h * 60)} min old`;
  if (h < 48) return `${h.toFixed(1)} h old`;
  return `${(h / 24).toFixed(1)} days old`;
}

async function calRefreshStatus() {
  let s;
  try {
    s = await api('GET', '/api/status');
  } catch (_) {
    return; // app.js shows status errors
  }
  const c = s.calibration;
  $('cal-status').textContent = c
    ? `Current: ${c.method}${c.id ? ' ' + c.id : ''}, ${fmtTime(c.date)} (${calFmtAge(c.age_h)})`
    : 'No calibration yet: run the guided calibration.';
  const dc = s.daily_check || {};
  const w = $('cal-warning');
  w.hidden = !dc.warning;
  w.textContent = dc.warning ? `Daily check: ${dc.warning}` : '';
  if (s.calibrating && s.calibrating.state === 'running' && !calTimer) calPoll();
}

function calSetButtons(job) {
  const running = job && job.state === 'running';
  $('cal-start').disabled = !!running;
  $('cal-verify').disabled = !!running;
  const waiting = running && job.guided;
  const phase = waiting ? job.phase : '';
  const passed = job && job.result && job.result.outcome === 'checked' && job.result.passed;
  const confirm = $('cal-confirm');
  confirm.disabled = !(phase === 'place' || (phase === 'review' && passed));
  confirm.textContent = phase === 'review' ? 'Keep step' : 'Target in place';
  $('cal-repeat').disabled = phase !== 'review';
  $('cal-abort').disabled = !running;
}

function calRender(job) {
  calJob = job;
  calSetButtons(job);
  const wiz = $('cal-wizard');
  wiz.hidden = !job;
  if (!job) return;
  const what = job.kind === 'verify' ? 'Daily check' : 'Calibration';
  const step = job.step;
  $('cal-step').textContent = step
    ? `${what} ${job.id} — step ${step.index + 1} of ${step.of}: ${step.title}` +
      (job.attempt > 1 ? ` (attempt ${job.attempt})` : '')
    : `${what} ${job.id}: ${job.phase}`;
  $('cal-instruction').textContent = step ? step.instruction : '';
  const prog = $('cal-progress');
  prog.max = Math.max(1, job.total_frames || 1);
  prog.value = job.frames || 0;
  const seen = $('cal-seen');
  seen.className = 'small';
  seen.replaceChildren();
  if (job.result) {
    const r = job.result;
    if (r.outcome === 'fault') {
      seen.className = 'fail';
      seen.append(`Device fault: ${r.reason}. Repeat the step or abort.`);
    } else {
      seen.className = r.passed ? 'pass' : 'fail';
      seen.append(r.passed ? 'Check passed. ' : 'Check FAILED. ', `Expected ${r.expected}; saw ${r.seen}.`);
      if (r.problem) seen.append(' ', r.problem);
    }
  } else if (job.phase === 'place') {
    seen.append('Put the target on the glass, then press “Target in place”.');
  } else if (job.phase === 'acquiring') {
    seen.append(`Acquiring: ${job.frames || 0} of ${job.total_frames || 0} frames`);
  }
  $('cal-kept').textContent = job.kept && job.kept.length ? `Kept: ${job.kept.join(', ')}` : '';
  if (job.state !== 'running') calRenderEnd(job);
  else $('cal-result').replaceChildren();
}

async function calRenderEnd(job) {
  const out = $('cal-result');
  out.replaceChildren(el('p', {}, `${job.kind === 'verify' ? 'Daily check' : 'Calibration'} ${job.id}: `, stateBadge(job.state), job.reason ? ' ' + job.reason : ''));
  $('cal-wizard').hidden = job.state !== 'complete';
  if (job.state !== 'complete') return;
  if (job.kind === 'verify' && job.report) {
    const r = job.report;
    out.append(el('p', { id: 'cal-verdict' }, badge(r.passed, 'PASS', 'FAIL'), ` width ${r.width_mm.toFixed(2)} of ${r.width_stated_mm} mm, tolerance ${r.tolerance_mm} mm`));
    const body = el('tbody');
    for (const s of r.steps) {
      const e = typeof s.error_mm === 'number' ? s.error_mm.toFixed(4) : 'not seen';
      body.append(el('tr', {}, el('td', { class: 'num' }, s.stated_mm.toFixed(2)), el('td', { class: 'num' }, e), el('td', {}, badge(s.passed, 'ok', 'fail'))));
    }
    out.append(el('table', { class: 'data', id: 'cal-steps' },
      el('thead', {}, el('tr', {}, el('th', { class: 'num' }, 'Step (mm)'), el('th', { class: 'num' }, 'Error (mm)'), el('th', {}, ''))), body));
    for (const f of r.failures || []) out.append(el('p', { class: 'warn' }, f));
  } else if (job.calibration_id) {
    let c;
    try {
      c = await api('GET', `/api/calibrations/${encodeURIComponent(job.calibration_id)}`);
    } catch (e) {
      showError(e);
      return;
    }
    const p = c.parameters || {};
    const sd = c.stddev || {};
    const rs = c.residuals || {};
    const row = (k, label, unit, d) => el('tr', {},
      el('th', { scope: 'row' }, label),
      el('td', { class: 'num' }, typeof p[k] === 'number' ? p[k].toFixed(d) : '–'),
      el('td', { class: 'num' }, typeof sd[k] === 'number' ? '± ' + sd[k].toFixed(d) : ''),
      el('td', {}, unit));
    out.append(el('table', { class: 'data', id: 'cal-params' },
      el('caption', {}, `Calibration ${c.id} (${c.method}), confirmed by ${c.confirmed_by}`),
      el('tbody', {}, row('f_px', 'F', 'px', 2), row('d_mm', 'D', 'mm', 3), row('l_mm', 'L', 'mm', 3))));
    if (typeof rs.u_h_mm === 'number') out.append(el('p', { id: 'cal-uh' }, `Height uncertainty u_h ${rs.u_h_mm.toFixed(4)} mm`));
  }
}

async function calPoll() {
  clearTimeout(calTimer);
  calTimer = null;
  let job = null;
  try {
    job = await api('GET', '/api/calibrations/job');
  } catch (e) {
    if (e.status !== 404) showError(e);
  }
  const ended = calJob && calJob.state === 'running' && job && job.state !== 'running';
  calRender(job);
  if (job && job.state === 'running') calTimer = setTimeout(calPoll, CAL_POLL_MS);
  if (ended) calRefreshStatus();
}

async function calStart(path, body) {
  try {
    await api('POST', path, body);
  } catch (e) {
    showError(e);
    return;
  }
  calPoll();
}

async function calAnswer(what) {
  if (!calJob) return;
  // One answer per shown step: the buttons stay off until the job shows the next one.
  for (const id of ['cal-confirm', 'cal-repeat']) $(id).disabled = true;
  try {
    // The step this answer is for: the daemon refuses it (409) if the job has moved on.
    const seen = { phase: calJob.phase, attempt: calJob.attempt };
    if (calJob.step) seen.step = calJob.step.index;
    const body = what === 'abort' ? {} : seen;
    await api('POST', `/api/calibrations/${encodeURIComponent(calJob.id)}/${what}`, body);
  } catch (e) {
    showError(e);
  }
  calPoll();
}

$('cal-start').addEventListener('click', () => calStart('/api/calibrations', { method: 'insystem', guided: true }));
$('cal-verify').addEventListener('click', () => calStart('/api/verify', { guided: true }));
$('cal-confirm').addEventListener('click', () => calAnswer('confirm'));
$('cal-repeat').addEventListener('click', () => calAnswer('repeat'));
$('cal-abort').addEventListener('click', () => calAnswer('abort'));

calRefreshStatus();
calPoll();
setInterval(calRefreshStatus, 5000);
