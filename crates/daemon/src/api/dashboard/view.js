// The dashboard's 3D view of the shown scan's foot (model.glb: the solid, its landmarks and
// the length and ball-width lines), with three.js vendored under /vendor/three/ (no CDN),
// and the HTTPS certificate's fingerprint in the Scanner card.
//
// A module beside app.js rather than part of it: it follows the Result card by watching
// #result's data-scan-id, so app.js needs no change to drive it.
import * as THREE from 'three';
import { OrbitControls } from '/vendor/three/examples/jsm/controls/OrbitControls.js';
import { GLTFLoader } from '/vendor/three/examples/jsm/loaders/GLTFLoader.js';

const TOKEN_KEY = 'footscand.token';
const BACKGROUND = 0xf7f7f5;
const LANDMARK = 0xd01010;
// The last drawn around the foot (style.css .swatch-last): a clear blue, apart from the skin
// and from the red of the foot where it stands out.
const LAST = 0x4a78d0;
const LAST_OPACITY = 0.25;

function authHeaders() {
  const t = sessionStorage.getItem(TOKEN_KEY) || '';
  return t ? { Authorization: `Bearer ${t}` } : {};
}

// ---------------------------------------------------------------- HTTPS fingerprint

async function showTls() {
  const dd = document.getElementById('st-tls');
  if (!dd) return;
  try {
    const r = await fetch('/api/tls', { headers: authHeaders() });
    if (!r.ok) return;
    const v = await r.json();
    dd.hidden = false;
    document.getElementById('st-tls-dt').hidden = false;
    if (v.https) {
      const c = v.certificate;
      dd.replaceChildren(
        (c.self_signed ? 'self-signed, ' : '') + 'SHA-256 ',
        Object.assign(document.createElement('code'), { textContent: c.fingerprint_sha256, id: 'st-tls-fp' }),
      );
    } else {
      dd.textContent = 'off (plain HTTP)';
    }
  } catch (_) {
    /* the status card says the rest */
  }
}

// ---------------------------------------------------------------- the 3D view

const state = { id: null, ready: false, error: null, triangles: 0, landmarks: [], lines: [],
  last: null };
window.footscanViewer = state;

/** A WebGL view on `canvas`: lights, a camera the mouse and touch turn about the model
 * (OrbitControls: drag to turn about the vertical and over, wheel or pinch to zoom,
 * right-drag or two-finger drag to pan; the vertical stays up, as on a turntable), and
 * `frame(bounds, view)` pointing it at a box from 'top' (down onto the instep), 'side' or
 * 'three-quarter'. Throws without WebGL. Shared by the Result card's view and a visit's. */
function makeStage(canvas) {
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setClearColor(BACKGROUND, 1);
  const scene = new THREE.Scene();
  scene.add(new THREE.HemisphereLight(0xffffff, 0x888888, 2.0));
  const sun = new THREE.DirectionalLight(0xffffff, 1.5);
  scene.add(sun);
  const camera = new THREE.PerspectiveCamera(35, canvas.width / canvas.height, 0.001, 20);
  const controls = new OrbitControls(camera, canvas);
  controls.enableDamping = false;
  const render = () => {
    sun.position.copy(camera.position);
    renderer.render(scene, camera);
  };
  controls.addEventListener('change', render);
  const frame = (box, view) => {
    const c = box.getCenter(new THREE.Vector3());
    const size = box.getSize(new THREE.Vector3());
    const r = 0.5 * size.length();
    const dist = r / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2)) * 1.05;
    const dir = {
      top: new THREE.Vector3(0, 1, 0.0001),
      side: new THREE.Vector3(0, 0, 1),
      'three-quarter': new THREE.Vector3(-0.6, 0.7, 1.0),
    }[view] || new THREE.Vector3(-0.6, 0.7, 1.0);
    camera.up.set(0, 1, 0);
    camera.position.copy(c).addScaledVector(dir.normalize(), dist);
    controls.target.copy(c);
    controls.update();
    render();
  };
  const dispose = () => {
    controls.dispose();
    scene.traverse((o) => {
      if (o.geometry) o.geometry.dispose();
      if (o.material) o.material.dispose();
    });
    renderer.dispose();
    renderer.forceContextLoss();
  };
  return { renderer, scene, camera, controls, render, frame, dispose };
}

const fig = document.getElementById('viewer-fig');
const canvas = document.getElementById('viewer');
showTls();
let stage;
try {
  stage = makeStage(canvas);
} catch (e) {
  // No WebGL (an old browser, or graphics turned off): the rest of the page works as before.
  state.error = `no WebGL: ${e && e.message ? e.message : e}`;
  throw e;
}
const { scene, render } = stage;
let model = null;
let bounds = null;

/** Point the camera at the model from `view`: 'top' (down onto the instep, heel left),
 * 'side' (from the medial or lateral side), or 'three-quarter' (the default). */
function setView(view) {
  if (bounds) stage.frame(bounds, view);
}
state.setView = setView;

function clear() {
  if (model) {
    scene.remove(model);
    model.traverse((o) => {
      if (o.geometry) o.geometry.dispose();
      if (o.material) o.material.dispose();
      if (o.userData.plain) {
        o.userData.plain.geometry.dispose();
        o.userData.plain.material.dispose();
      }
    });
  }
  model = null;
  bounds = null;
}

async function load(id) {
  if (id === state.id) return;
  Object.assign(state, { id, ready: false, error: null, triangles: 0, landmarks: [], lines: [],
    last: null, lastError: null });
  fitShown = null;
  legend.hidden = true;
  clear();
  render();
  const t0 = performance.now();
  let buf;
  try {
    const r = await fetch(`/api/scans/${encodeURIComponent(id)}/files/model.glb`, { headers: authHeaders() });
    if (r.status === 404) {
      fig.hidden = true;
      state.error = 'no model.glb for this scan';
      return;
    }
    if (!r.ok) throw new Error(`GET model.glb: ${r.status}`);
    buf = await r.arrayBuffer();
  } catch (e) {
    state.error = String(e);
    fig.hidden = true;
    return;
  }
  if (state.id !== id) return; // another scan was opened meanwhile
  new GLTFLoader().parse(buf, '', (gltf) => {
    if (state.id !== id) return;
    model = gltf.scene;
    const marks = [];
    model.traverse((o) => {
      if (o.isMesh) {
        state.triangles += o.geometry.index ? o.geometry.index.count / 3 : 0;
        if (o.material.transparent) o.material.depthWrite = false;
      } else if (o.isLineSegments || o.isLine) {
        // The measured lines stay visible through the foot.
        o.material.depthTest = false;
        o.renderOrder = 10;
        state.lines.push(o.name);
      } else if (o !== model && o.children.length === 0) {
        marks.push(o);
      }
    });
    const footMesh = model.getObjectByName('foot');
    bounds = new THREE.Box3().setFromObject(footMesh || model);
    const radius = 0.012 * bounds.getSize(new THREE.Vector3()).length();
    const dot = new THREE.SphereGeometry(radius, 16, 12);
    for (const o of marks) {
      const m = new THREE.Mesh(dot, new THREE.MeshBasicMaterial({ color: LANDMARK, depthTest: false }));
      m.renderOrder = 11;
      o.add(m);
      state.landmarks.push(o.name);
    }
    scene.add(model);
    fig.hidden = false;
    setView('three-quarter');
    state.loadMs = performance.now() - t0;
    // From the page's navigation start: what a user waits from opening the dashboard.
    state.readyAt = performance.now();
    state.ready = true;
    loadFit(id);
  }, (e) => {
    state.error = `model.glb: ${e && e.message ? e.message : e}`;
    fig.hidden = true;
  });
}
state.load = load;

// ---------------------------------------------------------------- the last around the foot

const legend = document.getElementById('viewer-legend');
let fitShown = null; // the job (scan and finish time) whose fit.glb is drawn
let fitLoading = null; // the one being fetched

function clearFit() {
  if (!model) return;
  const old = model.getObjectByName('fit-last');
  if (old) {
    model.remove(old);
    old.traverse((o) => {
      if (o.geometry) o.geometry.dispose();
      if (o.material) o.material.dispose();
    });
  }
  const foot = model.getObjectByName('foot');
  if (foot && foot.userData.plain) {
    foot.geometry = foot.userData.plain.geometry;
    foot.material = foot.userData.plain.material;
  }
  legend.hidden = true;
  state.last = null;
  fitShown = null;
}

/** The scan's last (its job's fit.glb: the last laid flat in the foot's frame, the foot
 * coloured by how far it stands out of it, both computed by footscand), drawn translucent
 * around the foot, when the scan has one. */
async function loadFit(id) {
  let job;
  try {
    const r = await fetch(`/api/scans/${encodeURIComponent(id)}/last`, { headers: authHeaders() });
    if (!r.ok) { if (state.id === id) clearFit(); return; }
    job = await r.json();
  } catch (_) {
    return;
  }
  if (state.id !== id || !model) return;
  const key = `${id} ${job.finished}`;
  if (!job.fit) {
    if (job.state !== 'running') clearFit();
    if (job.fit_error) state.lastError = job.fit_error;
    return;
  }
  // The job's end is seen twice at times (the page's poll and this call): one load each.
  if (fitShown === key || fitLoading === key) return;
  fitLoading = key;
  try {
    await drawFit(id, job, key);
  } finally {
    if (fitLoading === key) fitLoading = null;
  }
}

async function drawFit(id, job, key) {
  let buf;
  try {
    const r = await fetch(`/api/scans/${encodeURIComponent(id)}/last/${encodeURIComponent(job.fit.file)}`,
      { headers: authHeaders() });
    if (!r.ok) throw new Error(`GET ${job.fit.file}: ${r.status}`);
    buf = await r.arrayBuffer();
  } catch (e) {
    state.lastError = String(e);
    return;
  }
  let gltf;
  try {
    gltf = await new GLTFLoader().parseAsync(buf, '');
  } catch (e) {
    state.lastError = `${job.fit.file}: ${e && e.message ? e.message : e}`;
    return;
  }
  if (state.id !== id || !model) return;
  clearFit();
  const last = gltf.scene.getObjectByName('last');
  const coloured = gltf.scene.getObjectByName('foot');
  const foot = model.getObjectByName('foot');
  if (!last || !coloured || !foot) {
    state.lastError = `${job.fit.file}: no foot or last node`;
    return;
  }
  // The clearance colours replace the plain foot; the landmarks and lines stay.
  foot.userData.plain = { geometry: foot.geometry, material: foot.material };
  foot.geometry = coloured.geometry;
  foot.material = coloured.material;
  const group = new THREE.Group();
  group.name = 'fit-last';
  last.traverse((o) => {
    if (o.isMesh) {
      o.material = new THREE.MeshStandardMaterial({
        color: LAST, transparent: true, opacity: LAST_OPACITY, roughness: 0.8,
        metalness: 0, side: THREE.DoubleSide, depthWrite: false,
        // Over the foot everywhere: its bottom lies on the sole, and depth-tested there the
        // two speckled (a shell the foot is inside needs no depth order).
        depthTest: false,
      });
      o.renderOrder = 5;
    }
  });
  group.add(last);
  model.add(group);
  // The camera frames the last and the foot in it.
  bounds = new THREE.Box3().setFromObject(foot).union(new THREE.Box3().setFromObject(last));
  document.getElementById('viewer-legend-red').textContent = job.fit.red_at_mm.toFixed(0);
  document.getElementById('viewer-legend-worst').textContent = job.fit.foot_out_mm > 0.05
    ? `Largest: ${job.fit.foot_out_mm.toFixed(1)} mm out; ${(100 * job.fit.foot_out_share).toFixed(1)} % of the foot more than 0.5 mm out.`
    : 'The foot is inside the last everywhere.';
  legend.hidden = false;
  fitShown = key;
  state.last = { stock: job.request.stock, ...job.fit };
  setView('three-quarter');
}
state.loadFit = loadFit;

/** Show or hide the last around the foot (the foot keeps its clearance colours). */
function showLast(on) {
  const g = model && model.getObjectByName('fit-last');
  if (g) g.visible = on;
  document.getElementById('view-last').checked = on;
  render();
}
state.showLast = showLast;
document.getElementById('view-last').addEventListener('change', (e) => showLast(e.target.checked));

/** Show or hide the landmarks and the measured lines. */
state.showMarks = (on) => {
  if (!model) return;
  model.traverse((o) => {
    if (o.renderOrder >= 10) o.visible = on;
  });
  render();
};

// A last made while the scan is shown (last.js shows the job's state in #last-job) is drawn
// when its job ends.
new MutationObserver(() => {
  const s = document.getElementById('last-state');
  if (state.id && s && s.dataset.state !== 'running') loadFit(state.id);
}).observe(document.getElementById('last-job'), { childList: true, subtree: true });

const result = document.getElementById('result');
new MutationObserver(() => {
  const id = result.dataset.scanId;
  if (id) load(id);
}).observe(result, { attributes: true, attributeFilter: ['data-scan-id'] });
if (result.dataset.scanId) load(result.dataset.scanId);

for (const [id, view] of [['view-top', 'top'], ['view-side', 'side'], ['view-reset', 'three-quarter']]) {
  document.getElementById(id).addEventListener('click', () => setView(view));
}
render();

// ---------------------------------------------------------------- a visit's two feet

// visits.js draws a canvas.visit-viewer (data-scan-id) per foot of the open visit; each
// gets its own view of that scan's model.glb. A canvas taken out of the page (another visit
// opened) gives back its WebGL context: Chromium keeps only a few at once.
const visitViews = new Map();

async function visitView(c) {
  const id = c.dataset.scanId;
  const t0 = performance.now();
  let st;
  try {
    st = makeStage(c);
  } catch (e) {
    c.dataset.error = `no WebGL: ${e && e.message ? e.message : e}`;
    return;
  }
  visitViews.set(c, st);
  try {
    const r = await fetch(`/api/scans/${encodeURIComponent(id)}/files/model.glb`, { headers: authHeaders() });
    if (!r.ok) throw new Error(`GET model.glb: ${r.status}`);
    const buf = await r.arrayBuffer();
    const gltf = await new GLTFLoader().parseAsync(buf, '');
    if (!c.isConnected) return;
    const foot = gltf.scene.getObjectByName('foot');
    if (!foot) throw new Error('model.glb has no foot');
    st.scene.add(foot);
    st.frame(new THREE.Box3().setFromObject(foot), 'three-quarter');
    c.dataset.triangles = foot.geometry.index ? foot.geometry.index.count / 3 : 0;
    c.dataset.loadMs = (performance.now() - t0).toFixed(0);
    c.dataset.ready = '1';
  } catch (e) {
    c.dataset.error = String(e);
  }
}

function visitViewsFollow() {
  for (const [c, st] of visitViews) {
    if (!c.isConnected) {
      st.dispose();
      visitViews.delete(c);
    }
  }
  for (const c of document.querySelectorAll('canvas.visit-viewer')) {
    if (!visitViews.has(c) && !c.dataset.error) visitView(c);
  }
}
/** Turn a visit's views: 'top', 'side' or 'three-quarter'. */
window.footscanVisitViews = (view) => {
  for (const st of visitViews.values()) {
    const foot = st.scene.getObjectByName('foot');
    if (foot) st.frame(new THREE.Box3().setFromObject(foot), view);
  }
};
new MutationObserver(visitViewsFollow)
  .observe(document.getElementById('visit-detail'), { childList: true, subtree: true });
visitViewsFollow();
