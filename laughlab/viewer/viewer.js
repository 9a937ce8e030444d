// laughlab viewer: the run's character.glb in sync with its audio, the MCS and laughing energy
// scrolling below with the clips as blocks (cf. van Duijn 2014, Figs. 3.2 and 4.2).
// The audio element is the clock: the animation shows audio.currentTime; without audio a wall clock does.
// Served (python -m laughlab view RUN), the page fetches run.json and character.glb; written with --out, the
// page carries them inline (script elements laughlab-run and laughlab-glb) so that it also works opened as a file.
// Live (output=viewer: run.json's live), it applies each frame laughlab sends over Server-Sent Events (./events:
// the tracks' layout, then per frame the values character.glb would hold; laughlab/viewer/live.py) instead.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const $ = (id) => document.getElementById(id);
const state = { ready: false, error: null, animTime: 0, frames: 0 };
window.laughlab = state;
window.addEventListener('error', (e) => { state.error = String(e.message || e); document.title = 'error: ' + state.error; });
window.addEventListener('unhandledrejection', (e) => { state.error = String(e.reason); document.title = 'error: ' + state.error; });

const inline = (id) => document.getElementById(id);
async function loadRun() {
  if (inline('laughlab-run')) return JSON.parse(inline('laughlab-run').textContent);
  const r = await fetch('./run.json');
  if (!r.ok) throw new Error(`run.json: HTTP ${r.status}`);
  return r.json();
}
// a user's avatar (--character): a VRM goes through three-vrm (MToon materials, spring bones), which the import
// map names 'three-vrm' (a file beside the page when served, a data: URL when inlined); the run is baked into
// the file's first animation (bones and morph weights), so the mixer plays it as it plays ours
async function loadCharacter(avatar) {
  const loader = new GLTFLoader();
  if (avatar.vrm) {
    const { VRMLoaderPlugin } = await import('three-vrm');
    loader.register((parser) => new VRMLoaderPlugin(parser, { autoUpdateHumanBones: false }));
  }
  const el = inline('laughlab-glb');
  if (!el) return loader.loadAsync('./character.glb');
  const bytes = Uint8Array.from(atob(el.textContent.trim()), (c) => c.charCodeAt(0));
  return loader.parseAsync(bytes.buffer, './');
}

const run = await loadRun();
const live = !!run.live;
const audio = $('audio');
const hasAudio = run.audio !== null;
if (hasAudio) audio.src = './' + run.audio;
let wallStart = null, wallOffset = 0, speed = 1;

function now() {
  if (hasAudio) return audio.currentTime;
  return wallStart === null ? wallOffset : wallOffset + (performance.now() - wallStart) / 1000 * speed;
}
function playing() { return hasAudio ? !audio.paused : wallStart !== null; }
function setPlaying(on) {
  if (hasAudio) { on ? audio.play() : audio.pause(); }
  else if (on && wallStart === null) { wallStart = performance.now(); }
  else if (!on && wallStart !== null) { wallOffset = now(); wallStart = null; }
  $('play').innerHTML = on ? '&#10074;&#10074;' : '&#9654;';
}
async function seek(t) {
  t = Math.max(0, Math.min(run.duration, t));
  if (hasAudio) {
    if (audio.readyState < 1) await new Promise((r) => audio.addEventListener('loadedmetadata', r, { once: true }));
    const done = new Promise((r) => audio.addEventListener('seeked', r, { once: true }));
    audio.currentTime = t;
    await done;
  } else { wallOffset = t; if (wallStart !== null) wallStart = performance.now(); }
}

// the 3D view
const canvas = $('view');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x2a3040);
scene.add(new THREE.HemisphereLight(0xeef0ff, 0x303038, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 2.2);
sun.position.set(1.5, 3, 2.5);
scene.add(sun);
const floor = new THREE.Mesh(new THREE.CircleGeometry(2.5, 48), new THREE.MeshStandardMaterial({ color: 0x555b66 }));
floor.rotation.x = -Math.PI / 2;
scene.add(floor);
const camera = new THREE.PerspectiveCamera(28, 1, 0.05, 50);
const controls = new OrbitControls(camera, canvas);
let userMoved = false;
controls.addEventListener('start', () => { userMoved = true; });

const avatar = run.avatar || { vrm: false, facing: 1, bones: {} };
const gltf = await loadCharacter(avatar);
const vrm = gltf.userData.vrm || null;
const root = vrm ? vrm.scene : gltf.scene;
scene.add(root);
// turn the avatar to the camera (VRM 0.x faces -Z; an export may face +-X): the turn about Y that laughlab's
// retargeting and video undo too (laughlab/avatar/retarget.py facing_matrix)
if (avatar.turn !== undefined) root.rotation.y = avatar.turn;
else if (avatar.facing < 0) root.rotation.y = Math.PI;
const mixer = new THREE.AnimationMixer(root);
const action = mixer.clipAction(gltf.animations[0]);
action.play();
// the character's meshes: skinned ones, and rigid ones that ride on a bone (as some avatars' parts do)
const meshes = [];
root.traverse((o) => { if (o.isMesh && o.geometry && o.geometry.attributes.position) meshes.push(o); });
let lastT = -1;   // the time of the last frame drawn (-1: none yet, so the first frame settles the springs)

function pose(t) {
  if (!live) mixer.setTime(t);
  root.updateMatrixWorld(true);
  for (const m of meshes) if (m.isSkinnedMesh) m.skeleton.update();
}
// every vertex of the character, posed, in world space (Mesh.getVertexPosition applies the morphs, and a
// SkinnedMesh's the bones too)
function eachVertex(fn) {
  const v = new THREE.Vector3();
  for (const m of meshes) {
    const n = m.geometry.attributes.position.count;
    for (let i = 0; i < n; i++) { m.getVertexPosition(i, v); v.applyMatrix4(m.matrixWorld); fn(v); }
  }
}
// the space the character takes over the whole run: its vertices at 16 moments (every one in the box, every
// 4th, or fewer for a large avatar, kept to fit the camera to)
const vertices = meshes.reduce((n, m) => n + m.geometry.attributes.position.count, 0);
const stride = Math.max(4, Math.ceil(17 * vertices / 40000));
const reach = new THREE.Box3(), points = [];
for (let k = 0; k <= 16; k++) {
  pose(run.duration * k / 16);
  let i = 0;
  eachVertex((v) => { reach.expandByPoint(v); if (i++ % stride === 0) points.push(v.clone()); });
}
pose(0);
if (live) {   // only the rest pose is known: leave room for a laugh's bend and sway
  const size = reach.getSize(new THREE.Vector3()), c = reach.getCenter(new THREE.Vector3());
  reach.expandByVector(new THREE.Vector3(0.15 * size.y, 0.05 * size.y, 0.15 * size.y));
  for (const dx of [-1, 1]) for (const dz of [-1, 1]) points.push(new THREE.Vector3(c.x + dx * size.x, c.y, c.z + dz * size.z));
  // and at the feet, in front: a laugh on the floor (rofl) puts the hands there, under the view's edge before
  for (const x of [reach.min.x, reach.max.x]) points.push(new THREE.Vector3(x, reach.min.y + 0.05 * size.y, reach.max.z));
}

// node index -> its object, for the tests' check of the joints' world positions
const nodes = {};
root.traverse((o) => {
  const a = gltf.parser.associations.get(o);
  if (a && a.nodes !== undefined && !(a.nodes in nodes)) nodes[a.nodes] = o;
});
state.world = (indices) => indices.map((i) => { const p = new THREE.Vector3(); nodes[i].getWorldPosition(p); return p.toArray(); });
state.morphs = () => { const out = {}; root.traverse((o) => {
  const a = gltf.parser.associations.get(o);
  if (o.morphTargetInfluences && a && a.meshes !== undefined) out[o.name] = Array.from(o.morphTargetInfluences);
}); return out; };
state.vrm = vrm !== null;

// frame the camera on those points: from the front, a little from above and to the side, every point within
// the middle of the view (88% of its height, 90% of its width), whatever the window's shape; the view ends
// where the control bar starts (the page's CSS), so the bar never covers the character
const viewFrom = new THREE.Vector3(0.5, 0.3, 3.9).normalize();
// the distances scale with the character's bounding sphere, so an avatar in centimetres (170 m tall in glTF's
// metres: FBX exports without unit conversion) is framed as one in metres (it was beyond the far plane)
const radius = Math.max(1e-3, reach.getBoundingSphere(new THREE.Sphere()).radius);
if (radius > 1.5) floor.scale.setScalar(radius / 1.5);
function frameCharacter() {
  const centre = reach.getCenter(new THREE.Vector3());
  const p = new THREE.Vector3();
  const fits = () => points.every((v) => { p.copy(v).project(camera); return Math.abs(p.x) < 0.9 && Math.abs(p.y) < 0.88 && p.z < 1; });
  camera.near = Math.min(0.05, radius / 50);
  camera.far = Math.max(50, radius * 60);
  camera.updateProjectionMatrix();
  let d = 0.5 * radius;
  for (let i = 0; i < 120; i++) {  // move back from close by until every point projects inside
    camera.position.copy(centre).addScaledVector(viewFrom, d);
    camera.lookAt(centre);
    camera.updateMatrixWorld(true);
    if (fits()) break;
    d *= 1.04;
  }
  controls.target.copy(centre);
  controls.update();
}

// the strip: MCS and laughing energy around now, clips as blocks, the current time as a line
const strip = $('strip');
const sctx = strip.getContext('2d');
const fps = run.fps;
const colours = ['#6fa8dc', '#e69138', '#93c47d', '#c27ba0', '#ffd966', '#76a5af', '#e06666', '#8e7cc3'];
// now at the middle (a recorded run), or at 85% (live: nothing after it is known yet)
const nowAt = live ? 0.85 : 0.5;
function drawStrip(t) {
  const w = strip.width, h = strip.height, span = 8;
  sctx.clearRect(0, 0, w, h);
  const from = t - span * nowAt, to = from + span;
  const x = (s) => (s - from) / span * w;
  const eMax = run.clips.reduce((m, c) => Math.max(m, c.energy), Math.max(1, run.energy_max || 1));
  const shown = run.clips.filter((c) => !(c.stop < from || c.start > to));
  const topOf = (c) => h - 18 - (h - 36) * c.energy / eMax;
  for (const c of shown) {
    sctx.fillStyle = colours[c.index % colours.length] + '88';
    sctx.fillRect(x(c.start), topOf(c), x(c.stop) - x(c.start), h - 18 - topOf(c));
  }
  const line = (values, colour, scale) => {
    if (!values) return;
    sctx.strokeStyle = colour; sctx.lineWidth = 1.5; sctx.beginPath();
    const base = values.base || 0;   // live: the frame index of values[0] (older frames are let go)
    const i0 = Math.max(base, Math.floor(from * fps)), i1 = Math.min(base + values.length - 1, Math.ceil(to * fps));
    for (let i = i0; i <= i1; i++) {
      const y = h - 18 - (h - 36) * Math.max(0, values[i - base]) / scale;
      i === i0 ? sctx.moveTo(x(i / fps), y) : sctx.lineTo(x(i / fps), y);
    }
    sctx.stroke();
  };
  line(run.channels.energy, '#6aa84f', eMax);
  line(run.channels.mcs, '#e06666', 1);
  // the clips' names over the lines, each on a dark patch, so the MCS and energy lines do not run through them
  for (const c of shown) {
    const wText = sctx.measureText(c.clip).width, y = topOf(c) - 3;
    sctx.fillStyle = 'rgba(20, 20, 28, 0.8)';
    sctx.fillRect(x(c.start) + 1, y - 11, wText + 4, 14);
    sctx.fillStyle = '#ccd';
    sctx.fillText(c.clip, x(c.start) + 3, y);
  }
  sctx.strokeStyle = '#fff'; sctx.beginPath(); sctx.moveTo(w * nowAt, 0); sctx.lineTo(w * nowAt, h); sctx.stroke();
  sctx.fillStyle = '#aab';
  sctx.fillText('MCS (red), laughing energy (green), clips (blocks of height e)', 8, 14);
  for (let s = Math.ceil(from); s <= to; s++) sctx.fillText(s + ' s', x(s) + 2, h - 4);
}

function resize() {
  for (const c of [canvas, strip]) { c.width = c.clientWidth * window.devicePixelRatio; c.height = c.clientHeight * window.devicePixelRatio; }
  renderer.setSize(canvas.clientWidth, canvas.clientHeight, false);
  camera.aspect = canvas.clientWidth / Math.max(1, canvas.clientHeight);
  camera.updateProjectionMatrix();
  if (!userMoved) frameCharacter();
  sctx.font = `${11 * window.devicePixelRatio}px system-ui`;
}
window.addEventListener('resize', resize);
resize();

// a VRM's spring bones (hair, clothes) step with the time played; a jump (a seek, the first frame, a frame late
// by more than 0.1 s) starts them again from rest and lets them settle 0.5 s at the new pose, so a paused frame
// shows them as playback does (an avatar developer's review: after a seek while paused, Godette's hair covered
// her face and stayed there, one 0.1 s step having carried it from the old pose)
function springs(step) {
  if (!vrm || !vrm.springBoneManager) return;
  vrm.scene.updateMatrixWorld(true);
  if (step >= 0 && step <= 0.1) { vrm.springBoneManager.update(step); return; }
  vrm.springBoneManager.reset();
  for (let i = 0; i < 30; i++) vrm.springBoneManager.update(1 / 60);
}
state.springs = () => (vrm && vrm.springBoneManager ? [...vrm.springBoneManager.joints].map(
  (j) => j.bone.getWorldPosition(new THREE.Vector3()).toArray()) : []);

function frame() {
  if (live) { liveFrame(); return; }
  const t = Math.min(now(), run.duration);
  mixer.setTime(t);
  springs(t - lastT);
  lastT = t;
  state.animTime = mixer.time;
  state.frames += 1;
  renderer.render(scene, camera);
  drawStrip(t);
  $('seek').value = String(t / run.duration);
  $('time').textContent = `${t.toFixed(2)} / ${run.duration.toFixed(2)} s`;
  if (!hasAudio && t >= run.duration) setPlaying(false);
}
renderer.setAnimationLoop(frame);

$('play').addEventListener('click', () => setPlaying(!playing()));
$('seek').addEventListener('input', (e) => seek(Number(e.target.value) * run.duration));
$('speed').addEventListener('change', (e) => { wallOffset = now(); if (wallStart !== null) wallStart = performance.now(); speed = Number(e.target.value); audio.playbackRate = speed; });
window.addEventListener('keydown', (e) => { if (e.code === 'Space') { e.preventDefault(); setPlaying(!playing()); } });
audio.addEventListener('ended', () => setPlaying(false));

state.check = async (t) => { await seek(t); frame(); return { anim: state.animTime, audio: state.audioTime(), fps }; };
// where the character is drawn now, in CSS pixels of the page: its lowest and highest vertex, its feet (the
// foot and toe joints), and the top of the control bar (for tests: nothing of the character under the bar)
state.onScreen = () => {
  if (!live) pose(state.animTime);   // live: the pose laughlab sent last
  const rect = canvas.getBoundingClientRect();
  const y = (v) => rect.top + (1 - (v.clone().project(camera).y + 1) / 2) * rect.height;
  let lowest = -Infinity, highest = Infinity;
  eachVertex((v) => { const py = y(v); lowest = Math.max(lowest, py); highest = Math.min(highest, py); });
  const feet = [];
  // an avatar's humanoid feet and toes (its joints may have any names, or be plain nodes), else the mannequin's
  const humanoid = Object.entries(avatar.bones || {}).filter(([b]) => /foot|toes/i.test(b)).map(([, i]) => nodes[i]);
  if (humanoid.length) for (const o of humanoid) feet.push(y(o.getWorldPosition(new THREE.Vector3())));
  else root.traverse((o) => { if (o.isBone && /foot|toe/.test(o.name)) feet.push(y(o.getWorldPosition(new THREE.Vector3()))); });
  return { lowest, highest, feet: Math.max(...feet), viewTop: rect.top, viewBottom: rect.bottom,
           barTop: $('bar').getBoundingClientRect().top };
};
// live: the newest frame laughlab sent is applied on each animation frame; the strip scrolls with it
const feed = { frames: 0, k: -1, t: 0, layout: null, pending: null, last: null, ended: false, lost: false };
state.live = feed;
function meshesOf(i) {   // the meshes of node i (a glTF mesh of several primitives is a group of meshes)
  const o = nodes[i];
  if (!o) return [];
  return o.isMesh ? [o] : o.children.filter((c) => c.isMesh && c.morphTargetInfluences);
}
function applyFrame(f) {
  let i = 0;
  for (const tr of feed.layout) {
    const v = f.v;
    if (tr.path === 'rotation') tr.obj.quaternion.set(v[i], v[i + 1], v[i + 2], v[i + 3]);
    else if (tr.path === 'translation') tr.obj.position.set(v[i], v[i + 1], v[i + 2]);
    else for (const m of tr.meshes) for (let j = 0; j < tr.size; j++) m.morphTargetInfluences[j] = v[i + j];
    i += tr.size;
  }
}
// for tests: nodes' local rotation and translation and their meshes' morph weights, as the page holds them now
state.localOf = (indices) => indices.map((i) => ({ q: nodes[i].quaternion.toArray(), p: nodes[i].position.toArray(),
                                                   w: meshesOf(i).map((m) => Array.from(m.morphTargetInfluences)) }));
let wallLast = performance.now();
function liveFrame() {
  const f = feed.pending;
  if (f && feed.layout) { applyFrame(f); feed.pending = null; feed.last = f; feed.k = f.k; feed.t = f.t; }
  const wall = performance.now(), dt = Math.max(0, Math.min(0.1, (wall - wallLast) / 1000));
  wallLast = wall;
  if (vrm && vrm.springBoneManager) { vrm.scene.updateMatrixWorld(true); vrm.springBoneManager.update(dt); }
  state.frames += 1;
  renderer.render(scene, camera);
  drawStrip(feed.t);
  $('time').textContent = feed.ended ? `ended at ${feed.t.toFixed(2)} s` : feed.lost ? 'laughlab is gone'
    : feed.k < 0 ? 'waiting for laughlab\u2026' : `live ${feed.t.toFixed(2)} s`;
}
if (live) {
  for (const id of ['play', 'seek', 'speed']) $(id).hidden = true;
  $('speed').parentElement.hidden = true;
  const clipIndex = {}, keep = Math.ceil(12 * fps);   // 12 s of frames: more than the strip's 8 s
  feed.held = () => ({ mcs: run.channels.mcs ? run.channels.mcs.length : 0, clips: run.clips.length });
  const es = new EventSource('./events');
  es.addEventListener('layout', (e) => {
    feed.layout = JSON.parse(e.data).map(([node, path, size]) => ({ obj: nodes[node], path, size,
                                                                    meshes: path === 'weights' ? meshesOf(node) : [] }));
  });
  es.onmessage = (e) => {
    const f = JSON.parse(e.data);
    feed.pending = f;
    feed.frames += 1;
    // the strip's channels and clips: only what it can still show is kept (a page open for days grew by
    // 60 values a second, and every clip, walked on each frame)
    for (const [name, value] of [['mcs', f.mcs], ['energy', f.energy]]) {
      let a = run.channels[name];
      if (!a) { a = run.channels[name] = []; a.base = f.k; }
      a[f.k - a.base] = value;
      if (a.length > 2 * keep) { a.splice(0, a.length - keep); a.base = f.k - keep + 1; }
    }
    run.energy_max = Math.max(run.energy_max, f.energy);
    for (const c of run.clips) if (c.open) c.stop = f.t;
    if (run.clips.length > 64) run.clips = run.clips.filter((c) => c.open || c.stop > f.t - 12);
    for (const [kind, clip, energy] of f.clips || []) {
      if (kind === 'start') {
        if (!(clip in clipIndex)) clipIndex[clip] = Object.keys(clipIndex).length;
        run.clips.push({ clip, start: f.t, stop: f.t, energy, index: clipIndex[clip], open: true });
      } else for (const c of run.clips) if (c.open && c.clip === clip) c.open = false;
    }
  };
  es.addEventListener('end', () => { feed.ended = true; es.close(); });
  es.onerror = () => { if (!feed.ended) { feed.lost = true; es.close(); } };
} else for (const id of ['play', 'seek']) $(id).disabled = false;
state.ready = true;
state.audioTime = () => (hasAudio ? audio.currentTime : now());
state.seek = seek;
// ?selftest=T: seek to T s, draw, and report the animation and audio clocks in the title (for tests)
const selftest = new URLSearchParams(location.search).get('selftest');
if (selftest !== null) {
  await seek(Number(selftest));
  frame();
  document.title = JSON.stringify({ ready: true, anim: state.animTime, audio: state.audioTime(), fps,
                                    audioLoaded: hasAudio ? audio.readyState : -1, error: state.error });
}
