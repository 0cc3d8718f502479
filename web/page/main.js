// Relief's browser client: a tile session over /v1/stream, decoded and checked by
// relief-proto compiled to WebAssembly (/page/pkg/, built by web/build-wasm.sh), drawn with
// WebGL2. The page does no stitching: each tile arrives with its crack patches, and it draws
// the triangles the wasm hands it.
//
// Shading as the wgpu client's: the hypsometric ramp, the sun on smooth normals, haze; tiles
// that arrive by a split morph in from their parent's mesh over 0.25 s.
//
// Query options: ?tau=2, ?crack=patches|skirts|none, ?background=#rrggbb, ?wire=1, ?hud=0,
// ?morph=0, ?path=standard|stress (fly the camera path, ?poses=N of its poses, then hold;
// ?pitch=DEG looks that far down instead of the path's own pitch, for crack tests looking
// down).
// window.relief holds the counters the browser tests read.

import init, {
  TileSession, close_retries, close_refused_snapshot, camera_path_queries, camera_path_poses,
} from '/page/pkg/relief_wasm.js';

const query = new URLSearchParams(location.search);
const FOV_Y_DEG = 60;
const NEAR = 1;
const POSE_HZ = 10;
const SKY = '#9eb3cc';

const relief = {
  frames: 0, deltas: 0, desyncs: 0, reconnects: 0, resumes: 0, welcomes: 0, bytes: 0,
  poses: 0, tiles: 0, nodes: 0, triangles: 0, fps: 0, bytesPerS: 0, latencyMs: null, tau: 0,
  connected: false, message: null, fatal: null, pathLength: 0, pathSent: 0, answered: 0,
  poseSeq: 0, complete: false, applyUs: { count: 0, total: 0, max: 0 },
  uploadUs: { count: 0, total: 0, max: 0 }, lastError: null,
};
window.relief = relief;

const canvas = document.getElementById('view');
const statsEl = document.getElementById('stats');
const messageEl = document.getElementById('message');
const tauInput = document.getElementById('tau');
const tauValue = document.getElementById('tau-value');
const wireInput = document.getElementById('wire');

function colour(hex, fallback) {
  const m = /^#?([0-9a-f]{6})$/i.exec(hex ?? '');
  const v = parseInt(m ? m[1] : fallback.slice(1), 16);
  return [(v >> 16) / 255, ((v >> 8) & 255) / 255, (v & 255) / 255];
}
const background = colour(query.get('background'), SKY);
document.body.style.background = `rgb(${background.map((c) => Math.round(c * 255)).join(',')})`;
const crack = ['patches', 'skirts', 'none'].includes(query.get('crack')) ? query.get('crack') : 'patches';
const stream = query.get('stream') === 'vertex' ? 'vertex' : 'tiles';
let tau = Number(query.get('tau') ?? tauInput.value);
if (!(tau >= 0.5 && tau <= 100)) tau = 2;
tauInput.value = String(tau);
tauValue.textContent = String(tau);
relief.tau = tau;
wireInput.checked = query.get('wire') === '1';
if (query.get('hud') === '0') {
  // Nothing over the terrain (the crack test reads the page's pixels).
  document.getElementById('hud').style.display = 'none';
  document.getElementById('help').style.display = 'none';
}

function say(text) {
  relief.message = text;
  messageEl.textContent = text ?? '';
  messageEl.style.display = text ? 'block' : 'none';
}

// ---- WebGL2 ----------------------------------------------------------------------------------

const gl = canvas.getContext('webgl2', { antialias: false, preserveDrawingBuffer: true });
if (!gl) {
  say('This browser has no WebGL2.');
  throw new Error('no WebGL2');
}

// A tile that arrived by a split morphs from its parent's mesh (pos.w, nrm.zw) to its own
// (pos.z, nrm.xy) as alpha grows from 0 to 1 (the wgpu client's tiles.wgsl). Written as
// a + (b - a) * alpha so that a vertex that never moves (a == b: the tile's boundary, patches,
// skirts) stays bit for bit where its neighbours put it.
// The vertex stream's record textures: texels a row (see web/wasm's take_node_rows and
// take_cell_rows).
const NODE_ROW_TEXELS = 768;
const CELL_ROW_TEXELS = 4096;

const VS = `#version 300 es
layout(location = 0) in vec4 pos;
layout(location = 1) in vec4 nrm;
uniform mat4 viewProj;
uniform vec3 eye;
uniform float alpha;
uniform float extra;
out vec3 rel;
out float height;
out vec3 normal;
void main() {
  vec3 p = vec3(pos.xy, pos.w + (pos.z - pos.w) * alpha);
  rel = p - eye;
  height = p.z;
  vec2 nxy = nrm.zw + (nrm.xy - nrm.zw) * alpha;
  // Patches and skirts shade like the surface they stand in for: their edge vertices carry the
  // tile's smooth normals, their own vertices none (0, 0: straight up). Shaded flat, as
  // vertical walls, the one-pixel patches of distant seams showed as dark dots.
  normal = vec3(nxy, sqrt(max(1.0 - dot(nxy, nxy), 0.0)));
  gl_Position = viewProj * vec4(rel, 1.0);
}`;

// The shading of the wgpu client's shade.wgsl: its hypsometric ramp in metres, sun, haze.
const FS = `#version 300 es
precision highp float;
in vec3 rel;
in float height;
in vec3 normal;
uniform vec3 light;
uniform vec3 haze;
uniform float fogDistance;
uniform float extra;
uniform float wire;
uniform int lines;
out vec4 colour;
const vec4 STOPS[9] = vec4[9](
  vec4(0.0, 0.13, 0.27, 0.10), vec4(300.0, 0.24, 0.38, 0.14), vec4(800.0, 0.42, 0.45, 0.22),
  vec4(1400.0, 0.50, 0.42, 0.26), vec4(2000.0, 0.42, 0.32, 0.21), vec4(2600.0, 0.40, 0.36, 0.33),
  vec4(3100.0, 0.55, 0.54, 0.53), vec4(3400.0, 0.82, 0.82, 0.84), vec4(3700.0, 0.95, 0.95, 0.97));
vec3 ramp(float h) {
  if (h <= STOPS[0].x) return STOPS[0].yzw;
  for (int i = 1; i < 9; i++) {
    if (h < STOPS[i].x) {
      vec4 a = STOPS[i - 1];
      vec4 b = STOPS[i];
      return mix(a.yzw, b.yzw, (h - a.x) / (b.x - a.x));
    }
  }
  return STOPS[8].yzw;
}
void main() {
  if (lines == 1) {
    colour = vec4(0.05, 0.05, 0.07, 1.0);
    return;
  }
  // The smooth normal where there is one, else the drawn triangle's flat one.
  vec3 n = normalize(cross(dFdx(rel), dFdy(rel)));
  if (n.z < 0.0) n = -n;
  if (dot(normal, normal) > 1.0e-12) n = normalize(normal);
  vec3 c = ramp(height) * (0.30 + 0.95 * max(dot(n, light), 0.0));
  float fog = 1.0 - exp(-length(rel) / fogDistance);
  c = mix(c, haze, 0.45 * fog);
  // Under the wireframe, patches and skirts are tinted red.
  c = mix(c, vec3(0.95, 0.08, 0.06), 0.85 * extra * wire);
  colour = vec4(pow(c, vec3(1.0 / 2.2)), 1.0);
}`;

function compile(type, source) {
  const s = gl.createShader(type);
  gl.shaderSource(s, source);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}
const program = gl.createProgram();
gl.attachShader(program, compile(gl.VERTEX_SHADER, VS));
gl.attachShader(program, compile(gl.FRAGMENT_SHADER, FS));
gl.linkProgram(program);
if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
const uniform = (name) => gl.getUniformLocation(program, name);

// The vertex stream: every cell record's two triangles, six corners of node slots, read from
// a texture by gl_VertexID; each corner is a node record (three RGBA32UI texels: position and
// parent slot, box min and static error, box max and split time) geomorphed here from its
// ancestors' screen errors, the formula of relief_proto::mesh::morph and of the wgpu client's
// terrain.wgsl (its `vs` path). Flat shading, as there.
const VS_VERTEX = `#version 300 es
precision highp float;
precision highp int;
precision highp usampler2D;
uniform usampler2D nodes;
uniform usampler2D cells;
uniform mat4 viewProj;
uniform vec3 eye;
uniform float now;
uniform vec4 forward;   // unit view direction, focal length (px)
uniform vec4 planes[5]; // inward normals of the side and near planes, offsets
uniform vec4 morph;     // tau, lambda, growth duration (s), off-axis bound
uniform float near;
out vec3 rel;
out float height;
out vec3 normal;
const uint NONE = 0xffffffffu;
struct Node { vec3 pos; uint parent; vec3 bmin; float err; vec3 bmax; float tsplit; };
Node node(uint slot) {
  int t = 3 * int(slot);
  ivec2 at = ivec2(t % ${NODE_ROW_TEXELS}, t / ${NODE_ROW_TEXELS});
  uvec4 a = texelFetch(nodes, at, 0);
  uvec4 b = texelFetch(nodes, at + ivec2(1, 0), 0);
  uvec4 c = texelFetch(nodes, at + ivec2(2, 0), 0);
  return Node(uintBitsToFloat(a.xyz), a.w, uintBitsToFloat(b.xyz), uintBitsToFloat(b.w),
    uintBitsToFloat(c.xyz), uintBitsToFloat(c.w));
}
float screenError(vec3 b0, vec3 b1, float err) {
  if (err <= 0.0) return 0.0;
  vec3 relMin = b0 - eye;
  vec3 relMax = b1 - eye;
  float margin = 3.0e38;
  for (int i = 0; i < 5; i++) {
    vec3 n = planes[i].xyz;
    vec3 p = mix(relMin, relMax, step(0.0, n));
    margin = min(margin, dot(n, p) - planes[i].w);
  }
  if (margin < 0.0) return 0.0;
  vec3 f = forward.xyz;
  vec3 nearCorner = mix(relMax, relMin, step(0.0, f));
  vec3 far = max(abs(relMin), abs(relMax));
  float depth = max(dot(f, nearCorner), near);
  float rMax = sqrt(far.x * far.x + far.y * far.y);
  return forward.w * err * min(rMax / depth, morph.w) / depth;
}
float alphaOf(Node p) {
  float tau = morph.x;
  float e = screenError(p.bmin, p.bmax, p.err);
  float a = clamp((e - tau) / ((morph.y - 1.0) * tau), 0.0, 1.0);
  if (morph.z > 0.0) a = min(a, clamp((now - p.tsplit) / morph.z, 0.0, 1.0));
  return a;
}
void main() {
  uint slot = texelFetch(cells, ivec2(gl_VertexID % ${CELL_ROW_TEXELS}, gl_VertexID / ${CELL_ROW_TEXELS}), 0).r;
  normal = vec3(0.0);
  if (slot == NONE) {
    // A missing triangle: all three corners land outside the clip volume.
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    rel = vec3(0.0);
    height = 0.0;
    return;
  }
  // D(n) = D(p) + alpha(p) (P(n) - D(p)), walked upwards from the node, stopping at the first
  // ancestor whose alpha is 1.
  uint cur = slot;
  vec3 p = vec3(0.0);
  float w = 1.0;
  for (int k = 0; k < 64; k++) {
    Node n = node(cur);
    if (n.parent == NONE) {
      p += w * n.pos;
      break;
    }
    float a = alphaOf(node(n.parent));
    p += (w * a) * n.pos;
    w *= 1.0 - a;
    if (w <= 0.0) break;
    cur = n.parent;
  }
  rel = p - eye;
  height = p.z;
  gl_Position = viewProj * vec4(rel, 1.0);
}`;
const vertexProgram = gl.createProgram();
gl.attachShader(vertexProgram, compile(gl.VERTEX_SHADER, VS_VERTEX));
gl.attachShader(vertexProgram, compile(gl.FRAGMENT_SHADER, FS));
gl.linkProgram(vertexProgram);
if (!gl.getProgramParameter(vertexProgram, gl.LINK_STATUS)) {
  throw new Error(gl.getProgramInfoLog(vertexProgram));
}
const V = Object.fromEntries(['nodes', 'cells', 'viewProj', 'eye', 'now', 'forward', 'planes', 'morph',
  'near', 'light', 'haze', 'fogDistance', 'extra', 'wire', 'lines']
  .map((n) => [n, gl.getUniformLocation(vertexProgram, n)]));
const emptyVao = gl.createVertexArray();
/** The vertex stream's record textures: nodes (RGBA32UI) and cells (R32UI). */
const records = {
  nodes: { texture: null, rows: 0, width: NODE_ROW_TEXELS, format: [gl.RGBA32UI, gl.RGBA_INTEGER], words: 4 },
  cells: { texture: null, rows: 0, width: CELL_ROW_TEXELS, format: [gl.R32UI, gl.RED_INTEGER], words: 1 },
};

/** Uploads the rows `take_*_rows` handed out: `[rows, then per run: first, count, words]`. */
function uploadRows(r, update) {
  if (update.length === 0) return;
  const rows = update[0];
  const [internal, format] = r.format;
  if (r.texture === null || rows !== r.rows) {
    if (r.texture) gl.deleteTexture(r.texture);
    r.texture = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, r.texture);
    gl.texStorage2D(gl.TEXTURE_2D, 1, internal, r.width, Math.max(1, rows));
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    r.rows = rows;
  }
  gl.bindTexture(gl.TEXTURE_2D, r.texture);
  const rowWords = r.width * r.words;
  for (let i = 1; i < update.length;) {
    const [first, count] = [update[i], update[i + 1]];
    const words = update.subarray(i + 2, i + 2 + count * rowWords);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, first, r.width, count, format, gl.UNSIGNED_INT, words);
    i += 2 + count * rowWords;
  }
  gl.bindTexture(gl.TEXTURE_2D, null);
}

const U = {
  viewProj: uniform('viewProj'), eye: uniform('eye'), light: uniform('light'), haze: uniform('haze'),
  fogDistance: uniform('fogDistance'), extra: uniform('extra'), wire: uniform('wire'),
  lines: uniform('lines'), alpha: uniform('alpha'),
};
// The wgpu client's sun (client/src/render/frame.rs).
const SUN = (() => {
  const v = [-0.55, 0.45, 0.70];
  const l = Math.hypot(...v);
  return v.map((x) => x / l);
})();
const HAZE = colour(SKY, SKY).map((c) => c ** 2.2);
// How long a tile that arrived by a split takes to morph in, seconds (the wgpu client's growth
// duration); ?morph=0 turns the morph off.
const GROWTH_S = query.get('morph') === '0' ? 0 : 0.25;
// The arrival time of a tile drawn as it is.
const SETTLED = -Infinity;

/** GPU buffers of the tiles the session holds, by dense index. */
const tiles = new Map();

function upload(index) {
  const g = session.geometry(index);
  if (!g) return null;
  const positions = g.positions();
  const normals = g.normals();
  const indices = g.indices();
  const t = {
    vao: gl.createVertexArray(), vbo: gl.createBuffer(), nbo: gl.createBuffer(),
    ibo: gl.createBuffer(), lines: null, indices, mesh: g.mesh_triangles,
    extra: g.extra_triangles, active: false, arrived: SETTLED,
  };
  g.free();
  gl.bindVertexArray(t.vao);
  gl.bindBuffer(gl.ARRAY_BUFFER, t.vbo);
  gl.bufferData(gl.ARRAY_BUFFER, positions, gl.STATIC_DRAW);
  gl.enableVertexAttribArray(0);
  gl.vertexAttribPointer(0, 4, gl.FLOAT, false, 0, 0);
  gl.bindBuffer(gl.ARRAY_BUFFER, t.nbo);
  gl.bufferData(gl.ARRAY_BUFFER, normals, gl.STATIC_DRAW);
  gl.enableVertexAttribArray(1);
  gl.vertexAttribPointer(1, 4, gl.FLOAT, false, 0, 0);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, t.ibo);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, indices, gl.STATIC_DRAW);
  gl.bindVertexArray(null);
  tiles.set(index, t);
  return t;
}

function drop(index) {
  const t = tiles.get(index);
  if (!t) return;
  gl.deleteVertexArray(t.vao);
  gl.deleteBuffer(t.vbo);
  gl.deleteBuffer(t.nbo);
  gl.deleteBuffer(t.ibo);
  if (t.lines) gl.deleteBuffer(t.lines.buffer);
  tiles.delete(index);
}

/** A tile's triangle edges as line indices, built the first time the wireframe shows it. */
function lineBuffer(t) {
  if (t.lines) return t.lines;
  const n = t.indices.length / 3;
  const out = new Uint32Array(n * 6);
  for (let i = 0; i < n; i++) {
    const [a, b, c] = [t.indices[3 * i], t.indices[3 * i + 1], t.indices[3 * i + 2]];
    out.set([a, b, b, c, c, a], 6 * i);
  }
  const buffer = gl.createBuffer();
  gl.bindVertexArray(t.vao);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, buffer);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, out, gl.STATIC_DRAW);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, t.ibo);
  gl.bindVertexArray(null);
  t.lines = { buffer, count: out.length };
  return t.lines;
}

/** Vertex stream: the record rows the last message changed, into their textures. */
function uploadRecords() {
  if (stream !== 'vertex') return;
  uploadRows(records.nodes, session.take_node_rows());
  uploadRows(records.cells, session.take_cell_rows());
}

function countTriangles() {
  if (stream === 'vertex') {
    relief.triangles = session ? session.fan_triangles : 0;
    relief.nodes = session ? session.active_nodes : 0;
    return;
  }
  let n = 0;
  let active = 0;
  for (const t of tiles.values()) {
    if (!t.active) continue;
    active += 1;
    n += t.mesh + t.extra;
  }
  relief.tiles = active;
  relief.triangles = n;
}

// ---- Camera ----------------------------------------------------------------------------------

const cam = { x: 0, y: 0, z: 0, yaw: 0, pitch: -0.3 };
relief.camera = cam;
let terrain = null;
let path = null;
let pathIndex = 0;
const pitchDeg = Number(query.get('pitch'));
const pitchOverride = query.has('pitch') && Math.abs(pitchDeg) < 89 ? (pitchDeg * Math.PI) / 180 : null;

function forward() {
  const cp = Math.cos(cam.pitch);
  return [Math.cos(cam.yaw) * cp, Math.sin(cam.yaw) * cp, Math.sin(cam.pitch)];
}

function viewProj(aspect, far) {
  const f = forward();
  let s = [f[1], -f[0], 0];
  const sl = Math.hypot(s[0], s[1]) || 1;
  s = [s[0] / sl, s[1] / sl, 0];
  const u = [s[1] * f[2] - s[2] * f[1], s[2] * f[0] - s[0] * f[2], s[0] * f[1] - s[1] * f[0]];
  // Column-major: the view rotation (eye at the origin), then a GL perspective.
  const view = [s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0, s[2], u[2], -f[2], 0, 0, 0, 0, 1];
  const g = 1 / Math.tan((FOV_Y_DEG * Math.PI) / 360);
  const proj = [g / aspect, 0, 0, 0, 0, g, 0, 0, 0, 0, (far + NEAR) / (NEAR - far), -1,
    0, 0, (2 * far * NEAR) / (NEAR - far), 0];
  const out = new Float32Array(16);
  for (let c = 0; c < 4; c++) {
    for (let r = 0; r < 4; r++) {
      let v = 0;
      for (let k = 0; k < 4; k++) v += proj[k * 4 + r] * view[c * 4 + k];
      out[c * 4 + r] = v;
    }
  }
  return out;
}

const keys = new Set();
addEventListener('keydown', (e) => keys.add(e.key.toLowerCase()));
addEventListener('keyup', (e) => keys.delete(e.key.toLowerCase()));
addEventListener('blur', () => keys.clear());
const pointers = new Map();
canvas.addEventListener('pointerdown', (e) => {
  canvas.setPointerCapture(e.pointerId);
  pointers.set(e.pointerId, [e.clientX, e.clientY]);
});
canvas.addEventListener('pointermove', (e) => {
  const last = pointers.get(e.pointerId);
  if (!last || path) return;
  pointers.set(e.pointerId, [e.clientX, e.clientY]);
  if (pointers.size > 1) return; // two fingers fly forward (below), they do not turn
  cam.yaw -= (e.clientX - last[0]) * 0.004;
  cam.pitch = Math.max(-1.5, Math.min(1.5, cam.pitch - (e.clientY - last[1]) * 0.004));
});
const release = (e) => pointers.delete(e.pointerId);
canvas.addEventListener('pointerup', release);
canvas.addEventListener('pointercancel', release);

function fly(dt) {
  if (!terrain || path) return;
  const [hmin, hmax] = terrain.height_range_m;
  const speed = Math.max(50, (cam.z - hmin) * 0.8) * (keys.has('shift') ? 4 : 1);
  const f = forward();
  const right = [Math.sin(cam.yaw), -Math.cos(cam.yaw)];
  let [dx, dy, dz] = [0, 0, 0];
  const ahead = (keys.has('w') ? 1 : 0) - (keys.has('s') ? 1 : 0) + (pointers.size > 1 ? 1 : 0);
  const side = (keys.has('d') ? 1 : 0) - (keys.has('a') ? 1 : 0);
  dx += ahead * f[0] + side * right[0];
  dy += ahead * f[1] + side * right[1];
  dz += ahead * f[2] + (keys.has('e') ? 1 : 0) - (keys.has('q') ? 1 : 0);
  cam.x += dx * speed * dt;
  cam.y += dy * speed * dt;
  cam.z = Math.max(hmin - 100, Math.min(hmax + 50000, cam.z + dz * speed * dt));
}

// ---- Session ---------------------------------------------------------------------------------

let session = null;
let ws = null;
let backoff = 50;
let lastSent = 0;
let sentPose = null;
const poseTimes = new Map();
const received = [];

function lens() {
  return [Math.max(1, canvas.width), Math.max(1, canvas.height)];
}

function connect() {
  const [w, h] = lens();
  session.set_view(w, h, tau);
  const socket = new WebSocket(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/v1/stream`);
  ws = socket;
  socket.binaryType = 'arraybuffer';
  socket.onopen = () => {
    socket.send(session.hello());
    lastSent = performance.now();
  };
  socket.onmessage = (ev) => {
    if (socket !== ws || !(ev.data instanceof ArrayBuffer)) return;
    const now = performance.now();
    relief.bytes += ev.data.byteLength;
    received.push([now, ev.data.byteLength]);
    let kind;
    const t0 = performance.now();
    try {
      kind = session.receive(new Uint8Array(ev.data), performance.now() / 1000);
    } catch (e) {
      // A desync (or a message this page cannot read): start again from scratch.
      relief.desyncs += 1;
      relief.lastError = String(e.message ?? e);
      console.warn(`relief: ${relief.lastError}; starting again`);
      session.reset();
      for (const i of [...tiles.keys()]) drop(i);
      countTriangles();
      socket.close(1000, 'desync');
      return;
    }
    const us = (performance.now() - t0) * 1000;
    if (kind === 'welcome' || kind === 'resumed') {
      relief.connected = true;
      relief.welcomes += 1;
      backoff = 50;
      say(null);
      if (kind === 'welcome') {
        for (const i of [...tiles.keys()]) drop(i);
      } else {
        relief.resumes += 1;
        const active = new Set(session.active());
        for (const [i, t] of [...tiles.entries()]) {
          if (active.has(i)) t.active = true;
          else drop(i);
        }
      }
      uploadRecords();
      countTriangles();
      sendPose(true);
    } else if (kind === 'delta') {
      relief.deltas += 1;
      relief.applyUs.count += 1;
      relief.applyUs.total += us;
      relief.applyUs.max = Math.max(relief.applyUs.max, us);
      const t1 = performance.now();
      for (const i of session.removed()) {
        const t = tiles.get(i);
        if (t) t.active = false;
      }
      for (const i of session.evicted()) drop(i);
      const split = new Set(session.split_added());
      const arrival = performance.now() / 1000;
      for (const i of session.added()) {
        const t = tiles.get(i) ?? upload(i);
        if (t) {
          t.active = true;
          t.arrived = split.has(i) ? arrival : SETTLED;
        }
      }
      uploadRecords();
      const up = (performance.now() - t1) * 1000;
      relief.uploadUs.count += 1;
      relief.uploadUs.total += up;
      relief.uploadUs.max = Math.max(relief.uploadUs.max, up);
      countTriangles();
      socket.send(session.ack());
      lastSent = performance.now();
      const answered = session.answered_pose;
      if (poseTimes.has(answered)) {
        relief.latencyMs = now - poseTimes.get(answered);
        for (const k of [...poseTimes.keys()]) if (k <= answered) poseTimes.delete(k);
      }
      relief.answered = answered;
      relief.complete = session.complete;
    } else if (kind === 'reconnect') {
      backoff = Math.max(backoff, session.reconnect_after_ms);
    }
  };
  socket.onclose = (ev) => {
    if (socket !== ws) return;
    ws = null;
    const was = relief.connected;
    relief.connected = false;
    if (close_refused_snapshot(ev.code)) {
      // The server holds another terrain: start again from the root.
      session.reset();
      for (const i of [...tiles.keys()]) drop(i);
      countTriangles();
    } else if (ev.code !== 1000 && !close_retries(ev.code)) {
      relief.fatal = `${ev.code} ${ev.reason}`;
      say(`The server ended the session: ${ev.reason || ev.code}. Reload the page to try again.`);
      return;
    }
    if (!was && ev.code !== 1000) {
      say(`Cannot reach the Relief server at ${location.host} (${ev.reason || `close ${ev.code}`}); ` +
        `retrying every ${Math.round(Math.min(2 * backoff, 2000) / 100) / 10} s...`);
    } else if (ev.code !== 1000) {
      say(`Connection to ${location.host} lost; reconnecting...`);
    }
    const wait = backoff;
    backoff = Math.min(2 * backoff, 2000);
    setTimeout(() => {
      relief.reconnects += 1;
      connect();
    }, wait);
  };
}

function sendPose(force) {
  if (!ws || !relief.connected || ws.readyState !== WebSocket.OPEN) return;
  const key = `${cam.x},${cam.y},${cam.z},${cam.yaw},${cam.pitch}`;
  const now = performance.now();
  if (!force && key === sentPose) {
    // Keepalive: repeat the last acknowledgement well within the idle timeout.
    if (now - lastSent > session.idle_timeout_ms / 4) {
      ws.send(session.ack());
      lastSent = now;
    }
    return;
  }
  ws.send(session.pose(cam.x, cam.y, cam.z, cam.yaw, cam.pitch));
  sentPose = key;
  lastSent = now;
  relief.poses += 1;
  relief.poseSeq = session.pose_seq;
  poseTimes.set(session.pose_seq, now);
}

function tick() {
  if (path && relief.connected) {
    const last = path.length / 5 - 1;
    const i = Math.min(pathIndex, last, relief.pathLength - 1);
    [cam.x, cam.y, cam.z, cam.yaw, cam.pitch] = path.slice(5 * i, 5 * i + 5);
    if (pitchOverride !== null) cam.pitch = pitchOverride;
    if (pathIndex <= i) {
      pathIndex += 1;
      relief.pathSent = pathIndex;
    }
  }
  sendPose(false);
}

tauInput.addEventListener('input', () => {
  tauValue.textContent = tauInput.value;
});
tauInput.addEventListener('change', () => {
  // tau is fixed for a connection: reconnect with the new one, resuming the tiles held.
  tau = Number(tauInput.value);
  relief.tau = tau;
  if (ws) {
    const old = ws;
    ws = null;
    relief.connected = false;
    old.close(1000, 'new tau');
    relief.reconnects += 1;
    connect();
  }
});

// ---- Frames ----------------------------------------------------------------------------------

let lastFrame = performance.now();
let fpsFrames = 0;
let fpsSince = lastFrame;

function resize() {
  const dpr = window.devicePixelRatio || 1;
  const w = Math.round(canvas.clientWidth * dpr);
  const h = Math.round(canvas.clientHeight * dpr);
  if (canvas.width !== w || canvas.height !== h) {
    canvas.width = w;
    canvas.height = h;
  }
}

/** How far tile `t` has morphed in at `seconds`: 0 on arrival by a split, then up to 1. */
function morphAlpha(t, seconds) {
  return GROWTH_S > 0 ? Math.min(1, Math.max(0, (seconds - t.arrived) / GROWTH_S)) : 1;
}

/** The tile stream: each active tile's mesh, then its patches or skirts. */
function drawTiles(now, far) {
  const [ex, ey] = terrain.extent_m;
  gl.useProgram(program);
  gl.enable(gl.DEPTH_TEST);
  gl.depthFunc(gl.LEQUAL);
  // Patches and skirts are vertical: no back-face culling.
  gl.disable(gl.CULL_FACE);
  gl.uniformMatrix4fv(U.viewProj, false, viewProj(canvas.width / canvas.height, far));
  gl.uniform3f(U.eye, cam.x, cam.y, cam.z);
  gl.uniform3fv(U.light, SUN);
  gl.uniform3fv(U.haze, HAZE);
  gl.uniform1f(U.fogDistance, Math.max(ex, ey));
  const wire = wireInput.checked;
  if (wire) {
    gl.enable(gl.POLYGON_OFFSET_FILL);
    gl.polygonOffset(1, 1);
  }
  gl.uniform1i(U.lines, 0);
  gl.uniform1f(U.wire, wire ? 1 : 0);
  const seconds = now / 1000;
  for (const t of tiles.values()) {
    if (!t.active) continue;
    gl.bindVertexArray(t.vao);
    gl.uniform1f(U.alpha, morphAlpha(t, seconds));
    gl.uniform1f(U.extra, 0);
    gl.drawElements(gl.TRIANGLES, 3 * t.mesh, gl.UNSIGNED_INT, 0);
    if (t.extra > 0) {
      gl.uniform1f(U.extra, 1);
      gl.drawElements(gl.TRIANGLES, 3 * t.extra, gl.UNSIGNED_INT, 12 * t.mesh);
    }
  }
  if (wire) {
    gl.disable(gl.POLYGON_OFFSET_FILL);
    gl.uniform1i(U.lines, 1);
    for (const t of tiles.values()) {
      if (!t.active) continue;
      const lines = lineBuffer(t);
      gl.bindVertexArray(t.vao);
      gl.uniform1f(U.alpha, morphAlpha(t, seconds));
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, lines.buffer);
      gl.drawElements(gl.LINES, lines.count, gl.UNSIGNED_INT, 0);
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, t.ibo);
    }
  }
  gl.bindVertexArray(null);
}

/** The vertex stream: every cell's two triangles, geomorphed in the vertex shader. */
function drawVertexStream(now, far) {
  const cells = session ? session.cell_count : 0;
  if (cells === 0 || !records.nodes.texture || !records.cells.texture) return;
  const [ex, ey] = terrain.extent_m;
  gl.useProgram(vertexProgram);
  gl.enable(gl.DEPTH_TEST);
  gl.depthFunc(gl.LEQUAL);
  gl.disable(gl.CULL_FACE);
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(gl.TEXTURE_2D, records.nodes.texture);
  gl.uniform1i(V.nodes, 0);
  gl.activeTexture(gl.TEXTURE1);
  gl.bindTexture(gl.TEXTURE_2D, records.cells.texture);
  gl.uniform1i(V.cells, 1);
  gl.uniformMatrix4fv(V.viewProj, false, viewProj(canvas.width / canvas.height, far));
  gl.uniform3f(V.eye, cam.x, cam.y, cam.z);
  gl.uniform1f(V.now, now / 1000);
  const m = session.morph_block(cam.x, cam.y, cam.z, cam.yaw, cam.pitch);
  gl.uniform4fv(V.forward, m.subarray(0, 4));
  gl.uniform4fv(V.planes, m.subarray(4, 24));
  gl.uniform4fv(V.morph, m.subarray(24, 28));
  gl.uniform1f(V.near, m[28]);
  gl.uniform3fv(V.light, SUN);
  gl.uniform3fv(V.haze, HAZE);
  gl.uniform1f(V.fogDistance, Math.max(ex, ey));
  gl.uniform1f(V.extra, 0);
  gl.uniform1f(V.wire, 0);
  gl.uniform1i(V.lines, 0);
  gl.bindVertexArray(emptyVao);
  gl.drawArrays(gl.TRIANGLES, 0, 6 * cells);
  gl.bindVertexArray(null);
  gl.activeTexture(gl.TEXTURE0);
}

function frame(now) {
  const dt = Math.min(0.1, (now - lastFrame) / 1000);
  lastFrame = now;
  fly(dt);
  resize();
  gl.viewport(0, 0, canvas.width, canvas.height);
  gl.clearColor(background[0], background[1], background[2], 1);
  gl.clearDepth(1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  if (terrain) {
    const [ex, ey] = terrain.extent_m;
    const far = 4 * Math.max(ex, ey) + Math.max(0, cam.z - terrain.height_range_m[0]) * 4;
    if (stream === 'vertex') {
      drawVertexStream(now, far);
    } else {
      drawTiles(now, far);
    }
  }
  relief.frames += 1;
  fpsFrames += 1;
  if (now - fpsSince >= 500) {
    relief.fps = (1000 * fpsFrames) / (now - fpsSince);
    fpsFrames = 0;
    fpsSince = now;
    hud(now);
  }
  requestAnimationFrame(frame);
}

function hud(now) {
  while (received.length && received[0][0] < now - 2000) received.shift();
  relief.bytesPerS = received.reduce((s, r) => s + r[1], 0) / 2;
  const kb = (relief.bytesPerS / 1024).toFixed(1);
  const lat = relief.latencyMs == null ? '-' : `${relief.latencyMs.toFixed(0)} ms`;
  const apply = relief.applyUs.count ? (relief.applyUs.total / relief.applyUs.count).toFixed(0) : '-';
  statsEl.textContent =
    `${relief.fps.toFixed(1)} fps   ${relief.triangles.toLocaleString('en')} triangles\n` +
    (stream === 'vertex'
      ? `${relief.nodes.toLocaleString('en')} nodes (vertex stream)   ${kb} KiB/s\n`
      : `${relief.tiles} tiles (${session ? session.held : 0} held)   ${kb} KiB/s\n`) +
    `tau ${tau} px   latency ${lat}   apply ${apply} us\n` +
    `deltas ${relief.deltas}   desyncs ${relief.desyncs}   resumes ${relief.resumes}` +
    (relief.connected ? '' : '   (offline)');
}

// ---- Start -----------------------------------------------------------------------------------

async function terrainInfo() {
  for (let wait = 250; ; wait = Math.min(2 * wait, 2000)) {
    try {
      const r = await fetch('/v1/terrain');
      if (r.ok) return await r.json();
      say(`The Relief server is not ready (${r.status}); retrying...`);
    } catch (e) {
      say(`Cannot reach the Relief server at ${location.host}; retrying...`);
    }
    await new Promise((res) => setTimeout(res, wait));
  }
}

async function cameraPath(kind) {
  const [ex, ey] = terrain.extent_m;
  const q = camera_path_queries(kind, ex, ey);
  const points = [];
  for (let i = 0; i < q.length; i += 2) points.push([q[i], q[i + 1]]);
  const r = await fetch('/v1/heights', { method: 'POST', body: JSON.stringify({ points }) });
  if (!r.ok) throw new Error(`POST /v1/heights: ${r.status}`);
  const { heights } = await r.json();
  return camera_path_poses(kind, ex, ey, Float32Array.from(heights, (h) => h ?? 0));
}

async function start() {
  await init();
  terrain = await terrainInfo();
  say(null);
  const [ex, ey] = terrain.extent_m;
  const [hmin, hmax] = terrain.height_range_m;
  // Start south of the terrain, above it, looking north at its middle.
  cam.x = ex / 2;
  cam.y = -0.35 * ey;
  cam.z = hmax + 0.25 * Math.max(ex, ey);
  cam.yaw = Math.PI / 2;
  cam.pitch = -Math.atan2(cam.z - (hmin + hmax) / 2, 0.85 * ey);
  const kind = query.get('path');
  if (kind) {
    path = await cameraPath(kind);
    const n = path.length / 5;
    const limit = Number(query.get('poses') ?? n);
    relief.pathLength = Math.max(1, Math.min(n, Number.isFinite(limit) ? limit : n));
    [cam.x, cam.y, cam.z, cam.yaw, cam.pitch] = path.slice(0, 5);
  }
  resize();
  const [w, h] = lens();
  session = new TileSession(w, h, FOV_Y_DEG, NEAR, tau, stream, crack, 1024);
  connect();
  setInterval(tick, 1000 / POSE_HZ);
  requestAnimationFrame(frame);
}

start().catch((e) => {
  relief.fatal = String(e.message ?? e);
  say(`The page failed to start: ${relief.fatal}`);
  console.error(e);
});
