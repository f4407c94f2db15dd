// The live view's 3D page (docs/live-view.md): the cell in three.js, the robots from their URDFs (urdf-loader), the
// other geoms from the "cell" message, moved by "frame" messages; the marking, commands, Gantt, faults and collisions
// beside it; the camera's view as a picture in picture; play/pause/step/restart/run-to, teaching and the check.
//
// URL parameters: ?view=camera:NAME draws only the cell camera NAME's view, at its resolution (the browser test
// compares it with MuJoCo's picture from that camera); &shift=DX,DY,DZ moves that view (metres, world axes).
// window.cellwright says what the page has done (for the browser test): ready (the cell drawn and a frame shown),
// robots (URDFs loaded), links, firings, state, errors (refusals), teach / saved / check (the last such message);
// showRobots(bool) hides or shows the robots.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import URDFLoader from 'urdf-loader';

THREE.Object3D.DEFAULT_UP.set(0, 0, 1);  // MuJoCo's world: z up

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);
const cameraView = (params.get('view') || '').startsWith('camera:') ? params.get('view').slice(7) : null;
const shift = (params.get('shift') || '0,0,0').split(',').map(Number);

const status = { ready: false, robots: 0, links: 0, firings: -1, state: '', frames: 0, errors: [] };
window.cellwright = status;

// ---------------------------------------------------------------------------------------------------------------
// The 3D scene.
const canvas = $('canvas');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(cameraView ? 1 : window.devicePixelRatio);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xdde3ea);
scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(0.5, -1.5, 3);
scene.add(sun);

const view = new THREE.PerspectiveCamera(45, 1, 0.02, 50);
view.position.set(-1.6, -2.4, 2.2);
const controls = new OrbitControls(view, canvas);
controls.target.set(0.4, 0.1, 0.4);
controls.update();

const world = new THREE.Group();   // the cell's geoms, by body
const robotsGroup = new THREE.Group();
const marksGroup = new THREE.Group();
const ghostGroup = new THREE.Group();
scene.add(world, robotsGroup, marksGroup, ghostGroup);

let cell = null;
let bodies = {};         // body id -> THREE.Group
let robots = {};         // cell robot name -> {urdf: URDFRobot, info, group}
let ghosts = {};         // cell robot name -> URDFRobot (translucent copy for teaching)
let cellCamera = null;   // THREE.PerspectiveCamera of the cell's first camera (or the one ?view names)
let frustum = null;
let lastFrame = null;
const markPos = new Map();  // mark text -> first position seen

function quat(q) { return new THREE.Quaternion(q[1], q[2], q[3], q[0]); }  // [w,x,y,z] -> three's (x,y,z,w)
function setPose(obj, p) { obj.position.set(p[0], p[1], p[2]); obj.quaternion.copy(quat(p.slice(3))); }

function geomMesh(g) {
  const s = g.size;
  let geo;
  switch (g.shape) {
    case 'box': geo = new THREE.BoxGeometry(2 * s[0], 2 * s[1], 2 * s[2]); break;
    case 'sphere': geo = new THREE.SphereGeometry(s[0], 24, 16); break;
    case 'cylinder': geo = new THREE.CylinderGeometry(s[0], s[0], 2 * s[1], 32).rotateX(Math.PI / 2); break;
    case 'capsule': geo = new THREE.CapsuleGeometry(s[0], 2 * s[1], 8, 16).rotateX(Math.PI / 2); break;
    case 'plane': geo = new THREE.PlaneGeometry(2 * (s[0] || 5), 2 * (s[1] || 5)); break;
    default: return null;
  }
  const c = g.rgba;
  const mat = new THREE.MeshStandardMaterial({ color: new THREE.Color(c[0], c[1], c[2]), roughness: 0.8,
                                               transparent: c[3] < 1, opacity: c[3] });
  const mesh = new THREE.Mesh(geo, mat);
  mesh.position.set(g.pos[0], g.pos[1], g.pos[2]);
  mesh.quaternion.copy(quat(g.quat));
  return mesh;
}

function cameraFrom(c, aspect) {
  const cam = new THREE.PerspectiveCamera(c.fovy, aspect, 0.05, 20);
  cam.up.set(0, 1, 0);  // MuJoCo's camera frame is three's: looks along its -z, y up
  cam.position.set(c.pos[0] + shift[0], c.pos[1] + shift[1], c.pos[2] + shift[2]);
  cam.quaternion.copy(quat(c.quat));
  cam.updateMatrixWorld();
  return cam;
}

function clear(group) { while (group.children.length) group.remove(group.children[0]); }

function loadRobot(r, translucent) {
  return new Promise((resolve) => {
    const loader = new URDFLoader();
    loader.packages = r.packages || {};
    loader.load(r.urdf, (urdf) => {
      if (translucent) {
        urdf.traverse((o) => {
          if (o.isMesh) {
            o.material = new THREE.MeshStandardMaterial({ color: 0x33aaff, transparent: true, opacity: 0.35,
                                                          depthWrite: false });
          }
        });
      }
      resolve(urdf);
    }, null, (err) => { status.errors.push(`${r.urdf}: ${err}`); showError(`cannot load ${r.urdf}: ${err}`); resolve(null); });
  });
}

async function showCell(m) {
  cell = m;
  status.ready = false; status.robots = 0; status.links = 0;
  clear(world); clear(robotsGroup); clear(ghostGroup); clear(marksGroup);
  bodies = {}; robots = {}; ghosts = {}; markPos.clear();
  for (const b of m.bodies) {
    const g = new THREE.Group();
    setPose(g, b.pose);
    bodies[b.id] = g;
    world.add(g);
  }
  for (const g of m.geoms) {
    const mesh = geomMesh(g);
    if (mesh && bodies[g.body]) bodies[g.body].add(mesh);
  }
  const cams = m.cameras || [];
  const chosen = cameraView ? cams.find((c) => c.name === cameraView) : cams[0];
  if (cameraView && !chosen) showError(`no camera '${cameraView}' in the cell (${cams.map((c) => c.name).join(', ')})`);
  if (frustum) { scene.remove(frustum); frustum = null; }
  cellCamera = chosen ? cameraFrom(chosen, chosen.resolution[0] / chosen.resolution[1]) : null;
  if (cellCamera && !cameraView) {
    const shown = cellCamera.clone();  // the frustum drawn down to the floor, not to the far plane
    shown.far = Math.max(0.3, chosen.pos[2]); shown.updateProjectionMatrix();
    frustum = new THREE.CameraHelper(shown);
    scene.add(frustum);
    $('pip-label').textContent = `camera '${chosen.name}' (${chosen.resolution[0]} x ${chosen.resolution[1]})`;
  }
  if (cameraView && chosen) {
    document.body.classList.add('camera-view');
    $('view').style.width = `${chosen.resolution[0]}px`;
    $('view').style.height = `${chosen.resolution[1]}px`;
  }
  $('title').textContent = `${m.name}: ${m.program} (${m.scenario}${m.mode ? ", " + m.mode : ""})`;
  const sel = $('teach-robot');
  sel.innerHTML = '';
  for (const r of m.robots) sel.add(new Option(`${r.name}`, r.name));
  const loaded = await Promise.all(m.robots.map((r) => loadRobot(r, false)));
  if (cell !== m) return;  // another cell came meanwhile
  m.robots.forEach((r, i) => {
    const urdf = loaded[i];
    if (!urdf) return;
    const group = new THREE.Group();
    if (r.base) setPose(group, r.base);
    group.add(urdf);
    robotsGroup.add(group);
    robots[r.name] = { urdf, info: r, group };
    status.robots += 1;
    status.links += Object.keys(urdf.links).length;
  });
  buildTeachButtons();
  if (lastFrame) showFrame(lastFrame);
}

function setJoints(urdf, info, joints, fingers) {
  info.joints.forEach((name, i) => { if (i < joints.length) urdf.setJointValue(name, joints[i]); });
  if (fingers !== undefined) {
    for (const f of ['finger_left_joint', 'finger_right_joint']) {
      if (urdf.joints[f]) urdf.setJointValue(f, fingers / 2);
    }
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Frames.
const gantt = { rows: {}, t: 0 };  // robot label -> [{command, start, end, ok}] (from frames without "gantt")

function showFrame(f) {
  lastFrame = f;
  status.frames += 1; status.firings = f.firings; status.state = f.state;
  for (const row of f.bodies) if (bodies[row[0]]) setPose(bodies[row[0]], row.slice(1));
  for (const r of f.robots) {
    const rob = robots[r.name];
    if (rob) setJoints(rob.urdf, rob.info, r.joints, r.fingers);
  }
  showMarks(f.marks || []);
  $('state').textContent = `${f.state}, t = ${f.t.toFixed(3)} s, ${f.firings} firings` +
    (f.replay ? `, replaying the counterexample (${f.replay_index || 0} done)` : '') +
    (f.outcome ? `, ${f.outcome} ${f.reason || ''}` : '');
  $('marking').textContent = f.marking;
  $('robots').textContent = f.robots.map((r) =>
    `${r.label} (${r.name}): ${r.activity || '-'} ${r.command || ''}${r.phase ? ` [${r.phase}${r.detail ? ': ' + r.detail : ''}]` : ''}`)
    .join('\n');
  $('fired').textContent = f.fired.join('\n');
  $('faults').textContent = (f.marks || []).map((m) => `${m.kind}: ${m.text}`).join('\n');
  drawGantt(f);
  if (cell && status.robots === cell.robots.length) status.ready = true;
}

function showMarks(marks) {
  clear(marksGroup);
  for (const m of marks) {
    if (!markPos.has(m.text)) markPos.set(m.text, m.pos);
    const p = markPos.get(m.text);
    const mesh = new THREE.Mesh(new THREE.SphereGeometry(0.04, 16, 12),
      new THREE.MeshBasicMaterial({ color: m.kind === 'collision' ? 0xff6600 : 0xdd0000, transparent: true,
                                    opacity: 0.8, depthTest: false }));
    mesh.position.set(p[0], p[1], p[2]);
    mesh.renderOrder = 10;
    marksGroup.add(mesh);
  }
}

function drawGantt(f) {
  let rows;
  if (f.gantt) {
    rows = {};
    for (const s of f.gantt) (rows[s.robot] = rows[s.robot] || []).push(s);
  } else {
    // No "gantt" (the run's log is streamed to a file): each robot's command as the frames show it.
    for (const r of f.robots) {
      const list = gantt.rows[r.label] = gantt.rows[r.label] || [];
      const last = list[list.length - 1];
      const running = r.activity && r.activity !== 'idle' && r.activity !== 'done';
      if (last && last.end === null && (!running || last.command !== r.command)) last.end = f.t;
      if (running && (!last || last.end !== null)) list.push({ command: r.command, start: f.t, end: null, ok: true });
    }
    rows = gantt.rows;
  }
  const c = $('gantt'), g = c.getContext('2d');
  const labels = f.robots.map((r) => r.label);
  c.width = Math.max(200, c.clientWidth);
  c.height = 22 * labels.length + 18;
  g.clearRect(0, 0, c.width, c.height);
  const t1 = Math.max(f.t, 1), x0 = 40, w = c.width - x0 - 5;
  g.font = '11px sans-serif';
  labels.forEach((label, i) => {
    const y = 4 + 22 * i;
    g.fillStyle = '#000'; g.fillText(label, 2, y + 14);
    (rows[label] || []).forEach((s, k) => {
      const a = x0 + w * s.start / t1, b = x0 + w * (s.end === null ? f.t : s.end) / t1;
      g.fillStyle = !s.ok ? '#c33' : s.end === null ? '#e9a23b' : (k % 2 ? '#4a7fc1' : '#6f9fd8');
      g.fillRect(a, y, Math.max(b - a, 1), 18);
    });
  });
  g.fillStyle = '#000';
  g.fillText(`0 s`, x0, c.height - 2);
  g.textAlign = 'right';
  g.fillText(`${t1.toFixed(1)} s`, c.width - 2, c.height - 2);
  g.textAlign = 'left';
}

// ---------------------------------------------------------------------------------------------------------------
// Teaching, check, errors.
let teachJoints = 0;

function buildTeachButtons() {
  const r = cell && cell.robots.find((x) => x.name === $('teach-robot').value);
  const box = $('teach-joints');
  box.innerHTML = '';
  if (!r) return;
  r.joints.forEach((name, i) => {
    const div = document.createElement('div');
    div.className = 'row';
    div.append(`${name} `);
    for (const sign of [-1, 1]) {
      const b = document.createElement('button');
      b.textContent = sign < 0 ? '−' : '+';
      b.id = `jog-${i}-${sign < 0 ? 'minus' : 'plus'}`;
      b.onclick = () => teach({ action: 'joint', joint: i, delta: sign * Number($('teach-rad').value) * Math.PI / 180 });
      div.append(b, ' ');
    }
    box.append(div);
  });
  teachJoints = r.joints.length;
  const cart = $('teach-cart');
  cart.innerHTML = '';
  for (const axis of ['x', 'y', 'z', 'yaw']) {
    cart.append(`${axis} `);
    for (const sign of [-1, 1]) {
      const b = document.createElement('button');
      b.textContent = sign < 0 ? '−' : '+';
      b.id = `jog-${axis}-${sign < 0 ? 'minus' : 'plus'}`;
      b.onclick = () => teach({ action: 'cartesian', axis,
        delta: sign * (axis === 'yaw' ? Number($('teach-rad').value) * Math.PI / 180 : Number($('teach-mm').value) / 1000) });
      cart.append(b, ' ');
    }
  }
}

function teach(fields) { send({ type: 'teach', robot: $('teach-robot').value, ...fields }); }

async function showTeach(m) {
  status.teach = m;
  const rob = robots[m.robot];
  if (!m.active) {
    if (ghosts[m.robot]) { ghostGroup.remove(ghosts[m.robot].parent); delete ghosts[m.robot]; }
    $('teach-state').textContent = `${m.robot}: not teaching`;
    clear(marksGroup);
    if (lastFrame) showMarks(lastFrame.marks || []);
    return;
  }
  if (!rob) return;
  if (!ghosts[m.robot]) {
    const urdf = await loadRobot(rob.info, true);
    if (!urdf) return;
    const g = new THREE.Group();
    g.position.copy(rob.group.position); g.quaternion.copy(rob.group.quaternion);
    g.add(urdf);
    ghostGroup.add(g);
    ghosts[m.robot] = urdf;
  }
  setJoints(ghosts[m.robot], rob.info, m.joints);
  const names = rob.info.joints;
  $('teach-state').textContent =
    `${m.robot}: ${m.reachable ? 'reachable' : 'NOT reachable'}` + (m.reason ? ` (${m.reason})` : '') + '\n' +
    `joints (deg) ${m.joints.map((j) => (j * 180 / Math.PI).toFixed(1)).join(' ')}\n` +
    (m.tool ? `tool ${m.tool.slice(0, 3).map((v) => v.toFixed(3)).join(' ')} m\n` : '') +
    ((m.at_limit || []).length ? `at limit: ${m.at_limit.map((i) => names[i] || i).join(', ')}\n` : '') +
    (m.collisions || []).map((c) => `collision ${c.a} / ${c.b}`).join('\n');
  for (const c of m.collisions || []) {
    const mesh = new THREE.Mesh(new THREE.SphereGeometry(0.035, 16, 12),
      new THREE.MeshBasicMaterial({ color: 0xff00ff, depthTest: false }));
    mesh.position.set(c.pos[0], c.pos[1], c.pos[2]);
    mesh.renderOrder = 11;
    marksGroup.add(mesh);
  }
}

function showCheck(m) {
  $('check-result').textContent = (m.ok ? 'passed: ' : `FAILED (${m.property}): `) + m.summary + '\n' +
    (m.counterexample || []).map((s, i) => `${i + 1}. ${s.transition}${s.line ? ` (line ${s.line})` : ''}${s.robot ? ` [${s.robot}]` : ''}`).join('\n') +
    (m.dead_marking ? `\ndead marking: ${m.dead_marking}` : '');
  $('replay').disabled = m.ok;
}

function showError(text) { $('error').textContent = text; }

// ---------------------------------------------------------------------------------------------------------------
// The socket and the buttons.
const ws = new WebSocket(`ws://${location.host}/ws`);
function send(msg) { if (ws.readyState === 1) ws.send(JSON.stringify(msg)); }
ws.onmessage = (ev) => {
  const m = JSON.parse(ev.data);
  if (m.type === 'cell') showCell(m);
  else if (m.type === 'frame') showFrame(m);
  else if (m.type === 'teach') showTeach(m);
  else if (m.type === 'saved') {
    status.saved = m;
    $('saved').textContent = `saved ${m.name} in ${m.file}${m.replaced ? ' (replaced)' : ''}:\n${m.diff}`;
  }
  else if (m.type === 'check') { status.check = m; showCheck(m); }
  else if (m.type === 'error') { status.errors.push(m.reason); showError(`refused: ${m.reason}`); }
};
ws.onclose = () => { $('title').textContent = 'disconnected'; };
for (const b of document.querySelectorAll('button[data-cmd]')) b.onclick = () => send({ type: 'command', command: b.dataset.cmd });
$('run-line').onclick = () => send({ type: 'command', command: 'run_to', line: Number($('to-line').value) });
$('run-time').onclick = () => send({ type: 'command', command: 'run_to', time: Number($('to-time').value) });
$('teach-begin').onclick = () => teach({ action: 'begin' });
$('teach-end').onclick = () => teach({ action: 'end' });
$('teach-robot').onchange = buildTeachButtons;
$('teach-save').onclick = () => send({ type: 'save_location', robot: $('teach-robot').value, name: $('teach-name').value });
$('check').onclick = () => send({ type: 'check' });
$('replay').onclick = () => send({ type: 'command', command: 'replay' });

status.showRobots = (on) => { robotsGroup.visible = on; };

// ---------------------------------------------------------------------------------------------------------------
// Drawing: the main view, and the cell camera's view in a corner (not in ?view=camera mode, where it is the view).
function draw() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  if (canvas.width !== Math.floor(w * renderer.getPixelRatio()) || canvas.height !== Math.floor(h * renderer.getPixelRatio())) {
    renderer.setSize(w, h, false);
  }
  renderer.setScissorTest(false);
  renderer.setViewport(0, 0, w, h);
  if (cameraView) {
    if (cellCamera) renderer.render(scene, cellCamera);
  } else {
    view.aspect = w / h; view.updateProjectionMatrix();
    renderer.render(scene, view);
    if (cellCamera) {
      const pw = Math.round(w * 0.28), ph = Math.round(pw / cellCamera.aspect);
      if (frustum) frustum.visible = false;
      renderer.setScissorTest(true);
      renderer.setScissor(w - pw - 8, 24, pw, ph);
      renderer.setViewport(w - pw - 8, 24, pw, ph);
      renderer.render(scene, cellCamera);
      renderer.setScissorTest(false);
      if (frustum) frustum.visible = true;
    }
  }
  requestAnimationFrame(draw);
}
requestAnimationFrame(draw);
