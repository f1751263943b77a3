// Gecko's viewer: loads a stored result's GLB (the same file engines get, with the scene and
// the overlays), plays its animation and shows its contact timeline.
// The GLB is already in glTF's frame (y up, metres): nothing here converts axes.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';

const ROUTES = {
  plan: (id) => `/v1/plans/${id}`,
  step: (id) => `/v1/twister/steps/${id}`,
  jump: (id) => `/v1/jumps/${id}`,
};
const ID_PATTERN = /^[0-9a-f]{32}$/;
const CONTACT_RADIUS = 0.025; // m

const $ = (id) => document.getElementById(id);
const canvas = $('view');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
const world = new THREE.Scene();
world.background = new THREE.Color(0xdfe6ee);
world.add(new THREE.HemisphereLight(0xffffff, 0x8a8070, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.8);
sun.position.set(3, 8, 5);
world.add(sun);
const camera = new THREE.PerspectiveCamera(45, 1, 0.05, 500);
camera.position.set(3, 2, 4);
const controls = new OrbitControls(camera, canvas);
controls.enableDamping = true;
const loader = new GLTFLoader();
const clock = new THREE.Clock();

const view = {
  root: null, // the loaded glTF scene
  character: null, // the root link's node
  mixer: null,
  action: null,
  start: 0,
  end: 0,
  time: 0,
  playing: false,
  phases: [],
  contactGroups: [],
  lastCharacterPosition: new THREE.Vector3(),
  firstPaintMs: null,
  paintedAt: null,
  openedAt: 0,
};

function setMessage(text, state) {
  $('message').textContent = text;
  if (state) document.body.dataset.state = state;
}

function resize() {
  const { clientWidth: w, clientHeight: h } = canvas;
  if (w === 0 || h === 0) return;
  if (canvas.width !== Math.floor(w * renderer.getPixelRatio())
      || canvas.height !== Math.floor(h * renderer.getPixelRatio())) {
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  }
}

function clear() {
  if (view.root) world.remove(view.root);
  for (const group of view.contactGroups) world.remove(group);
  Object.assign(view, { root: null, character: null, mixer: null, action: null, phases: [],
    contactGroups: [] });
}

// Contact points of each phase (the GLB's 'contacts' node, one Points child per phase)
// drawn as small spheres, and the outline of the phase's static-equilibrium COM region
// (a LineLoop under the phase node), both shown while their phase is current.
function contactSpheres(contacts) {
  const groups = [];
  const geometry = new THREE.SphereGeometry(CONTACT_RADIUS, 12, 8);
  const material = new THREE.MeshStandardMaterial({ color: 0x1a73f2, roughness: 0.5 });
  for (const phase of contacts ? contacts.children : []) {
    const group = new THREE.Group();
    phase.updateWorldMatrix(true, true);
    const outlines = [];
    phase.traverse((object) => {
      if (object.isLine) outlines.push(object);
      if (!object.isPoints) return;
      object.visible = false;
      const positions = object.geometry.getAttribute('position');
      for (let k = 0; k < positions.count; k++) {
        const sphere = new THREE.Mesh(geometry, material);
        sphere.position.fromBufferAttribute(positions, k).applyMatrix4(object.matrixWorld);
        group.add(sphere);
      }
    });
    for (const outline of outlines) {
      const copy = outline.clone();
      copy.matrixAutoUpdate = false;
      copy.matrix.copy(outline.matrixWorld);
      copy.material = new THREE.LineBasicMaterial({ color: 0x1fb040 });
      copy.name = 'equilibrium';
      outline.visible = false;
      group.add(copy);
    }
    group.visible = false;
    world.add(group);
    groups.push(group);
  }
  return groups;
}

function buildTimeline(phases, start, end) {
  const span = Math.max(end - start, 1e-9);
  const pos = (t) => `${(100 * (t - start)) / span}%`;
  const width = (t0, t1) => `${(100 * Math.max(t1 - t0, 0)) / span}%`;
  const phaseTrack = document.querySelector('#phases .track');
  phaseTrack.replaceChildren();
  phases.forEach((phase, index) => {
    const block = document.createElement('div');
    block.className = 'phase';
    block.dataset.index = String(index);
    block.dataset.t0 = String(phase.t0);
    block.dataset.t1 = String(phase.t1);
    block.dataset.limbs = phase.limbs.join(',');
    block.style.left = pos(phase.t0);
    block.style.width = width(phase.t0, phase.t1);
    block.title = `phase ${index}: ${phase.t0.toFixed(2)}-${phase.t1.toFixed(2)} s, `
      + `${phase.limbs.length ? phase.limbs.join(', ') : 'no contact (flight)'}`;
    phaseTrack.appendChild(block);
  });
  const limbs = [...new Set(phases.flatMap((phase) => phase.limbs))].sort();
  const rows = $('limbs');
  rows.replaceChildren();
  for (const limb of limbs) {
    const row = document.createElement('div');
    row.className = 'row limb';
    row.dataset.limb = limb;
    const label = document.createElement('span');
    label.className = 'label';
    label.textContent = limb;
    const track = document.createElement('div');
    track.className = 'track';
    phases.forEach((phase, index) => {
      if (!phase.limbs.includes(limb)) return;
      const bar = document.createElement('div');
      bar.className = 'span';
      bar.dataset.index = String(index);
      bar.style.left = pos(phase.t0);
      bar.style.width = width(phase.t0, phase.t1);
      track.appendChild(bar);
    });
    row.append(label, track);
    rows.appendChild(row);
  }
  for (const track of document.querySelectorAll('#timeline .track')) {
    track.addEventListener('click', (event) => {
      const box = track.getBoundingClientRect();
      setTime(start + ((event.clientX - box.left) / box.width) * span);
    });
  }
}

function currentPhase(t) {
  let found = -1;
  view.phases.forEach((phase, index) => {
    if (t >= phase.t0 - 1e-9 && t <= phase.t1 + 1e-9 && found === -1) found = index;
  });
  if (found === -1 && view.phases.length) found = t < view.phases[0].t0 ? 0 : view.phases.length - 1;
  return found;
}

function showTime(t) {
  const index = currentPhase(t);
  view.contactGroups.forEach((group, k) => { group.visible = k === index; });
  for (const element of document.querySelectorAll('#timeline .phase, #timeline .span')) {
    element.classList.toggle('current', Number(element.dataset.index) === index);
  }
  const track = document.querySelector('#phases .track');
  const timeline = $('timeline').getBoundingClientRect();
  const box = track.getBoundingClientRect();
  const fraction = (t - view.start) / Math.max(view.end - view.start, 1e-9);
  $('cursor').style.left = `${box.left - timeline.left + fraction * box.width}px`;
  $('scrub').value = String(t);
  $('clock').textContent = `${t.toFixed(2)} / ${view.end.toFixed(2)} s`;
  document.body.dataset.phase = String(index);
}

function setTime(t) {
  view.time = Math.min(Math.max(t, view.start), view.end);
  if (view.action) {
    view.action.time = view.time;
    view.mixer.update(0);
  }
  showTime(view.time);
}

function play() {
  if (!view.action) return;
  if (view.time >= view.end) setTime(view.start);
  view.playing = true;
  $('play').textContent = 'Pause';
}

function pause() {
  view.playing = false;
  $('play').textContent = 'Play';
}

function frameCamera() {
  const box = new THREE.Box3().setFromObject(view.character || view.root);
  const center = box.getCenter(new THREE.Vector3());
  const size = Math.max(box.getSize(new THREE.Vector3()).length(), 0.5);
  controls.target.copy(center);
  camera.position.copy(center).add(new THREE.Vector3(1.2 * size, 0.6 * size, 1.6 * size));
  camera.near = size / 100;
  camera.far = size * 500;
  camera.updateProjectionMatrix();
  controls.update();
  if (view.character) view.character.getWorldPosition(view.lastCharacterPosition);
}

async function open(kind, id) {
  if (!ROUTES[kind]) throw new Error(`unknown kind '${kind}'`);
  if (!ID_PATTERN.test(id)) {
    setMessage(`'${id}' is not a result id (32 hexadecimal digits)`, 'error');
    return;
  }
  pause();
  view.openedAt = performance.now();
  view.firstPaintMs = null;
  setMessage(`loading ${kind} ${id} ...`, 'loading');
  let gltf;
  try {
    const response = await fetch(`${ROUTES[kind](id)}.glb?scene=true&overlays=true`);
    if (!response.ok) {
      const body = await response.json().catch(() => ({}));
      const reason = body.error ? body.error.message : response.statusText;
      setMessage(`${kind} ${id}: ${reason}`, 'error');
      return;
    }
    gltf = await loader.parseAsync(await response.arrayBuffer(), '');
  } catch (error) {
    setMessage(`${kind} ${id}: ${error}`, 'error');
    return;
  }
  clear();
  const info = gltf.scene.userData.gecko || {};
  view.root = gltf.scene;
  world.add(view.root);
  view.character = view.root.children.find(
    (child) => !['scene', 'com', 'contacts'].includes(child.name)) || null;
  const contacts = view.root.getObjectByName('contacts');
  view.contactGroups = contactSpheres(contacts);
  const com = view.root.getObjectByName('com');
  if (com) com.traverse((object) => { if (object.material) object.material.depthTest = false; });
  if (com) com.renderOrder = 1;
  view.phases = info.phases || [];
  view.start = Number(info.start || 0);
  view.end = Number(info.end || 0);
  view.mixer = new THREE.AnimationMixer(view.root);
  if (gltf.animations.length) {
    view.action = view.mixer.clipAction(gltf.animations[0]);
    view.action.play();
  }
  const scrub = $('scrub');
  scrub.min = String(view.start);
  scrub.max = String(view.end);
  buildTimeline(view.phases, view.start, view.end);
  setTime(view.start);
  frameCamera();
  const params = new URLSearchParams({ [kind]: id });
  history.replaceState(null, '', `/viewer?${params}`);
  $('kind').value = kind;
  $('result-id').value = id;
  const label = `${info.kind || kind} ${id}: ${info.character || ''} on ${info.scene || ''}, `
    + `${info.status || ''}, ${(view.end - view.start).toFixed(2)} s, ${view.phases.length} phases`;
  setMessage(label, 'ready');
}

async function listRecent() {
  try {
    const response = await fetch('/v1/results?limit=50');
    if (!response.ok) return;
    const select = $('recent');
    for (const entry of await response.json()) {
      const option = document.createElement('option');
      option.value = `${entry.kind}:${entry.id}`;
      option.textContent = `${entry.kind} ${entry.id.slice(0, 8)} ${entry.character} on `
        + `${entry.scene}, ${entry.status}, ${entry.duration.toFixed(1)} s`;
      select.appendChild(option);
    }
  } catch (error) {
    console.warn('no result list', error);
  }
}

function animate() {
  requestAnimationFrame(animate);
  const delta = clock.getDelta();
  resize();
  if (view.playing && view.action) {
    const next = view.time + delta * Number($('speed').value);
    if (next >= view.end) {
      setTime(view.end);
      pause();
    } else {
      setTime(next);
    }
  }
  if ($('follow').checked && view.character) {
    const position = view.character.getWorldPosition(new THREE.Vector3());
    const shift = position.clone().sub(view.lastCharacterPosition);
    shift.y = 0;
    camera.position.add(shift);
    controls.target.add(shift);
    view.lastCharacterPosition.copy(position);
  }
  controls.update();
  renderer.render(world, camera);
  if (view.root && view.firstPaintMs === null && document.body.dataset.state === 'ready') {
    view.paintedAt = performance.now();
    view.firstPaintMs = view.paintedAt - view.openedAt;
    document.body.dataset.painted = 'true';
  }
}

$('play').addEventListener('click', () => (view.playing ? pause() : play()));
$('scrub').addEventListener('input', (event) => { pause(); setTime(Number(event.target.value)); });
$('open').addEventListener('click', () => open($('kind').value, $('result-id').value.trim()));
$('result-id').addEventListener('keydown', (event) => {
  if (event.key === 'Enter') open($('kind').value, $('result-id').value.trim());
});
$('recent').addEventListener('change', (event) => {
  const [kind, id] = event.target.value.split(':');
  if (id) open(kind, id);
});
window.addEventListener('keydown', (event) => {
  if (event.code === 'Space' && event.target === document.body) {
    event.preventDefault();
    if (view.playing) pause(); else play();
  }
});

// For tests and scripts: the viewer's state and controls.
window.gecko = {
  open,
  play,
  pause,
  setTime,
  get time() { return view.time; },
  get start() { return view.start; },
  get end() { return view.end; },
  get phases() { return view.phases; },
  get firstPaintMs() { return view.firstPaintMs; }, // ms from opening the GLB to its first frame
  get paintedAt() { return view.paintedAt; }, // ms from the page's navigation to that frame
  // The equilibrium outline on screen (glTF frame, metres), [] when none is shown.
  get equilibrium() {
    const out = [];
    for (const group of view.contactGroups) {
      if (!group.visible) continue;
      for (const line of group.children.filter((child) => child.isLine)) {
        const positions = line.geometry.getAttribute('position');
        for (let k = 0; k < positions.count; k++) {
          const p = new THREE.Vector3().fromBufferAttribute(positions, k).applyMatrix4(line.matrix);
          out.push([p.x, p.y, p.z]);
        }
      }
    }
    return out;
  },
};

animate();
listRecent();
const query = new URLSearchParams(window.location.search);
const wanted = Object.keys(ROUTES).find((kind) => query.get(kind));
if (wanted) {
  open(wanted, query.get(wanted).trim());
} else {
  setMessage('pick a stored result, or paste the id a plan, step or jump answered with', 'empty');
}
