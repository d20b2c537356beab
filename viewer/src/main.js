// manyhands 3-D plan viewer: `/viewer?plan=ID` shows a plan job's scene, its robots (from their
// URDF, via urdf-loader) and the motion on its time axis with a slider, play/pause, grasp/release
// marks, held objects moving with the hand, and for multi-robot plans the phase-space path.
//
// URL parameters: `plan` (job id), `t` (start at this time, paused), `play=1` (start playing),
// `token` (bearer token of a server started with --token), `scene` (show a scene without a plan),
// `geometry=collision` (draw the robots' collision geometry instead of their visual geometry).
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import URDFLoader from 'urdf-loader';
import { buildScene, poseMatrix } from './scene.js';
import { timelineOfJob, phaseAt, UNTIMED_SPEED } from './timeline.js';
import { drawPhase, phasePairs } from './phase.js';
import { addVisuals, setGeometryMode } from './visuals.js';

const params = new URLSearchParams(window.location.search);
const token = params.get('token');
const state = {
  ready: false,
  errors: [],
  time: 0,
  duration: 0,
  plan: params.get('plan'),
  geometry: 'visual',
  visuals: { drawn: 0, failed: 0 },
};
window.__manyhandsViewer = state;

// Console errors and uncaught exceptions are collected in `#errors` (tests read the page's DOM).
const errorsEl = document.getElementById('errors');
function noteError(msg) {
  state.errors.push(msg);
  errorsEl.textContent = state.errors.join('\n');
}
const origError = console.error.bind(console);
console.error = (...args) => {
  noteError(args.map(String).join(' '));
  origError(...args);
};
window.addEventListener('error', (e) => noteError(String(e.message || e)));
window.addEventListener('unhandledrejection', (e) => noteError(String(e.reason)));

const statusEl = document.getElementById('status');
function setStatus(text, isError = false) {
  statusEl.textContent = text;
  statusEl.className = isError ? 'error' : '';
}

async function api(path, as = 'json') {
  const headers = token ? { Authorization: `Bearer ${token}` } : {};
  let res = await fetch(path, { headers });
  // A busy server (503 with Retry-After, e.g. its heavy lane full of mesh reads): wait, retry.
  for (let tries = 0; res.status === 503 && res.headers.has('retry-after') && tries < 8; tries++) {
    const wait = Math.min(Math.max(parseFloat(res.headers.get('retry-after')) || 1, 0.2), 10);
    await new Promise((r) => setTimeout(r, wait * 1000));
    res = await fetch(path, { headers });
  }
  if (!res.ok) {
    let why = res.statusText;
    try {
      const body = await res.json();
      why = body.error ? `${body.error.message || body.error}` : JSON.stringify(body);
    } catch (_) {
      /* not JSON */
    }
    throw new Error(`GET ${path}: ${res.status} ${why}`);
  }
  return as === 'text' ? res.text() : res.json();
}

// ---- three.js setup -------------------------------------------------------------------------
const canvas = document.getElementById('view');
/** Why this browser cannot draw WebGL (null when it can). */
function noWebGl() {
  try {
    const c = document.createElement('canvas');
    if (!(window.WebGL2RenderingContext && c.getContext('webgl2')) && !c.getContext('webgl')) {
      return 'the browser offers no WebGL context';
    }
    return null;
  } catch (e) {
    return String(e.message || e);
  }
}
let renderer = null;
let webglProblem = noWebGl();
if (!webglProblem) {
  try {
    renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    renderer.setPixelRatio(window.devicePixelRatio || 1);
  } catch (e) {
    webglProblem = String(e.message || e);
  }
}
const scene3 = new THREE.Scene();
scene3.background = new THREE.Color(0xf4f6f8);
const camera = new THREE.PerspectiveCamera(45, 1, 0.02, 200);
camera.up.set(0, 0, 1);
const controls = new OrbitControls(camera, canvas);
scene3.add(new THREE.HemisphereLight(0xffffff, 0x667788, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.4);
sun.position.set(3, -4, 6);
scene3.add(sun);
const grid = new THREE.GridHelper(10, 20, 0xb0b8c0, 0xd0d6dc);
grid.rotation.x = Math.PI / 2;
scene3.add(grid);
const world = new THREE.Group();
scene3.add(world);

function resize() {
  const w = canvas.clientWidth;
  const h = canvas.clientHeight;
  if (canvas.width !== Math.floor(w * renderer.getPixelRatio()) || canvas.height !== Math.floor(h * renderer.getPixelRatio())) {
    renderer.setSize(w, h, false);
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
  }
}

const PALETTE = [0x3b6fb6, 0x3f9b5a, 0x8a4fb0, 0xb84a4a, 0x2a9aa0, 0x7a7a2a];

/**
 * Loads each robot of the scene: its collision model from its URDF (urdf-loader) and its visual
 * geometry (`GET /v1/robots/{name}/visuals`, see visuals.js); returns Map(scene robot name → entry).
 * Links are drawn with their visual geometry when it exists and loaded, else with their
 * collision geometry (and the page says which meshes could not be drawn).
 */
async function loadRobots(scene, notes) {
  const robots = new Map();
  const models = new Map();
  let k = 0;
  for (const sr of scene.robots || []) {
    const model = sr.model || sr.name;
    if (!models.has(model)) {
      const [urdf, detail, visuals] = await Promise.all([
        api(`/v1/robots/${encodeURIComponent(model)}/urdf`, 'text'),
        api(`/v1/robots/${encodeURIComponent(model)}`),
        api(`/v1/robots/${encodeURIComponent(model)}/visuals`).catch((e) => {
          notes.push(`${model}: visual geometry not available (${e.message || e}); collision geometry drawn`);
          return null;
        }),
      ]);
      models.set(model, { urdf, detail, visuals, failedNoted: false });
    }
    const m = models.get(model);
    const { urdf, detail, visuals } = m;
    const loader = new URDFLoader();
    loader.parseVisual = false;
    loader.parseCollision = true;
    let skipped = 0;
    loader.loadMeshCb = (_path, _manager, _material, done) => {
      skipped += 1;
      done(null);
    };
    const robot = loader.parse(urdf);
    if (skipped) notes.push(`${sr.name}: ${skipped} collision mesh geometries not drawn`);
    const mat = new THREE.MeshStandardMaterial({ color: PALETTE[k % PALETTE.length], roughness: 0.55, metalness: 0.1 });
    k += 1;
    robot.traverse((o) => {
      if (o.isMesh) o.material = mat;
    });
    const vis = await addVisuals(robot, visuals, mat, (path) => api(path, 'text'));
    state.visuals.drawn += vis.drawn;
    state.visuals.failed += vis.failed.length;
    if (vis.failed.length && !m.failedNoted) {
      // Once per model: every robot of the model fails alike.
      m.failedNoted = true;
      notes.push(
        `${model}: ${vis.failed.length} visual geometries not drawn, their links drawn with their collision geometry ` +
          `(${vis.failed.slice(0, 2).join('; ')}${vis.failed.length > 2 ? '; …' : ''})`,
      );
    }
    const base = new THREE.Group();
    base.matrixAutoUpdate = false;
    base.matrix.copy(poseMatrix(sr.base_pose));
    base.add(robot);
    world.add(base);
    // Joints not moved by the plan stay at the scene's start configuration (else 0 within limits).
    const start = (sr.configs && sr.start && sr.configs[sr.start]) || {};
    for (const j of detail.joints) {
      const v = j.name in start ? start[j.name] : Math.min(Math.max(0, j.lower), j.upper);
      robot.setJointValue(j.name, v);
    }
    const eeLink = new Map(detail.end_effectors.map((e) => [e.name, e.parent_link]));
    robots.set(sr.name, { robot, eeLink, base, visualLinks: vis.links });
  }
  return robots;
}

/** Visual or collision geometry for every robot (the `geometry` URL parameter, the checkbox). */
const geometryBox = document.getElementById('geometry-box');
const showCollision = document.getElementById('show-collision');
function applyGeometryMode() {
  state.geometry = showCollision.checked ? 'collision' : 'visual';
  for (const e of robots.values()) setGeometryMode(e.robot, e.visualLinks, state.geometry);
  world.updateMatrixWorld(true);
}
showCollision.addEventListener('change', applyGeometryMode);

// ---- the plan on its time axis --------------------------------------------------------------
let timeline = null;
let robots = new Map();
let objects = new Map();
let obstacleGroups = [];
let snapshots = []; // object states after each event: {time, poses: Map, holders: Map}
let setters = []; // per track variable: (value) => void

function bindTrack(track) {
  setters = track.names.map((name) => {
    const slash = name.indexOf('/');
    const robotName = slash >= 0 ? name.slice(0, slash) : [...robots.keys()][0];
    const joint = slash >= 0 ? name.slice(slash + 1) : name;
    const entry = robots.get(robotName);
    if (!entry || !(joint in entry.robot.joints)) {
      throw new Error(`plan variable '${name}' is not a joint of the scene's robots`);
    }
    return (v) => entry.robot.setJointValue(joint, v);
  });
}

function poseRobots(t) {
  const values = timeline.track.at(t);
  values.forEach((v, i) => setters[i](v));
  world.updateMatrixWorld(true);
}

function handLink(e) {
  const entry = robots.get(e.robot) || [...robots.values()][0];
  const linkName = entry.eeLink.get(e.end_effector) || e.end_effector;
  const link = entry.robot.links[linkName];
  if (!link) throw new Error(`event ${e.kind}: no link '${linkName}' for end effector '${e.end_effector}'`);
  return link;
}

function objectWorld(name, holders, poses) {
  const held = holders.get(name);
  if (held && held.length) return held[0].link.matrixWorld.clone().multiply(held[0].rel);
  return poses.get(name).clone();
}

/** Object poses and holders after every event, computed once (scrubbing reads them). */
function computeSnapshots() {
  let poses = new Map([...objects].map(([n, g]) => [n, g.matrix.clone()]));
  let holders = new Map();
  snapshots = [{ time: -Infinity, poses, holders }];
  for (const e of timeline.events) {
    if (!objects.has(e.object)) continue;
    poseRobots(e.time);
    poses = new Map(poses);
    holders = new Map([...holders].map(([k, v]) => [k, [...v]]));
    const link = handLink(e);
    const current = objectWorld(e.object, holders, poses);
    const list = holders.get(e.object) || [];
    if (e.kind === 'grasp') {
      const rel = link.matrixWorld.clone().invert().multiply(current);
      list.push({ link, rel });
      holders.set(e.object, list);
    } else if (e.kind === 'release') {
      const rest = list.filter((h) => h.link !== link);
      poses.set(e.object, current);
      // The remaining holders keep the object where it is now.
      holders.set(
        e.object,
        rest.map((h) => ({ link: h.link, rel: h.link.matrixWorld.clone().invert().multiply(current) })),
      );
    }
    snapshots.push({ time: e.time, poses, holders });
  }
}

function setTime(t) {
  state.time = Math.min(Math.max(t, 0), state.duration);
  poseRobots(state.time);
  let snap = snapshots[0];
  for (const s of snapshots) if (s.time <= state.time) snap = s;
  for (const [name, group] of objects) {
    group.matrix.copy(objectWorld(name, snap.holders, snap.poses));
  }
  world.updateMatrixWorld(true);
  slider.value = String(state.time);
  timeLabel.textContent = `${state.time.toFixed(2)} / ${state.duration.toFixed(2)} s`;
  if (timeline.phase) drawPhase(phaseCanvas, timeline.phase, phaseAt(timeline.phase, state.time), phaseShown());
}

/** The robot pairs shown in the phase panel: all of them for two or three robots, else the pair chosen. */
const phasePick = document.getElementById('phase-pair');
function phaseShown() {
  if (phasePick.hidden || phasePick.value === 'all') return null;
  return [parseInt(phasePick.value, 10)];
}
function setupPhasePick(phase) {
  const ps = phasePairs(phase.robots.length);
  if (ps.length <= 3) return;
  ps.forEach(([i, j], k) => {
    const o = document.createElement('option');
    o.value = String(k);
    o.textContent = `φ ${phase.robots[i]} × φ ${phase.robots[j]}`;
    phasePick.appendChild(o);
  });
  const all = document.createElement('option');
  all.value = 'all';
  all.textContent = `all ${ps.length} pairs`;
  phasePick.appendChild(all);
  phasePick.value = '0';
  phasePick.hidden = false;
  phasePick.addEventListener('change', () => setTime(state.time));
}

// ---- controls -------------------------------------------------------------------------------
const slider = document.getElementById('time');
const timeLabel = document.getElementById('time-label');
const playBtn = document.getElementById('play');
const marks = document.getElementById('marks');
const phaseCanvas = document.getElementById('phase');
let playing = false;
let last = null;

slider.addEventListener('input', () => {
  playing = false;
  playBtn.textContent = 'Play';
  setTime(parseFloat(slider.value));
});
playBtn.addEventListener('click', () => {
  playing = !playing;
  if (playing && state.time >= state.duration) setTime(0);
  playBtn.textContent = playing ? 'Pause' : 'Play';
  last = null;
});

function placeMarks() {
  marks.innerHTML = '';
  for (const e of timeline.events) {
    const m = document.createElement('div');
    m.className = `mark ${e.kind}`;
    m.style.left = `${state.duration > 0 ? (100 * e.time) / state.duration : 0}%`;
    m.title = `${e.time.toFixed(2)} s: ${e.kind} ${e.object || ''} (${e.robot || ''} ${e.end_effector || ''})`;
    marks.appendChild(m);
  }
}

function frameCamera() {
  const box = new THREE.Box3();
  for (const { base } of robots.values()) box.expandByObject(base);
  for (const g of objects.values()) box.expandByObject(g);
  if (box.isEmpty()) box.expandByObject(world);
  if (box.isEmpty()) box.set(new THREE.Vector3(-1, -1, 0), new THREE.Vector3(1, 1, 1));
  focusBox = box.clone();
  const c = box.getCenter(new THREE.Vector3());
  const r = Math.max(box.getSize(new THREE.Vector3()).length() * 0.5, 0.5);
  const d = r / Math.sin((camera.fov * Math.PI) / 360);
  const dir = new THREE.Vector3(-0.5, -0.65, 0.6).normalize();
  camera.position.copy(c).add(dir.multiplyScalar(d));
  controls.target.copy(c);
  controls.update();
}

/** Obstacles between the camera and what it looks at are drawn faded (walls of a room). */
const occluderRay = new THREE.Raycaster();
let focusBox = null;
function fadeOccluders() {
  const hit = new Set();
  // Rays to the centre and the corners of what the camera was framed on.
  const b = focusBox;
  const points = [controls.target.clone()];
  if (b && !b.isEmpty()) {
    for (const x of [b.min.x, b.max.x]) for (const y of [b.min.y, b.max.y]) for (const z of [b.min.z, b.max.z]) points.push(new THREE.Vector3(x, y, z));
  }
  for (const p of points) {
    const to = p.sub(camera.position);
    occluderRay.set(camera.position, to.clone().normalize());
    occluderRay.far = to.length();
    for (const h of occluderRay.intersectObjects(obstacleGroups, true)) {
      let o = h.object;
      while (o && !obstacleGroups.includes(o)) o = o.parent;
      if (o) hit.add(o);
    }
  }
  for (const g of obstacleGroups) {
    const faded = hit.has(g);
    g.traverse((o) => {
      if (!o.isMesh || o.material.userData.faded === faded) return;
      o.material.userData.faded = faded;
      o.material.transparent = faded;
      o.material.opacity = faded ? 0.18 : 1;
      o.material.depthWrite = !faded;
    });
  }
}

function render(now) {
  resize();
  if (playing && timeline) {
    if (last !== null) {
      const t = state.time + (now - last) / 1000;
      setTime(t);
      if (t >= state.duration) {
        playing = false;
        playBtn.textContent = 'Play';
      }
    }
    last = now;
  }
  controls.update();
  fadeOccluders();
  renderer.render(scene3, camera);
  writeProbe();
  requestAnimationFrame(render);
}

/**
 * Where the objects' centres and the end effectors' links are on the canvas (CSS pixels from
 * its top left), as JSON in the hidden `#probe` element: tests read it beside a screenshot.
 */
const probeEl = document.getElementById('probe');
function writeProbe() {
  const w = canvas.clientWidth;
  const h = canvas.clientHeight;
  const px = (v) => {
    const p = v.clone().project(camera);
    return [Math.round(((p.x + 1) / 2) * w), Math.round(((1 - p.y) / 2) * h)];
  };
  const out = { canvas: [w, h], geometry: state.geometry, visuals: state.visuals, objects: {}, hands: {} };
  for (const [name, g] of objects) {
    const b = new THREE.Box3().setFromObject(g);
    if (!b.isEmpty()) out.objects[name] = px(b.getCenter(new THREE.Vector3()));
  }
  for (const [rn, e] of robots) {
    for (const [ee, linkName] of e.eeLink) {
      const link = e.robot.links[linkName];
      if (link) out.hands[`${rn}/${ee}`] = px(link.getWorldPosition(new THREE.Vector3()));
    }
  }
  const text = JSON.stringify(out);
  if (probeEl.textContent !== text) probeEl.textContent = text;
}

/** Job kinds whose result holds no motion, and what they answer instead. */
const NOTHING_TO_DRAW = {
  collision_sweep: 'collision counts of sampled configurations',
  grasp_list: 'a grasp list (GET /v1/grasp-lists)',
};

async function listPlans() {
  const list = await api('/v1/plans');
  const ul = document.getElementById('plans');
  for (const j of (list.jobs || []).slice(0, 50)) {
    const li = document.createElement('li');
    const label = `${j.id} — ${j.kind} (${j.state})`;
    let why = null;
    if (j.kind in NOTHING_TO_DRAW) why = `nothing to draw: answers ${NOTHING_TO_DRAW[j.kind]}`;
    else if (j.state !== 'succeeded') why = j.state === 'queued' || j.state === 'running' ? 'no motion yet' : 'no motion';
    if (why) {
      li.textContent = `${label}: ${why}`;
      li.className = 'nodraw';
    } else {
      const a = document.createElement('a');
      a.href = `?plan=${encodeURIComponent(j.id)}${token ? `&token=${encodeURIComponent(token)}` : ''}`;
      a.textContent = label;
      li.appendChild(a);
    }
    ul.appendChild(li);
  }
  document.getElementById('plan-list').hidden = false;
}

async function main() {
  const notes = [];
  if (webglProblem) {
    // Nothing can be drawn: say so (and still list the plans when none is given).
    canvas.hidden = true;
    setStatus(
      `This browser cannot show the 3-D view: WebGL is not available (${webglProblem}). ` +
        'Enable WebGL / hardware acceleration, or use another browser; the plans are also at /v1/plans.',
      true,
    );
    if (!params.get('plan') && !params.get('scene')) await listPlans();
    document.title = 'manyhands viewer: no WebGL';
    state.ready = true;
    return;
  }
  const planId = params.get('plan');
  let job = null;
  let sceneName = params.get('scene');
  if (planId) {
    job = await api(`/v1/plans/${encodeURIComponent(planId)}`);
    sceneName = job.request && job.request.scene;
    // A job with no motion: say why, and show its scene (if it names one) without a time axis.
    let why = null;
    if (job.kind in NOTHING_TO_DRAW) why = `it answers ${NOTHING_TO_DRAW[job.kind]}, not a motion`;
    else if (job.state !== 'succeeded') why = `it is ${job.state}`;
    if (why) {
      notes.push(`plan ${job.id} (${job.kind}) has nothing to draw: ${why}`);
      job = null;
    }
    if (!sceneName) {
      if (why) {
        setStatus(notes.join(' · '));
        await listPlans();
        state.ready = true;
        document.title = 'manyhands viewer: ready';
        return;
      }
      throw new Error(`plan ${planId} (${job.kind}) names no scene`);
    }
  }
  if (!sceneName) {
    setStatus('No plan given: choose one below, or open /viewer?plan=ID.');
    await listPlans();
    state.ready = true;
    document.title = 'manyhands viewer: ready';
    requestAnimationFrame(render);
    return;
  }
  const scene = await api(`/v1/scenes/${encodeURIComponent(sceneName)}`);
  const built = buildScene(scene, world, sceneName, (path) => api(path, 'text'));
  objects = built.objects;
  obstacleGroups = built.obstacles;
  robots = await loadRobots(scene, notes);
  await built.loaded;
  showCollision.checked = params.get('geometry') === 'collision';
  geometryBox.hidden = ![...robots.values()].some((e) => e.visualLinks.size > 0);
  applyGeometryMode();
  notes.push(...built.notes);
  world.updateMatrixWorld(true);
  if (job) {
    timeline = timelineOfJob(job);
    bindTrack(timeline.track);
    state.duration = timeline.track.duration;
    slider.max = String(state.duration);
    computeSnapshots();
    placeMarks();
    if (timeline.phase) {
      setupPhasePick(timeline.phase);
      phaseCanvas.hidden = false;
    }
    document.getElementById('controls').hidden = false;
    const t0 = params.has('t') ? parseFloat(params.get('t')) : 0;
    setTime(Number.isFinite(t0) ? t0 : 0);
    if (params.get('play') === '1') {
      playing = true;
      playBtn.textContent = 'Pause';
    }
    if (!timeline.timed) notes.push(`untimed plan: shown at ≤ ${UNTIMED_SPEED} rad/s per joint`);
  }
  frameCamera();
  const title = job ? `plan ${job.id}: ${job.kind} in ${sceneName}` : `scene ${sceneName}`;
  // (A plan with nothing to draw is named in the notes.)
  setStatus([title, ...notes].join(' · '));
  requestAnimationFrame((now) => {
    render(now);
    state.ready = true;
    document.title = 'manyhands viewer: ready';
  });
}

main().catch((e) => {
  setStatus(String(e.message || e), true);
  noteError(String(e.message || e));
  document.title = `manyhands viewer: error: ${e.message || e}`;
});
