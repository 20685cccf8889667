// The orthotic insole of the scan shown in Result (docs/API.md "Insoles"): a preset
// (cushioning, supportive, correcting; GET /api/insole/presets) fills the parameters, any of
// which the clinician edits; the job is posted with the preset and the parameters changed
// from it (POST /api/scans/{id}/insole, or for both feet of the scan's visit, mirrored: POST
// /api/visits/{id}/insole); while it runs its record is polled; then each parameter as asked
// and as measured back on the mesh, the pictures (top, side, thickness) and the files (STL,
// 3MF, STEP, insole.json) are shown, or the reason it failed. Uses app.js's helpers (api, el,
// $, withToken, showError, clearError).
'use strict';

const INSOLE_POLL_MS = 500;
let insolePoll = null; // the timer polling a running job
let insoleScan = null; // the scan the card shows
let insoleVisit = null; // the visit holding the scan and the other foot, if any
let insolePresets = null; // GET /api/insole/presets

// The form's fields: [key, label, kind (number | side | length), step, min, max].
const INSOLE_FIELDS = [
  ['length', 'Length', 'length'],
  ['base_thickness_mm', 'Base thickness', 'number', 0.5, 2, 15],
  ['top_cover_mm', 'Top cover', 'number', 0.5, 0, 14],
  ['heel_cup_depth_mm', 'Heel cup depth', 'number', 1, 0, 25],
  ['arch_share', 'Arch (share of scanned)', 'number', 0.05, 0, 1.5],
  ['arch_height_mm', 'Arch height (empty: share)', 'number', 0.5, 0, 35],
  ['rearfoot_post_deg', 'Rearfoot post (deg)', 'number', 0.5, 0, 10],
  ['rearfoot_post_side', 'Rearfoot post side', 'side'],
  ['forefoot_post_deg', 'Forefoot post (deg)', 'number', 0.5, 0, 10],
  ['forefoot_post_side', 'Forefoot post side', 'side'],
  ['met_pad_height_mm', 'Metatarsal pad height', 'number', 0.5, 0, 10],
  ['met_pad_behind_mm', 'Pad behind MT2-4 heads', 'number', 1, 0, 25],
  ['first_ray_cutout_mm', 'First ray cut-out', 'number', 0.5, 0, 13],
  ['heel_lift_mm', 'Heel lift', 'number', 0.5, 0, 20],
  ['extra_length_mm', 'Extra length', 'number', 1, 0, 30],
  ['margin_mm', 'Outline margin', 'number', 0.5, 0, 15],
];

function insoleFileUrl(id, name) {
  return withToken(`/api/scans/${encodeURIComponent(id)}/insole/${encodeURIComponent(name)}`);
}

function insoleBuildForm() {
  const box = $('insole-params');
  if (box.querySelector('input, select')) return;
  for (const [key, label, kind, step, min, max] of INSOLE_FIELDS) {
    const id = `insole-${key.replace(/_/g, '-')}`;
    let input;
    if (kind === 'side') {
      input = el('select', { id }, el('option', { value: 'medial', text: 'medial' }), el('option', { value: 'lateral', text: 'lateral' }));
    } else if (kind === 'length') {
      input = el('select', { id }, el('option', { value: 'full', text: 'full' }), el('option', { value: 'three_quarter', text: '3/4' }));
    } else {
      input = el('input', { id, type: 'number', step: String(step), min: String(min), max: String(max) });
    }
    box.append(el('label', { for: id, text: label }), input);
  }
}

/** Put preset `name`'s parameters in the form. */
function insoleFill(name) {
  const p = insolePresets && insolePresets.presets[name];
  if (!p) return;
  for (const [key] of INSOLE_FIELDS) {
    const f = $(`insole-${key.replace(/_/g, '-')}`);
    f.value = p[key] == null ? '' : String(p[key]);
  }
}

/** The parameters that differ from the preset (the request's `params`). */
function insoleChanges() {
  const p = insolePresets.presets[$('insole-preset').value];
  const out = {};
  for (const [key, , kind] of INSOLE_FIELDS) {
    const raw = $(`insole-${key.replace(/_/g, '-')}`).value;
    const v = kind === 'number' ? (raw === '' ? null : Number(raw)) : raw;
    if (v !== p[key]) out[key] = v;
  }
  return out;
}

/** Show the card for scan `rec` (Result calls this on every scan it loads). */
async function renderInsole(rec) {
  const box = $('insole');
  if (insolePoll) clearTimeout(insolePoll);
  insolePoll = null;
  const changed = insoleScan !== rec.id;
  insoleScan = rec.id;
  const measured = (rec.artifacts || []).some((a) => a.name === 'measurements.json');
  box.hidden = !measured || rec.status === 'running';
  if (box.hidden) return;
  insoleBuildForm();
  try {
    if (!insolePresets) {
      insolePresets = await api('GET', '/api/insole/presets');
      insoleFill($('insole-preset').value);
    }
  } catch (e) {
    showError(e);
  }
  if (changed) {
    $('insole-shoe').checked = false;
    $('insole-visit').checked = false;
  }
  $('insole-shoe').disabled = !(rec.artifacts || []).some((a) => a.name === 'last_adjusted.stl');
  // The visit holding this scan and the other foot: both insoles in one job, mirrored.
  insoleVisit = null;
  try {
    const vs = await api('GET', `/api/visits?subject=${encodeURIComponent(rec.subject)}`);
    insoleVisit = vs.find((v) => (v.left === rec.id || v.right === rec.id) && v.left && v.right) || null;
  } catch (e) {
    // No visits: the scan's own insole only.
  }
  $('insole-visit-label').hidden = !insoleVisit;
  if (insoleVisit) {
    $('insole-visit-text').textContent = `Both feet of visit ${insoleVisit.id} (the same parameters, mirrored: a medial post is medial on each foot)`;
  }
  await insoleShowJob(rec.id);
}

async function insoleShowJob(id) {
  if (id !== insoleScan) return;
  const out = $('insole-job');
  let job = null;
  try {
    job = await api('GET', `/api/scans/${encodeURIComponent(id)}/insole`);
  } catch (e) {
    if (e.status !== 404) showError(e);
  }
  out.replaceChildren();
  $('insole-make').disabled = job !== null && job.state === 'running';
  if (!job) {
    out.append(el('p', { class: 'small', text: 'No insole made for this scan yet.' }));
    return;
  }
  const when = job.finished ? `, ${job.seconds.toFixed(2)} s` : '';
  const r = job.request;
  const ch = Object.entries(r.params || {}).map(([k, v]) => `${k} ${v}`).join(', ');
  const f = job.figures;
  out.append(el('p', { id: 'insole-state', class: 'small', 'data-state': job.state,
    text: `Insole ${job.state}${when}${f ? ` (${f.side} foot, ${f.foot_length_mm.toFixed(1)} mm)` : ''}: preset ${r.preset || 'defaults'}${ch ? '; changed ' + ch : ''}${job.visit ? `; both feet of visit ${job.visit}` : ''}` }));
  if (job.state === 'running') {
    insolePoll = setTimeout(() => insoleShowJob(id), INSOLE_POLL_MS);
    return;
  }
  if (job.state === 'failed') {
    out.append(el('p', { class: 'warn', id: 'insole-reason', text: job.reason || 'failed' }));
  }
  if (f && f.checks.length) {
    const t = el('table', { class: 'data', id: 'insole-checks' },
      el('caption', { text: 'Each parameter measured back on the mesh' }),
      el('thead', {}, el('tr', {}, ...['Parameter', 'Asked', 'Measured', 'Error', 'Within'].map((h) => el('th', { scope: 'col', text: h })))));
    const tb = el('tbody');
    for (const c of f.checks) {
      tb.append(el('tr', {},
        el('td', { text: c.name.replace(/_/g, ' ') }),
        el('td', { class: 'num', text: `${c.asked.toFixed(2)} ${c.unit}` }),
        el('td', { class: 'num', text: `${c.measured.toFixed(2)} ${c.unit}` }),
        el('td', { class: 'num', text: (c.error >= 0 ? '+' : '') + c.error.toFixed(3) }),
        el('td', { class: c.ok ? 'ok' : 'bad', text: c.ok ? `yes (${c.bound})` : `no (${c.bound})` })));
    }
    t.append(tb);
    out.append(t);
    out.append(el('p', { class: 'small', text: `Thinnest shell ${f.min_thickness_mm.toFixed(2)} mm (at least ${f.min_thickness_bound_mm.toFixed(2)}); top against the sole ${f.contact_rms_mm.toFixed(3)} mm RMS, ${f.contact_max_mm.toFixed(3)} mm at most; ${f.triangles} triangles; outline ${f.outline_from}` }));
  }
  if (job.state === 'done' && job.files.length) {
    const span = el('span', { class: 'files', id: 'insole-files' });
    job.files.forEach((n, i) => {
      if (i) span.append(' · ');
      span.append(el('a', { href: insoleFileUrl(id, n), download: n, text: n }));
    });
    out.append(el('p', { class: 'small' }, 'Insole files: ', span));
    // The job's end time in the URL: a new insole's pictures are not taken from the cache.
    const pics = el('div', { class: 'insole-pictures', id: 'insole-pictures' });
    for (const [n, alt] of [['top.png', 'The insole from above'], ['side.png', 'The insole from the side, over the sole'], ['thickness.png', 'Thickness map of the insole']]) {
      const u = insoleFileUrl(id, n);
      pics.append(el('img', { alt, src: u + (u.includes('?') ? '&' : '?') + 't=' + encodeURIComponent(job.finished || '') }));
    }
    out.append(pics);
  }
}

$('insole-preset').addEventListener('change', () => insoleFill($('insole-preset').value));

$('insole-form').addEventListener('submit', async (ev) => {
  ev.preventDefault();
  const id = insoleScan;
  if (!id || !insolePresets || !$('insole-form').reportValidity()) return;
  const body = { preset: $('insole-preset').value, params: insoleChanges(), shoe_bottom: $('insole-shoe').checked };
  $('insole-make').disabled = true;
  try {
    if ($('insole-visit').checked && insoleVisit) {
      await api('POST', `/api/visits/${encodeURIComponent(insoleVisit.id)}/insole`, body);
    } else {
      await api('POST', `/api/scans/${encodeURIComponent(id)}/insole`, body);
    }
    clearError('POST /api/');
  } catch (e) {
    showError(e);
  }
  await insoleShowJob(id);
});
