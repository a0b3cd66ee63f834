// cleave view: draws the simulation `cleave view` streams over the WebSocket (WebGL2)
// and sends the mouse's commands back. Messages: see src/io/stream.rs (binary) and
// src/bin/cleave/view/protocol.rs (commands).
'use strict';

const $ = (id) => document.getElementById(id);
const canvas = $('view');
const gl = canvas.getContext('webgl2', { antialias: false });
const strokeCanvas = $('stroke');
const ink = strokeCanvas.getContext('2d');
const FOV = 50 * Math.PI / 180;

// ---- small vector and matrix helpers (column-major 4×4, as WebGL reads them) ----
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const normalize = (a) => scale(a, 1 / (Math.hypot(a[0], a[1], a[2]) || 1));

function multiply(a, b) {
  const m = new Float32Array(16);
  for (let c = 0; c < 4; c++) {
    for (let r = 0; r < 4; r++) {
      let s = 0;
      for (let k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
      m[c * 4 + r] = s;
    }
  }
  return m;
}

function perspective(fov, aspect, near, far) {
  const f = 1 / Math.tan(fov / 2);
  return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) / (near - far), -1,
    0, 0, 2 * far * near / (near - far), 0]);
}

function lookAt(eye, basis) {
  const { right: r, up: u, forward: f } = basis;
  return new Float32Array([r[0], u[0], -f[0], 0, r[1], u[1], -f[1], 0, r[2], u[2], -f[2], 0,
    -dot(r, eye), -dot(u, eye), dot(f, eye), 1]);
}

// a pose (position, quaternion [x, y, z, w]) with a scale per local axis
function poseMatrix(pose, s) {
  const [x, y, z, w] = pose.rotation;
  const p = pose.position;
  const r = [
    1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w),
    2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
    2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y),
  ];
  return new Float32Array([r[0] * s[0], r[1] * s[0], r[2] * s[0], 0, r[3] * s[1], r[4] * s[1],
    r[5] * s[1], 0, r[6] * s[2], r[7] * s[2], r[8] * s[2], 0, p[0], p[1], p[2], 1]);
}

// ---- the camera: orbit about a target ----
const camera = { target: [0, 0.5, 0], yaw: 0.6, pitch: 0.35, distance: 6 };

function cameraBasis() {
  const cp = Math.cos(camera.pitch);
  const back = [cp * Math.sin(camera.yaw), Math.sin(camera.pitch), cp * Math.cos(camera.yaw)];
  const eye = add(camera.target, scale(back, camera.distance));
  const forward = scale(back, -1);
  const right = normalize(cross(forward, [0, 1, 0]));
  return { eye, forward, right, up: cross(right, forward) };
}

// the ray from the eye through a point of the canvas (CSS pixels)
function rayAt(x, y) {
  const b = cameraBasis();
  const t = Math.tan(FOV / 2);
  const nx = (2 * x / canvas.clientWidth - 1) * t * canvas.clientWidth / canvas.clientHeight;
  const ny = (1 - 2 * y / canvas.clientHeight) * t;
  return { eye: b.eye, dir: normalize(add(b.forward, add(scale(b.right, nx), scale(b.up, ny)))) };
}

// frame everything in `box` ([min, max])
function frameBox(box) {
  const centre = scale(add(box[0], box[1]), 0.5);
  const radius = Math.max(0.2, 0.5 * Math.hypot(...sub(box[1], box[0])));
  camera.target = centre;
  camera.distance = 1.15 * radius / Math.sin(FOV / 2);
}

// ---- shaders ----
function program(vertex, fragment) {
  const compile = (type, source) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, '#version 300 es\nprecision highp float;\n' + source);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  };
  const p = gl.createProgram();
  gl.attachShader(p, compile(gl.VERTEX_SHADER, vertex));
  gl.attachShader(p, compile(gl.FRAGMENT_SHADER, fragment));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
  const uniforms = {};
  for (let i = 0; i < gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS); i++) {
    const name = gl.getActiveUniform(p, i).name;
    uniforms[name] = gl.getUniformLocation(p, name);
  }
  return { p, u: uniforms };
}

const LIGHT = normalize([0.4, 1.0, 0.55]);
const shaded = program(`
  layout(location = 0) in vec3 position;
  layout(location = 1) in vec3 normal;
  layout(location = 2) in vec3 colour;
  uniform mat4 viewProjection, model;
  out vec3 n, c, world;
  void main() {
    vec4 w = model * vec4(position, 1.0);
    world = w.xyz; n = mat3(model) * normal; c = colour;
    gl_Position = viewProjection * w;
  }`, `
  in vec3 n, c, world;
  uniform vec3 light, eye, tint;
  uniform float alpha;
  out vec4 colour;
  void main() {
    vec3 normal = normalize(n);
    vec3 view = normalize(eye - world);
    if (dot(normal, view) < 0.0) normal = -normal;
    float diffuse = max(dot(normal, light), 0.0);
    float specular = pow(max(dot(reflect(-light, normal), view), 0.0), 32.0);
    vec3 base = c * tint;
    colour = vec4(base * (0.28 + 0.72 * diffuse) + 0.18 * specular, alpha);
  }`);
const ground = program(`
  layout(location = 0) in vec3 position;
  uniform mat4 viewProjection;
  uniform float height;
  out vec3 world;
  void main() { world = vec3(position.x, height, position.z); gl_Position = viewProjection * vec4(world, 1.0); }`, `
  in vec3 world;
  uniform vec3 eye;
  out vec4 colour;
  void main() {
    vec2 cell = floor(world.xz);
    float checker = mod(cell.x + cell.y, 2.0);
    float fade = exp(-0.02 * length(world.xz - eye.xz));
    colour = vec4(mix(vec3(0.17, 0.19, 0.23), mix(vec3(0.34, 0.36, 0.40), vec3(0.40, 0.42, 0.46), checker), fade), 1.0);
  }`);

// ---- meshes ----
function meshFrom(positions, normals, indices) {
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const buffer = (data, location) => {
    const b = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, b);
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.DYNAMIC_DRAW);
    gl.enableVertexAttribArray(location);
    gl.vertexAttribPointer(location, 3, gl.FLOAT, false, 0, 0);
    return b;
  };
  const mesh = {
    vao, position: buffer(positions, 0), normal: buffer(normals, 1),
    colour: buffer(new Float32Array(positions.length).fill(0.8), 2),
    index: gl.createBuffer(), count: indices.length,
  };
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, mesh.index);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, indices, gl.STATIC_DRAW);
  gl.bindVertexArray(null);
  return mesh;
}

function drawMesh(mesh, model, tint, alpha) {
  gl.uniformMatrix4fv(shaded.u.model, false, model);
  gl.uniform3fv(shaded.u.tint, tint);
  gl.uniform1f(shaded.u.alpha, alpha);
  gl.bindVertexArray(mesh.vao);
  gl.drawElements(gl.TRIANGLES, mesh.count, gl.UNSIGNED_INT, 0);
}

// unit shapes for colliders and tools: a cube [-1, 1]³, a sphere of radius 1, a
// cylinder of radius 1 along X from -1 to 1, a square [-1, 1]² in XY
function sphereMesh(rings = 16, segments = 24) {
  const p = [], idx = [];
  for (let i = 0; i <= rings; i++) {
    const t = Math.PI * i / rings;
    for (let j = 0; j <= segments; j++) {
      const f = 2 * Math.PI * j / segments;
      p.push(Math.sin(t) * Math.cos(f), Math.cos(t), Math.sin(t) * Math.sin(f));
    }
  }
  for (let i = 0; i < rings; i++) {
    for (let j = 0; j < segments; j++) {
      const a = i * (segments + 1) + j, b = a + segments + 1;
      idx.push(a, b, a + 1, a + 1, b, b + 1);
    }
  }
  const v = new Float32Array(p);
  return meshFrom(v, v, new Uint32Array(idx));
}

function boxMesh() {
  const p = [], n = [], idx = [];
  for (let axis = 0; axis < 3; axis++) {
    for (const side of [-1, 1]) {
      const base = p.length / 3;
      const u = (axis + 1) % 3, w = (axis + 2) % 3;
      for (const [a, b] of [[-1, -1], [1, -1], [1, 1], [-1, 1]]) {
        const q = [0, 0, 0], m = [0, 0, 0];
        q[axis] = side; q[u] = a; q[w] = b; m[axis] = side;
        p.push(...q); n.push(...m);
      }
      idx.push(base, base + 1, base + 2, base, base + 2, base + 3);
    }
  }
  return meshFrom(new Float32Array(p), new Float32Array(n), new Uint32Array(idx));
}

function cylinderMesh(segments = 24) {
  const p = [], n = [], idx = [];
  for (let j = 0; j <= segments; j++) {
    const f = 2 * Math.PI * j / segments, c = Math.cos(f), s = Math.sin(f);
    p.push(-1, c, s, 1, c, s);
    n.push(0, c, s, 0, c, s);
  }
  for (let j = 0; j < segments; j++) idx.push(2 * j, 2 * j + 1, 2 * j + 2, 2 * j + 1, 2 * j + 3, 2 * j + 2);
  return meshFrom(new Float32Array(p), new Float32Array(n), new Uint32Array(idx));
}

const square = meshFrom(new Float32Array([-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0]),
  new Float32Array([0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1]), new Uint32Array([0, 1, 2, 0, 2, 3]));
const shapes = { box: boxMesh(), sphere: sphereMesh(), cylinder: cylinderMesh(), square };
const groundQuad = gl.createVertexArray();
gl.bindVertexArray(groundQuad);
gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-200, 0, -200, 200, 0, -200, 200, 0, 200, -200, 0, -200, 200, 0, 200, -200, 0, 200]), gl.STATIC_DRAW);
gl.enableVertexAttribArray(0);
gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
gl.bindVertexArray(null);

function drawShape(shape, pose, tint, alpha) {
  const at = (offset) => ({
    position: add(pose.position, rotate(pose.rotation, offset)), rotation: pose.rotation,
  });
  switch (shape.kind) {
    case 'box': drawMesh(shapes.box, poseMatrix(pose, shape.half_extents), tint, alpha); break;
    case 'sphere': drawMesh(shapes.sphere, poseMatrix(pose, Array(3).fill(shape.radius)), tint, alpha); break;
    case 'capsule': {
      const r = shape.radius, h = shape.half_length;
      drawMesh(shapes.cylinder, poseMatrix(pose, [h, r, r]), tint, alpha);
      for (const end of [-h, h]) drawMesh(shapes.sphere, poseMatrix(at([end, 0, 0]), [r, r, r]), tint, alpha);
      break;
    }
    case 'blade': drawMesh(shapes.square, poseMatrix(pose, [shape.half_width, Math.max(shape.half_height, 0.01), 1]), tint, alpha); break;
    default: break; // a mesh collider is not drawn
  }
}

function rotate(q, v) {
  const u = [q[0], q[1], q[2]], w = q[3];
  const t = scale(cross(u, v), 2);
  return add(add(v, scale(t, w)), cross(u, t));
}

// ---- the bodies' surfaces, as the server streams them ----
const PALETTE = [[0.90, 0.45, 0.35], [0.35, 0.62, 0.90], [0.55, 0.80, 0.40], [0.92, 0.75, 0.30],
  [0.70, 0.50, 0.85], [0.35, 0.80, 0.78], [0.90, 0.55, 0.70], [0.65, 0.65, 0.60]];
let bodies = [];
let status = null;
let needFraming = true;
const view = { fps: 0, drawn: 0, status: null, positionsFrame: -1, bytes: 0, messages: 0 };
window.cleave = view;

function onTopology(words) {
  for (const { mesh } of bodies) {
    gl.deleteVertexArray(mesh.vao);
    for (const b of [mesh.position, mesh.normal, mesh.colour, mesh.index]) gl.deleteBuffer(b);
  }
  bodies = [];
  // pieces are numbered per body: number them on across the bodies, so that every
  // piece of every body takes the next colour
  let firstColour = 0;
  let at = 2;
  for (let k = 0; k < words[1]; k++) {
    const [version, vertices, triangles] = [words[at], words[at + 1], words[at + 2]];
    at += 3;
    const indices = words.slice(at, at + 3 * triangles);
    at += 3 * triangles;
    const pieces = words.slice(at, at + triangles);
    at += triangles;
    const colours = new Float32Array(3 * vertices).fill(0.8);
    let count = 0;
    for (let t = 0; t < triangles; t++) {
      const c = PALETTE[(firstColour + pieces[t]) % PALETTE.length];
      for (let j = 0; j < 3; j++) colours.set(c, 3 * indices[3 * t + j]);
      count = Math.max(count, pieces[t] + 1);
    }
    firstColour += count;
    const empty = new Float32Array(3 * vertices);
    const mesh = meshFrom(empty, empty, indices);
    gl.bindBuffer(gl.ARRAY_BUFFER, mesh.colour);
    gl.bufferData(gl.ARRAY_BUFFER, colours, gl.STATIC_DRAW);
    bodies.push({ version, vertices, indices, mesh, ready: false });
  }
}

// Positions wait for the next drawn frame: when frames come faster than the page
// draws, only the latest is uploaded.
function onPositions(buffer, words) {
  const frame = words[1];
  let at = 3;
  for (let k = 0; k < words[2]; k++) {
    const [version, vertices] = [words[at], words[at + 1]];
    at += 2;
    const body = bodies[k];
    if (body && body.version === version && body.vertices === vertices) {
      body.pending = new Float32Array(buffer, 4 * at, 3 * vertices);
    }
    at += 3 * vertices;
  }
  view.positionsFrame = frame;
}

function upload() {
  const box = [[Infinity, Infinity, Infinity], [-Infinity, -Infinity, -Infinity]];
  for (const body of bodies) {
    const xyz = body.pending;
    if (!xyz) continue;
    body.pending = null;
    gl.bindBuffer(gl.ARRAY_BUFFER, body.mesh.position);
    gl.bufferSubData(gl.ARRAY_BUFFER, 0, xyz);
    gl.bindBuffer(gl.ARRAY_BUFFER, body.mesh.normal);
    gl.bufferSubData(gl.ARRAY_BUFFER, 0, vertexNormals(xyz, body.indices));
    body.ready = true;
    if (!needFraming) continue;
    for (let i = 0; i < xyz.length; i += 3) {
      for (let a = 0; a < 3; a++) {
        box[0][a] = Math.min(box[0][a], xyz[i + a]);
        box[1][a] = Math.max(box[1][a], xyz[i + a]);
      }
    }
  }
  if (needFraming && box[0][0] <= box[1][0]) {
    frameBox(box);
    needFraming = false;
  }
}

// area-weighted vertex normals (the server's vertices already split where the
// surface is cut, so shared vertices are smooth ones)
function vertexNormals(xyz, indices) {
  const n = new Float32Array(xyz.length);
  for (let t = 0; t < indices.length; t += 3) {
    const a = 3 * indices[t], b = 3 * indices[t + 1], c = 3 * indices[t + 2];
    const ux = xyz[b] - xyz[a], uy = xyz[b + 1] - xyz[a + 1], uz = xyz[b + 2] - xyz[a + 2];
    const vx = xyz[c] - xyz[a], vy = xyz[c + 1] - xyz[a + 1], vz = xyz[c + 2] - xyz[a + 2];
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    for (const i of [a, b, c]) { n[i] += nx; n[i + 1] += ny; n[i + 2] += nz; }
  }
  return n;
}

function onStatus(s) {
  const firstOfScene = !status || status.epoch !== s.epoch;
  status = s;
  view.status = s;
  if (firstOfScene) needFraming = true;
  $('ms').textContent = s.ms_per_step.toFixed(1);
  $('frame').textContent = s.frame;
  $('particles').textContent = s.particles;
  $('clusters').textContent = s.clusters;
  $('pieces').textContent = s.pieces;
  $('play').textContent = s.playing ? 'Pause' : 'Play';
  // a panic stopped the simulation: say so and why until a reset starts it again
  const stopped = $('stopped');
  stopped.hidden = !s.stopped;
  if (s.stopped) stopped.textContent = `The simulation stopped: ${s.stopped}. Reset starts the scene again.`;
  const select = $('scene');
  if (select.options.length !== s.scenes.length) {
    select.replaceChildren(...s.scenes.map((name) => new Option(name, name)));
  }
  // the controls show the server's settings when those change (not on every frame,
  // which would undo a choice the server has not heard yet)
  const shown = [s.cut_mode, s.scripted_tools, s.scene].join();
  if (shown !== lastShown) {
    lastShown = shown;
    $('cutmode').value = s.cut_mode;
    $('scripted').checked = s.scripted_tools;
    select.value = s.scene;
  }
}
let lastShown = null;

// ---- the connection ----
let socket = null;
function send(command) {
  if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(command));
}

function connect() {
  // a server that listens beyond this machine wants its token, which its URL carries
  const token = new URLSearchParams(location.search).get('token');
  const query = token ? `?token=${encodeURIComponent(token)}` : '';
  socket = new WebSocket(`ws://${location.host}/ws${query}`);
  socket.binaryType = 'arraybuffer';
  socket.onopen = () => { $('connection').textContent = 'live'; };
  socket.onclose = () => {
    $('connection').textContent = 'closed, retrying';
    setTimeout(connect, 1000);
  };
  socket.onmessage = receive;
}

function receive(event) {
  view.messages++;
  if (typeof event.data === 'string') {
    view.bytes += event.data.length;
    onStatus(JSON.parse(event.data));
    return;
  }
  view.bytes += event.data.byteLength;
  const words = new Uint32Array(event.data);
  if (words[0] === 1) onTopology(words);
  else if (words[0] === 2) onPositions(event.data, words);
}

// ---- drawing ----
// The drawing buffer's resolution follows the frame rate, as games' dynamic resolution
// does: where the page is drawn without a GPU (a software rasteriser sharing the
// simulation's cores), fewer pixels keep it smooth; with a GPU it stays at full size.
view.resolution = 1;
let frames = 0, since = performance.now();
function draw(now) {
  requestAnimationFrame(draw);
  frames++;
  if (now - since >= 1000) {
    view.fps = 1000 * frames / (now - since);
    $('fps').textContent = view.fps.toFixed(0);
    if (view.fps < 36 && view.resolution > 0.4) view.resolution = Math.max(0.4, 0.8 * view.resolution);
    else if (view.fps > 55 && view.resolution < 1) view.resolution = Math.min(1, 1.25 * view.resolution);
    frames = 0;
    since = now;
  }
  const dpr = (window.devicePixelRatio || 1) * view.resolution;
  const [w, h] = [Math.round(canvas.clientWidth * dpr), Math.round(canvas.clientHeight * dpr)];
  if (canvas.width !== w || canvas.height !== h) {
    canvas.width = w; canvas.height = h;
  }
  if (strokeCanvas.width !== canvas.clientWidth || strokeCanvas.height !== canvas.clientHeight) {
    strokeCanvas.width = canvas.clientWidth; strokeCanvas.height = canvas.clientHeight;
  }
  upload();
  gl.viewport(0, 0, w, h);
  gl.clearColor(0.13, 0.15, 0.18, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  gl.enable(gl.DEPTH_TEST);
  const basis = cameraBasis();
  const projection = perspective(FOV, w / h, 0.02 * camera.distance, 200 * camera.distance);
  const viewProjection = multiply(projection, lookAt(basis.eye, basis));
  if (status && status.ground !== null) {
    gl.useProgram(ground.p);
    gl.uniformMatrix4fv(ground.u.viewProjection, false, viewProjection);
    gl.uniform1f(ground.u.height, status.ground);
    gl.uniform3fv(ground.u.eye, basis.eye);
    gl.bindVertexArray(groundQuad);
    gl.drawArrays(gl.TRIANGLES, 0, 6);
  }
  gl.useProgram(shaded.p);
  gl.uniformMatrix4fv(shaded.u.viewProjection, false, viewProjection);
  gl.uniform3fv(shaded.u.light, LIGHT);
  gl.uniform3fv(shaded.u.eye, basis.eye);
  const identity = poseMatrix({ position: [0, 0, 0], rotation: [0, 0, 0, 1] }, [1, 1, 1]);
  for (const body of bodies) if (body.ready) drawMesh(body.mesh, identity, [1, 1, 1], 1);
  if (status) {
    for (const c of status.colliders) drawShape(c.shape, c.pose, [0.55, 0.57, 0.62], 1);
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA);
    gl.depthMask(false);
    for (const t of status.tools) drawShape(t.shape, t.pose, [0.95, 0.95, 1.0], 0.35);
    gl.depthMask(true);
    gl.disable(gl.BLEND);
  }
  view.drawn++;
  if (counting) {
    const pixels = new Uint8Array(4 * w * h);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
    let n = 0;
    for (let i = 0; i < pixels.length; i += 4) {
      const [r, g, b] = [pixels[i], pixels[i + 1], pixels[i + 2]];
      if (Math.max(r, g, b) - Math.min(r, g, b) > 60) n++;
    }
    counting(n / (w * h) * canvas.clientWidth * canvas.clientHeight);
    counting = null;
  }
}

// How many CSS pixels of the next drawn frame show a piece (their colours are
// saturated; the ground, background and colliders are grey): for tests.
let counting = null;
view.countBodyPixels = () => new Promise((resolve) => { counting = resolve; });

// ---- the mouse ----
let gesture = null;
canvas.addEventListener('contextmenu', (e) => e.preventDefault());
canvas.addEventListener('pointerdown', (e) => {
  canvas.setPointerCapture(e.pointerId);
  const tool = $('tool').value;
  const kind = e.button === 2 || e.button === 1 || tool === 'orbit'
    ? (e.shiftKey || e.button === 1 ? 'pan' : 'orbit') : tool;
  gesture = { kind, x: e.offsetX, y: e.offsetY, startX: e.offsetX, startY: e.offsetY };
  if (kind === 'grab') {
    const r = rayAt(e.offsetX, e.offsetY);
    send({ cmd: 'grab', eye: r.eye, dir: r.dir });
  }
});
canvas.addEventListener('pointermove', (e) => {
  if (!gesture) return;
  const [dx, dy] = [e.offsetX - gesture.x, e.offsetY - gesture.y];
  gesture.x = e.offsetX; gesture.y = e.offsetY;
  if (gesture.kind === 'orbit') {
    camera.yaw -= 0.008 * dx;
    camera.pitch = Math.max(-1.5, Math.min(1.5, camera.pitch + 0.008 * dy));
  } else if (gesture.kind === 'pan') {
    const b = cameraBasis();
    const k = camera.distance * 2 * Math.tan(FOV / 2) / canvas.clientHeight;
    camera.target = add(camera.target, add(scale(b.right, -dx * k), scale(b.up, dy * k)));
  } else if (gesture.kind === 'grab') {
    const r = rayAt(e.offsetX, e.offsetY);
    send({ cmd: 'drag', eye: r.eye, dir: r.dir });
  } else if (gesture.kind === 'cut') {
    strokeCanvas.hidden = false;
    ink.clearRect(0, 0, strokeCanvas.width, strokeCanvas.height);
    ink.strokeStyle = '#f0c674';
    ink.lineWidth = 2;
    ink.beginPath();
    ink.moveTo(gesture.startX, gesture.startY);
    ink.lineTo(e.offsetX, e.offsetY);
    ink.stroke();
  }
});
canvas.addEventListener('pointerup', (e) => {
  if (!gesture) return;
  if (gesture.kind === 'grab') send({ cmd: 'release' });
  if (gesture.kind === 'cut') {
    // (hidden between strokes: one layer fewer for the compositor to blend)
    strokeCanvas.hidden = true;
    if (Math.hypot(e.offsetX - gesture.startX, e.offsetY - gesture.startY) > 4) {
      const from = rayAt(gesture.startX, gesture.startY), to = rayAt(e.offsetX, e.offsetY);
      send({ cmd: 'stroke', eye: from.eye, from: from.dir, to: to.dir });
    }
  }
  gesture = null;
});
canvas.addEventListener('wheel', (e) => {
  e.preventDefault();
  camera.distance = Math.max(0.1, camera.distance * Math.exp(0.001 * e.deltaY));
}, { passive: false });

// ---- the controls ----
$('play').addEventListener('click', () => send({ cmd: status && status.playing ? 'pause' : 'play' }));
$('step').addEventListener('click', () => send({ cmd: 'step' }));
$('reset').addEventListener('click', () => send({ cmd: 'reset' }));
$('scene').addEventListener('change', (e) => send({ cmd: 'scene', name: e.target.value }));
$('cutmode').addEventListener('change', (e) => send({ cmd: 'cut_mode', mode: e.target.value }));
$('scripted').addEventListener('change', (e) => send({ cmd: 'scripted_tools', on: e.target.checked }));
window.addEventListener('keydown', (e) => {
  if (e.code === 'Space' && e.target === document.body) {
    e.preventDefault();
    $('play').click();
  }
});

connect();
requestAnimationFrame(draw);
