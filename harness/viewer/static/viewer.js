// The map viewer page: draws the fused point cloud with three.js and asks the local server
// (harness/viewer/server.py) text, click and image queries. Its state is in window.cfViewer
// (read by the browser tests and the benchmark) and in the #answer element's data attributes.
import * as THREE from './vendor/three.module.min.js';

const state = (window.cfViewer = {
  ready: false, error: null, busy: false, frames: 0, pointsDrawn: 0, boxes: 0, answers: 0,
  lastAnswer: null, lastError: null, timing: null, mode: 'rgb', info: null, spin: false, gl: null,
  lod: true, drawnLast: 0,
});
const params = new URLSearchParams(location.search);
state.spin = params.has('spin');
const $ = (id) => document.getElementById(id);
const statusEl = $('status'), answerEl = $('answer');

function apiUrl(path, extra) {
  const url = new URL(path, location.origin);
  if (params.get('map')) url.searchParams.set('map', params.get('map'));
  for (const [k, v] of Object.entries(extra || {})) url.searchParams.set(k, v);
  return url;
}

function setStatus(text, isError) {
  statusEl.textContent = text;
  statusEl.className = isError ? 'error' : '';
}

// ------------------------------------------------------------------ scene
const canvas = $('canvas');
let renderer;
try {
  renderer = new THREE.WebGLRenderer({ canvas, antialias: false, powerPreference: 'high-performance' });
} catch (err) {
  state.error = 'WebGL is not available in this browser: ' + err.message;
  setStatus(state.error, true);
  throw err;
}
renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
{
  const gl = renderer.getContext();
  const ext = gl.getExtension('WEBGL_debug_renderer_info');
  state.gl = ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
}
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x14171c);
const camera = new THREE.PerspectiveCamera(50, 1, 0.01, 1000);
camera.up.set(0, 0, 1);
const answerGroup = new THREE.Group();
scene.add(answerGroup);
const orbit = { target: new THREE.Vector3(), theta: -Math.PI / 3, phi: Math.PI / 4, dist: 3, radius: 1, focus: 1 };
let points = null, rgbColors = null, heatColors = null, palette = null, needsRender = true;

function placeCamera() {
  const c = Math.cos(orbit.phi);
  camera.position.set(
    orbit.target.x + orbit.dist * c * Math.cos(orbit.theta),
    orbit.target.y + orbit.dist * c * Math.sin(orbit.theta),
    orbit.target.z + orbit.dist * Math.sin(orbit.phi));
  camera.near = Math.max(orbit.dist / 1000, 1e-3);
  camera.far = orbit.dist + orbit.radius * 4;
  camera.lookAt(orbit.target);
  camera.updateProjectionMatrix();
  needsRender = true;
  moved();
}

function resize() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  if (canvas.width !== Math.floor(w * renderer.getPixelRatio()) || canvas.height !== Math.floor(h * renderer.getPixelRatio())) {
    renderer.setSize(w, h, false);
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
    needsRender = true;
  }
}

// Level of detail: while the view moves, draw a prefix of the (randomly ordered) points sized to
// keep about 20-40 frames/s; once it rests, draw them all. The first moving frame draws at most
// LOD_FIRST points (a frame the size of a software-rendered 2-frames/s full draw would make the
// first answer to a query wait for it); later frames adapt the budget to the time they take.
const LOD_FIRST = 150000;
const lod = { budget: LOD_FIRST, lastMove: 0, lastFrame: 0, full: true, wasMoving: false };
function moved() { lod.lastMove = performance.now(); }

function loop(now) {
  requestAnimationFrame(loop);
  resize();
  if (state.spin) { orbit.theta += 0.01; placeCamera(); moved(); }
  const moving = now - lod.lastMove < 250;
  if (!needsRender && (moving || lod.full)) return;
  if (points) {
    const total = points.geometry.attributes.position.count;
    let count = total;
    if (moving && state.lod) {
      lod.budget = Math.min(lod.budget, total);
      if (lod.wasMoving) {  // the last frame's time says how many points the next one can afford
        const dt = now - lod.lastFrame;
        if (dt > 50) lod.budget = Math.max(20000, lod.budget * Math.min(Math.max(35 / dt, 0.25), 0.8));
        else if (dt < 25) lod.budget = Math.min(total, lod.budget * 1.25);
      }
      count = Math.floor(lod.budget);
    }
    points.geometry.setDrawRange(0, count);
    lod.full = count === total;
    state.drawnLast = count;
  }
  renderer.render(scene, camera);
  lod.wasMoving = moving && state.lod;
  lod.lastFrame = now;
  needsRender = false;
  state.frames += 1;
}

function nextFrame() {
  return new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve)));
}

async function fullFrame() {  // resolves after a frame that drew every point
  do { await nextFrame(); } while (!lod.full);
}

// ------------------------------------------------------------------ controls
let drag = null;
canvas.addEventListener('contextmenu', (e) => e.preventDefault());
canvas.addEventListener('pointerdown', (e) => {
  drag = { x: e.clientX, y: e.clientY, x0: e.clientX, y0: e.clientY, pan: e.button === 2 || e.shiftKey, button: e.button };
  canvas.setPointerCapture(e.pointerId);
});
canvas.addEventListener('pointermove', (e) => {
  if (!drag) return;
  const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
  drag.x = e.clientX; drag.y = e.clientY;
  if (drag.pan) {
    const scale = (2 * orbit.dist * Math.tan((camera.fov * Math.PI) / 360)) / canvas.clientHeight;
    const right = new THREE.Vector3().setFromMatrixColumn(camera.matrix, 0);
    const up = new THREE.Vector3().setFromMatrixColumn(camera.matrix, 1);
    orbit.target.addScaledVector(right, -dx * scale).addScaledVector(up, dy * scale);
  } else {
    orbit.theta -= dx * 0.008;
    orbit.phi = Math.min(Math.max(orbit.phi + dy * 0.008, -1.5), 1.5);
  }
  placeCamera();
});
canvas.addEventListener('pointerup', (e) => {
  const d = drag;
  drag = null;
  if (d && d.button === 0 && !d.pan && Math.hypot(e.clientX - d.x0, e.clientY - d.y0) < 4) pick(e.clientX, e.clientY);
});
canvas.addEventListener('wheel', (e) => {
  e.preventDefault();
  orbit.dist = Math.min(Math.max(orbit.dist * Math.exp(e.deltaY * 0.001), orbit.radius * 0.05), orbit.radius * 20);
  placeCamera();
}, { passive: false });

const raycaster = new THREE.Raycaster();
function pickIndex(clientX, clientY) {
  if (!points) return null;
  const rect = canvas.getBoundingClientRect();
  const ndc = new THREE.Vector2(((clientX - rect.left) / rect.width) * 2 - 1, -((clientY - rect.top) / rect.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  points.geometry.setDrawRange(0, Infinity);  // pick among all points, not the moving view's sample
  // a few pixels around the cursor, in metres at the orbit distance
  raycaster.params.Points.threshold = (6 * orbit.dist * Math.tan((camera.fov * Math.PI) / 360)) / rect.height;
  const hits = raycaster.intersectObject(points, false);
  if (!hits.length) return null;
  // the hit nearest the camera among those close to the ray
  const near = hits[0].distance;
  let best = hits[0];
  for (const h of hits) {
    if (h.distance > near + orbit.focus * 0.02) break;
    if (h.distanceToRay < best.distanceToRay) best = h;
  }
  return best.index;
}

function pick(clientX, clientY) {
  const index = pickIndex(clientX, clientY);
  if (index === null) { setStatus('No map point under the cursor: click on the cloud.', false); return; }
  ask('/api/click', { body: JSON.stringify({ index }), headers: { 'Content-Type': 'application/json' } }, 'click');
}
state.pickAt = pickIndex;  // for tests: (clientX, clientY) -> point index or null
state.projectPoint = (i) => {  // for tests: a point's position on the page, in CSS pixels
  const p = points.geometry.attributes.position;
  const v = new THREE.Vector3(p.getX(i), p.getY(i), p.getZ(i)).project(camera);
  const rect = canvas.getBoundingClientRect();
  return { x: rect.left + ((v.x + 1) / 2) * rect.width, y: rect.top + ((1 - v.y) / 2) * rect.height, visible: Math.abs(v.z) <= 1 };
};

// ------------------------------------------------------------------ colours
function setMode(mode) {
  if (mode === 'heat' && !heatColors) mode = 'rgb';
  state.mode = mode;
  document.querySelector(`input[name=mode][value=${mode}]`).checked = true;
  if (points) {
    points.geometry.attributes.color.array.set(mode === 'heat' ? heatColors : rgbColors);
    points.geometry.attributes.color.needsUpdate = true;
  }
  $('color-bar').style.display = mode === 'heat' ? 'block' : 'none';
  needsRender = true;
}
document.querySelectorAll('input[name=mode]').forEach((el) => el.addEventListener('change', () => setMode(el.value)));
$('point-size').addEventListener('input', (e) => {
  if (points) { points.material.size = Number(e.target.value); needsRender = true; }
});

function heatToColors(b64) {
  const raw = atob(b64);
  const n = raw.length;
  const out = heatColors && heatColors.length === 3 * n ? heatColors : new Uint8Array(3 * n);
  for (let i = 0; i < n; i++) {
    const v = raw.charCodeAt(i);
    const j = 3 * i;
    if (v === 255) { out[j] = 70; out[j + 1] = 72; out[j + 2] = 78; continue; }
    const c = palette[v];
    out[j] = c[0]; out[j + 1] = c[1]; out[j + 2] = c[2];
  }
  return out;
}

// ------------------------------------------------------------------ answers
const REGION_COLORS = [0xffffff, 0xff4fd8, 0x4fe3ff, 0xffe14f, 0x9dff4f, 0xff8c4f, 0xb04fff, 0x4f8cff];

function clearAnswer() {
  for (const obj of [...answerGroup.children]) {
    answerGroup.remove(obj);
    if (obj.geometry) obj.geometry.dispose();
    if (obj.material) obj.material.dispose();
  }
  state.boxes = 0;
}

function drawRegions(answer) {
  clearAnswer();
  const r = Math.max(orbit.focus * 0.015, 0.004);
  const sphere = new THREE.SphereGeometry(1, 12, 8);
  answer.regions.forEach((reg, k) => {
    const color = REGION_COLORS[k % REGION_COLORS.length];
    const box = new THREE.Box3(new THREE.Vector3(...reg.aabb_min), new THREE.Vector3(...reg.aabb_max));
    const helper = new THREE.Box3Helper(box, color);
    helper.material.depthTest = false;
    helper.renderOrder = 2;
    answerGroup.add(helper);
    const mark = new THREE.Mesh(sphere, new THREE.MeshBasicMaterial({ color, depthTest: false }));
    mark.position.set(...reg.median);
    mark.scale.setScalar(r);
    mark.renderOrder = 3;
    answerGroup.add(mark);
  });
  if (answer.clicked) {
    const mark = new THREE.Mesh(sphere, new THREE.MeshBasicMaterial({ color: 0x00ff66, depthTest: false }));
    mark.position.set(...answer.clicked);
    mark.scale.setScalar(r * 0.8);
    mark.renderOrder = 3;
    answerGroup.add(mark);
  }
  state.boxes = answer.regions.length;
}

function fmt(v) { return v.map((x) => x.toFixed(2)).join(', '); }

function showAnswer(answer) {
  const what = { text: 'Text', click: 'Click', image: 'Image' }[answer.kind] || answer.kind;
  answerEl.dataset.found = String(answer.found);
  answerEl.dataset.kind = answer.kind;
  answerEl.dataset.regions = String(answer.regions.length);
  answerEl.dataset.query = answer.query;
  answerEl.replaceChildren();
  const head = document.createElement('div');
  head.className = answer.found ? 'found' : 'not-found';
  const presumed = answer.presumed ? ` (presumed present: ${answer.presumed.replace('_', ' ')})` : '';
  head.textContent = answer.found
    ? `${what} query "${answer.query}": found ${answer.num_regions} region${answer.num_regions === 1 ? '' : 's'}${presumed}`
    : `${what} query "${answer.query}": not found: ${answer.reason}`;
  answerEl.dataset.presumed = answer.presumed || '';
  answerEl.appendChild(head);
  if (answer.found) {
    const list = document.createElement('ol');
    answer.regions.forEach((reg, k) => {
      const li = document.createElement('li');
      const sw = document.createElement('span');
      sw.className = 'swatch';
      sw.style.background = '#' + REGION_COLORS[k % REGION_COLORS.length].toString(16).padStart(6, '0');
      li.appendChild(sw);
      li.appendChild(document.createTextNode(
        `score ${reg.score.toFixed(2)}, ${reg.num_points} points, median (${fmt(reg.median)}) m`));
      list.appendChild(li);
    });
    answerEl.appendChild(list);
  }
}

async function ask(path, init, kind) {
  if (state.busy) return;
  state.busy = true;
  const t0 = performance.now();
  setStatus(kind === 'image' ? 'embedding the image ...' : 'asking the map ...', false);
  try {
    const res = await fetch(apiUrl(path, init.query), { method: 'POST', body: init.body, headers: init.headers });
    let answer;
    try { answer = await res.json(); } catch (err) { answer = { ok: false, error: `the server answered ${res.status} without JSON` }; }
    const t1 = performance.now();
    if (!res.ok || !answer.ok) {
      state.lastError = answer.error || `request failed (${res.status})`;
      setStatus(state.lastError, true);
      return;
    }
    heatColors = heatToColors(answer.heat);
    drawRegions(answer);
    setMode('heat');
    showAnswer(answer);
    moved();  // the first frame of the answer may draw the moving view's sample; the next, every point
    await nextFrame();
    const t2 = performance.now();
    await fullFrame();
    const t3 = performance.now();
    delete answer.heat;
    state.lastError = null;
    state.timing = { request_ms: t1 - t0, total_ms: t2 - t0, full_ms: t3 - t0, server_ms: answer.server_ms };
    state.lastAnswer = answer;
    state.answers += 1;
    setStatus(`answered in ${(t2 - t0).toFixed(0)} ms (server ${answer.server_ms.toFixed(0)} ms)`, false);
  } catch (err) {
    state.lastError = 'the viewer server did not answer: ' + err.message;
    setStatus(state.lastError, true);
  } finally {
    state.busy = false;
  }
}

$('text-form').addEventListener('submit', (e) => {
  e.preventDefault();
  const lookup = $('presume').checked ? 'present' : 'plain';
  ask('/api/query', { body: JSON.stringify({ text: $('text-query').value, lookup }), headers: { 'Content-Type': 'application/json' } }, 'text');
});
$('image-file').addEventListener('change', (e) => {
  const file = e.target.files[0];
  if (!file) return;
  ask('/api/image', { body: file, headers: { 'Content-Type': file.type || 'application/octet-stream' }, query: { name: file.name } }, 'image');
  e.target.value = '';
});

// ------------------------------------------------------------------ loading
async function load() {
  const infoRes = await fetch(apiUrl('/api/info'));
  const info = await infoRes.json();
  if (!infoRes.ok || !info.ok) throw new Error(info.error || `map info: ${infoRes.status}`);
  state.info = info;
  palette = info.palette;
  const res = await fetch(apiUrl('/api/points'));
  if (!res.ok) throw new Error(`points: ${res.status}`);
  const buf = await res.arrayBuffer();
  const m = info.sent_points;
  if (buf.byteLength !== 15 * m) throw new Error(`points: expected ${15 * m} bytes, got ${buf.byteLength}`);
  const positions = new Float32Array(buf, 0, 3 * m);
  rgbColors = new Uint8Array(buf, 12 * m, 3 * m);
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
  geometry.setAttribute('color', new THREE.BufferAttribute(new Uint8Array(rgbColors), 3, true));
  const lo = new THREE.Vector3(...info.bounds_min), hi = new THREE.Vector3(...info.bounds_max);
  const centre = lo.clone().add(hi).multiplyScalar(0.5);
  orbit.radius = Math.max(hi.distanceTo(lo) / 2, 0.05);
  geometry.boundingSphere = new THREE.Sphere(centre, orbit.radius * 1.01);  // no O(N) pass
  geometry.boundingBox = new THREE.Box3(lo, hi);
  const flo = new THREE.Vector3(...info.focus_min), fhi = new THREE.Vector3(...info.focus_max);
  const focusRadius = (orbit.focus = Math.max(fhi.distanceTo(flo) / 2, 0.05));
  const size = m > 300000 ? 1.5 : m > 50000 ? 2 : 3;
  $('point-size').value = String(size);
  points = new THREE.Points(geometry, new THREE.PointsMaterial({ size, vertexColors: true, sizeAttenuation: false }));
  scene.add(points);
  orbit.target.copy(flo).add(fhi).multiplyScalar(0.5);
  orbit.dist = focusRadius * 2.6;
  placeCamera();
  state.pointsDrawn = m;
  const thinned = m < info.num_points ? ` (${m.toLocaleString()} drawn)` : '';
  $('map-info').textContent = `${info.map}: ${info.num_points.toLocaleString()} points${thinned}, ` +
    `${info.frames_integrated} frames; encoder ${info.encoder}` + (info.image_queries ? '' : ' (text only)');
  $('image-file').disabled = !info.image_queries;
  $('presume').checked = info.lookup === 'present';
  if (info.notes && info.notes.length) { const n = $('map-notes'); n.textContent = info.notes.join(' '); n.hidden = false; }
  if (info.maps.length > 1) {
    const sel = $('map-select');
    for (const name of info.maps) {
      const opt = document.createElement('option');
      opt.value = name; opt.textContent = name; opt.selected = name === info.map;
      sel.appendChild(opt);
    }
    sel.hidden = false;
    sel.addEventListener('change', () => { location.search = '?map=' + encodeURIComponent(sel.value); });
  }
  if (info.replay) { const v = $('replay'); v.src = info.replay; v.hidden = false; }
  const bar = $('color-bar');
  bar.style.background = 'linear-gradient(to right, ' +
    palette.filter((_, i) => i % 32 === 0 || i === palette.length - 1).map((c) => `rgb(${c.join(',')})`).join(', ') + ')';
  setStatus('Type a query, click a point or upload an image.', false);
  state.ready = true;
}

requestAnimationFrame(loop);
load().catch((err) => {
  state.error = String(err.message || err);
  setStatus('Could not load the map: ' + state.error, true);
});
