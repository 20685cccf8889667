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

const state = { id: null, ready: false, error: null, triangles: 0, landmarks: [], lines: [] };
window.footscanViewer = state;

const fig = document.getElementById('viewer-fig');
const canvas = document.getElementById('viewer');
showTls();
let renderer;
try {
  renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
} catch (e) {
  // No WebGL (an old browser, or graphics turned off): the rest of the page works as before.
  state.error = `no WebGL: ${e && e.message ? e.message : e}`;
  throw e;
}
renderer.setPixelRatio(1);
renderer.setClearColor(BACKGROUND, 1);
const scene = new THREE.Scene();
scene.add(new THREE.HemisphereLight(0xffffff, 0x888888, 2.0));
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
scene.add(sun);
const camera = new THREE.PerspectiveCamera(35, canvas.width / canvas.height, 0.001, 20);
// OrbitControls: drag to turn (about the vertical axis and over), wheel or pinch to zoom,
// right-drag or two-finger drag to pan; the vertical stays up, as on a turntable.
const controls = new OrbitControls(camera, canvas);
controls.enableDamping = false;
controls.addEventListener('change', render);
let model = null;
let bounds = null;

function render() {
  sun.position.copy(camera.position);
  renderer.render(scene, camera);
}

/** Point the camera at the model from `view`: 'top' (down onto the instep, heel left),
 * 'side' (from the medial or lateral side), or 'three-quarter' (the default). */
function setView(view) {
  if (!bounds) return;
  const c = bounds.getCenter(new THREE.Vector3());
  const size = bounds.getSize(new THREE.Vector3());
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
}
state.setView = setView;

function clear() {
  if (model) {
    scene.remove(model);
    model.traverse((o) => {
      if (o.geometry) o.geometry.dispose();
      if (o.material) o.material.dispose();
    });
  }
  model = null;
  bounds = null;
}

async function load(id) {
  if (id === state.id) return;
  Object.assign(state, { id, ready: false, error: null, triangles: 0, landmarks: [], lines: [] });
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
    state.ready = true;
  }, (e) => {
    state.error = `model.glb: ${e && e.message ? e.message : e}`;
    fig.hidden = true;
  });
}
state.load = load;

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
