// laughlab viewer: the run's character.glb in sync with its audio, the MCS and laughing energy
// scrolling below with the clips as blocks (cf. van Duijn 2014, Figs. 3.2 and 4.2).
// The audio element is the clock: the animation shows audio.currentTime; without audio a wall clock does.
import * as THREE from 'three';
import { GLTFLoader } from './vendor/three/examples/jsm/loaders/GLTFLoader.js';
import { OrbitControls } from './vendor/three/examples/jsm/controls/OrbitControls.js';

const $ = (id) => document.getElementById(id);
const state = { ready: false, error: null, animTime: 0, frames: 0 };
window.laughlab = state;
window.addEventListener('error', (e) => { state.error = String(e.message || e); document.title = 'error: ' + state.error; });
window.addEventListener('unhandledrejection', (e) => { state.error = String(e.reason); document.title = 'error: ' + state.error; });

const run = await (await fetch('./run.json')).json();
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
camera.position.set(0.5, 1.25, 3.9);
const controls = new OrbitControls(camera, canvas);
controls.target.set(0, 0.95, 0);
controls.update();

// a user's avatar (--character): a VRM goes through three-vrm (MToon materials, spring bones); the run is
// baked into the file's first animation (bones and morph weights), so the mixer plays it as it plays ours
const avatar = run.avatar || { vrm: false, bones: {}, scale: 1 };
const loader = new GLTFLoader();
if (avatar.vrm) {
  const { VRMLoaderPlugin } = await import('./vendor/three_vrm/three-vrm.module.min.js');
  loader.register((parser) => new VRMLoaderPlugin(parser, { autoUpdateHumanBones: false }));
}
const gltf = await loader.loadAsync('./character.glb');
const vrm = gltf.userData.vrm || null;
scene.add(vrm ? vrm.scene : gltf.scene);
const mixer = new THREE.AnimationMixer(vrm ? vrm.scene : gltf.scene);
const action = mixer.clipAction(gltf.animations[0]);
action.play();
if (avatar.facing < 0) (vrm ? vrm.scene : gltf.scene).rotation.y = Math.PI;  // VRM 0.x faces -Z: turn it to the camera
if (avatar.file) {  // frame the avatar as the 1.78 m mannequin is framed
  const box = new THREE.Box3().setFromObject(vrm ? vrm.scene : gltf.scene);
  const scale = Math.max(0.2, (box.max.y - Math.min(0, box.min.y)) / 1.78);
  camera.position.multiplyScalar(scale);
  controls.target.multiplyScalar(scale);
  controls.update();
}
// node index -> its object, for the tests' check of the joints' world positions
const nodes = {};
(vrm ? vrm.scene : gltf.scene).traverse((o) => {
  const a = gltf.parser.associations.get(o);
  if (a && a.nodes !== undefined && !(a.nodes in nodes)) nodes[a.nodes] = o;
});
state.world = (indices) => indices.map((i) => { const p = new THREE.Vector3(); nodes[i].getWorldPosition(p); return p.toArray(); });
state.morphs = () => { const out = {}; (vrm ? vrm.scene : gltf.scene).traverse((o) => {
  const a = gltf.parser.associations.get(o);
  if (o.morphTargetInfluences && a && a.meshes !== undefined) out[o.name] = Array.from(o.morphTargetInfluences);
}); return out; };
state.vrm = vrm !== null;
let lastT = 0;

// the strip: MCS and laughing energy around now, clips as blocks, the current time as a line
const strip = $('strip');
const sctx = strip.getContext('2d');
const fps = run.fps;
const colours = ['#6fa8dc', '#e69138', '#93c47d', '#c27ba0', '#ffd966', '#76a5af', '#e06666', '#8e7cc3'];
function drawStrip(t) {
  const w = strip.width, h = strip.height, span = 8;
  sctx.clearRect(0, 0, w, h);
  const x = (s) => (s - (t - span / 2)) / span * w;
  const eMax = Math.max(1, ...run.clips.map((c) => c.energy), run.energy_max || 1);
  for (const c of run.clips) {
    if (c.stop < t - span / 2 || c.start > t + span / 2) continue;
    sctx.fillStyle = colours[c.index % colours.length] + '88';
    const top = h - 18 - (h - 36) * c.energy / eMax;
    sctx.fillRect(x(c.start), top, x(c.stop) - x(c.start), h - 18 - top);
    sctx.fillStyle = '#ccd';
    sctx.fillText(c.clip, x(c.start) + 3, top - 3);
  }
  const line = (values, colour, scale) => {
    if (!values) return;
    sctx.strokeStyle = colour; sctx.lineWidth = 1.5; sctx.beginPath();
    const i0 = Math.max(0, Math.floor((t - span / 2) * fps)), i1 = Math.min(values.length - 1, Math.ceil((t + span / 2) * fps));
    for (let i = i0; i <= i1; i++) {
      const y = h - 18 - (h - 36) * Math.max(0, values[i]) / scale;
      i === i0 ? sctx.moveTo(x(i / fps), y) : sctx.lineTo(x(i / fps), y);
    }
    sctx.stroke();
  };
  line(run.channels.energy, '#6aa84f', eMax);
  line(run.channels.mcs, '#e06666', 1);
  sctx.strokeStyle = '#fff'; sctx.beginPath(); sctx.moveTo(w / 2, 0); sctx.lineTo(w / 2, h); sctx.stroke();
  sctx.fillStyle = '#aab';
  sctx.fillText('MCS (red), laughing energy (green), clips (blocks of height e)', 8, 14);
  for (let s = Math.ceil(t - span / 2); s <= t + span / 2; s++) sctx.fillText(s + ' s', x(s) + 2, h - 4);
}

function resize() {
  for (const c of [canvas, strip]) { c.width = c.clientWidth * window.devicePixelRatio; c.height = c.clientHeight * window.devicePixelRatio; }
  renderer.setSize(canvas.clientWidth, canvas.clientHeight, false);
  camera.aspect = canvas.clientWidth / canvas.clientHeight;
  camera.updateProjectionMatrix();
  sctx.font = `${11 * window.devicePixelRatio}px system-ui`;
}
window.addEventListener('resize', resize);
resize();

function frame() {
  const t = Math.min(now(), run.duration);
  mixer.setTime(t);
  if (vrm && vrm.springBoneManager) { vrm.scene.updateMatrixWorld(true); vrm.springBoneManager.update(Math.max(0, Math.min(0.1, t - lastT))); }
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
