// Shared by the browser tests of scopetrack-studio: the programs under test,
// the browser, sequences made by the simulator, and the camera geometry
// (written here independently of the page and of the server).
//
// Environment (set by CTest; defaults suit a build in build/):
//   STUDIO_BIN, SIM_BIN, TRACKER_BIN  the programs (default: ../../bin/ beside this folder)
//   WORK_DIR                          scratch folder (default: a new folder in the system's temp)
//   SCREENSHOT_DIR                    optional: where to write the README's screenshots
//   CHROMIUM                          the browser (default /usr/bin/chromium)

import { spawn, execFile } from 'node:child_process';
import fs from 'node:fs';
import net from 'node:net';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

const here = path.dirname(fileURLToPath(import.meta.url));
const defaultBin = (name) => path.resolve(here, '../../bin', name);

export const env = {
  studio: process.env.STUDIO_BIN || defaultBin('scopetrack-studio'),
  sim: process.env.SIM_BIN || defaultBin('scopetrack-sim'),
  tracker: process.env.TRACKER_BIN || defaultBin('scopetrack'),
  screenshots: process.env.SCREENSHOT_DIR || '',
  chromium: process.env.CHROMIUM || '/usr/bin/chromium',
};

/** A fresh scratch folder for one test file, under WORK_DIR when set. */
export function workDir(name) {
  const base = process.env.WORK_DIR || os.tmpdir();
  fs.mkdirSync(base, { recursive: true });
  return fs.mkdtempSync(path.join(base, `${name}-`));
}

export const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

// ------------------------------------------------------------------ processes

/** Runs a program to its end; resolves with {code, stdout, stderr}. */
export function run(program, args, { timeoutMs = 60000 } = {}) {
  return new Promise((resolve) => {
    execFile(program, args, { timeout: timeoutMs, maxBuffer: 16 << 20 }, (error, stdout, stderr) => {
      const code = error ? (typeof error.code === 'number' ? error.code : -1) : 0;
      resolve({ code, stdout, stderr, error });
    });
  });
}

/** Runs a program that must succeed; throws with its output otherwise. */
export async function mustRun(program, args, options) {
  const r = await run(program, args, options);
  if (r.code !== 0) {
    throw new Error(`${path.basename(program)} ${args.join(' ')} exited ${r.code}\n${r.stdout}\n${r.stderr}`);
  }
  return r;
}

/** Makes a simulated sequence; returns its folder. */
export async function makeSequence(dir, { scenario = 'orbit', frames = 30, size = '640x360', seed = 1 } = {}) {
  const out = path.join(dir, `${scenario}-${frames}`);
  await mustRun(env.sim, ['--scenario', scenario, '--frames', String(frames), '--size', size, '--seed', String(seed), '--out', out], {
    timeoutMs: 120000,
  });
  return out;
}

/**
 * Starts scopetrack-studio with `args` (add '--port', '0') and waits for
 * the line with its address. Returns {url, proc, output(), alive(), stop()}.
 */
export function startStudio(args, { timeoutMs = 20000 } = {}) {
  const proc = spawn(env.studio, args, { stdio: ['ignore', 'pipe', 'pipe'] });
  let stdout = '';
  let stderr = '';
  let exit = null;
  proc.stdout.setEncoding('utf8');
  proc.stderr.setEncoding('utf8');
  proc.stderr.on('data', (chunk) => {
    stderr += chunk;
  });
  const studio = {
    proc,
    url: '',
    output: () => `--- stdout\n${stdout}--- stderr\n${stderr}`,
    alive: () => exit === null,
    exit: () => exit,
    async stop() {
      if (exit !== null) return exit;
      proc.kill('SIGTERM');
      const done = await Promise.race([exited, sleep(5000).then(() => null)]);
      if (done === null) {
        proc.kill('SIGKILL');
        await exited;
      }
      return exit;
    },
  };
  const exited = new Promise((resolve) => {
    proc.on('exit', (code, signal) => {
      exit = { code, signal };
      resolve(exit);
    });
  });
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => {
      proc.kill('SIGKILL');
      reject(new Error(`scopetrack-studio ${args.join(' ')} printed no address within ${timeoutMs} ms\n${studio.output()}`));
    }, timeoutMs);
    proc.stdout.on('data', (chunk) => {
      stdout += chunk;
      const m = /scopetrack-studio: (http:\/\/\S+)/.exec(stdout);
      if (m && !studio.url) {
        studio.url = m[1];
        clearTimeout(timer);
        resolve(studio);
      }
    });
    exited.then(() => {
      clearTimeout(timer);
      if (!studio.url) reject(new Error(`scopetrack-studio ${args.join(' ')} exited ${JSON.stringify(exit)} before listening\n${studio.output()}`));
    });
  });
}

/** A TCP port free on 127.0.0.1 right now. */
export function freePort() {
  return new Promise((resolve, reject) => {
    const server = net.createServer();
    server.on('error', reject);
    server.listen(0, '127.0.0.1', () => {
      const { port } = server.address();
      server.close(() => resolve(port));
    });
  });
}

// ------------------------------------------------------------------ browser

export const CHROMIUM_ARGS = [
  '--headless',
  '--no-sandbox',
  '--disable-gpu',
  '--disable-quic',
  '--no-first-run',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--use-angle=swiftshader',
  '--enable-unsafe-swiftshader',
];

/** Headless Chromium with software WebGL, a fresh profile. */
export function launchBrowser(extraArgs = []) {
  return chromium.launch({ executablePath: env.chromium, args: [...CHROMIUM_ARGS, ...extraArgs], timeout: 30000 });
}

/** A new page of `browser` at `url`, its console errors collected in page.errors. */
export async function openPage(browser, url, { width = 1600, height = 900 } = {}) {
  const page = await browser.newPage({ viewport: { width, height } });
  page.errors = [];
  page.on('pageerror', (error) => page.errors.push(`pageerror: ${error.message}`));
  page.on('console', (message) => {
    if (message.type() === 'error') page.errors.push(`console: ${message.text()}`);
  });
  await page.goto(url, { timeout: 20000 });
  return page;
}

/** Waits for window.studio.ready. */
/**
 * A simulated sequence opened in the register view: the sequence, its
 * camera, frame 0's true T_camera_model and the ready page (the server and
 * the browser end with the test).
 */
export async function openRegister(t, name, frames) {
  const dir = workDir(name);
  const seq = await makeSequence(dir, { frames, size: '640x360' });
  const camera = readCamera(seq);
  const truth = groundTruthCameraModel(seq, 0);
  const studio = await startStudio(['register', seq, '--port', '0']);
  t.after(() => studio.stop());
  const browser = await launchBrowser();
  t.after(() => browser.close());
  const page = await openPage(browser, studio.url);
  await waitReady(page);
  return { dir, seq, camera, truth, studio, browser, page };
}

export async function waitReady(page, timeoutMs = 30000) {
  await page.waitForFunction(() => window.studio && window.studio.ready === true, null, { timeout: timeoutMs, polling: 100 });
}

export async function screenshot(page, name) {
  if (!env.screenshots) return;
  fs.mkdirSync(env.screenshots, { recursive: true });
  await page.screenshot({ path: path.join(env.screenshots, name) });
}

/** Text (window.studio.lastMessage: the text of #message, one line per part) and kind of #message. */
export function message(page) {
  return page.evaluate(() => ({ text: window.studio.lastMessage, kind: document.getElementById('message').dataset.kind }));
}

// ------------------------------------------------------------------ sequence files

/** The numbers of an OpenCV YAML matrix `key: !!opencv-matrix ... data: [ ... ]`. */
function yamlMatrix(text, key) {
  const start = text.indexOf(`${key}:`);
  if (start < 0) return null;
  const open = text.indexOf('[', text.indexOf('data:', start));
  const close = text.indexOf(']', open);
  return text
    .slice(open + 1, close)
    .split(',')
    .map((s) => Number(s.trim()));
}

function yamlNumber(text, key) {
  const m = new RegExp(`^${key}:\\s*([-+0-9.eE]+)`, 'm').exec(text);
  return m ? Number(m[1]) : NaN;
}

/** The camera of a sequence.yaml: {width, height, K: [fx, fy, cx, cy], distortion: [k1, k2, p1, p2, k3]}. */
export function readCamera(sequenceDir) {
  const text = fs.readFileSync(path.join(sequenceDir, 'sequence.yaml'), 'utf8');
  const k = yamlMatrix(text, 'camera_matrix');
  const d = yamlMatrix(text, 'distortion_coefficients') ?? [];
  const distortion = [0, 0, 0, 0, 0].map((_, i) => d[i] ?? 0);
  return {
    width: yamlNumber(text, 'image_width'),
    height: yamlNumber(text, 'image_height'),
    K: [k[0], k[4], k[2], k[5]],
    distortion,
  };
}

/** Ground-truth T_camera_model of frame `index` (groundtruth.txt: TUM lines of T_model_camera). */
export function groundTruthCameraModel(sequenceDir, index = 0) {
  const lines = fs
    .readFileSync(path.join(sequenceDir, 'groundtruth.txt'), 'utf8')
    .split('\n')
    .filter((l) => l.trim() && !l.startsWith('#'));
  const [, tx, ty, tz, qx, qy, qz, qw] = lines[index].trim().split(/\s+/).map(Number);
  const R = quaternionToMatrix(qx, qy, qz, qw); // R_model_camera
  return invertRigid(rigid(R, [tx, ty, tz]));
}

// ------------------------------------------------------------------ geometry (4x4 row-major arrays)

export function quaternionToMatrix(x, y, z, w) {
  const n = Math.hypot(x, y, z, w);
  x /= n; y /= n; z /= n; w /= n;
  return [
    [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
  ];
}

export function rigid(R, t) {
  return [R[0][0], R[0][1], R[0][2], t[0], R[1][0], R[1][1], R[1][2], t[1], R[2][0], R[2][1], R[2][2], t[2], 0, 0, 0, 1];
}

export function invertRigid(T) {
  const R = [[T[0], T[4], T[8]], [T[1], T[5], T[9]], [T[2], T[6], T[10]]]; // transposed
  const t = [T[3], T[7], T[11]];
  const ti = R.map((row) => -(row[0] * t[0] + row[1] * t[1] + row[2] * t[2]));
  return rigid(R, ti);
}

export function transform(T, p) {
  return [
    T[0] * p[0] + T[1] * p[1] + T[2] * p[2] + T[3],
    T[4] * p[0] + T[5] * p[1] + T[6] * p[2] + T[7],
    T[8] * p[0] + T[9] * p[1] + T[10] * p[2] + T[11],
  ];
}

/** Camera centre (model frame) of T_camera_model. */
export function cameraCentre(T) {
  return transform(invertRigid(T), [0, 0, 0]);
}

/** Angle between the rotations of two transforms, degrees. */
export function rotationDifferenceDeg(A, B) {
  // trace(Ra Rb^T)
  let trace = 0;
  for (let i = 0; i < 3; i++) for (let k = 0; k < 3; k++) trace += A[4 * i + k] * B[4 * i + k];
  return (Math.acos(Math.min(1, Math.max(-1, (trace - 1) / 2))) * 180) / Math.PI;
}

/** Pinhole + OpenCV (k1, k2, p1, p2, k3) projection of a model point; null behind the camera. */
export function project(T_camera_model, camera, p) {
  const [X, Y, Z] = transform(T_camera_model, p);
  if (Z <= 0) return null;
  const x = X / Z;
  const y = Y / Z;
  const [k1, k2, p1, p2, k3] = camera.distortion;
  const r2 = x * x + y * y;
  const radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
  const xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
  const yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  const [fx, fy, cx, cy] = camera.K;
  return { u: fx * xd + cx, v: fy * yd + cy, depth: Z };
}

export const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
export const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
export const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
export const norm = (a) => Math.hypot(a[0], a[1], a[2]);
export const distance = (a, b) => norm(sub(a, b));

/** Area-weighted vertex normals of a triangle mesh. */
export function vertexNormals(vertices, triangles) {
  const normals = new Float64Array(vertices.length);
  const v = (i) => [vertices[3 * i], vertices[3 * i + 1], vertices[3 * i + 2]];
  for (let t = 0; t < triangles.length; t += 3) {
    const [a, b, c] = [triangles[t], triangles[t + 1], triangles[t + 2]];
    const n = cross(sub(v(b), v(a)), sub(v(c), v(a)));
    for (const i of [a, b, c]) {
      normals[3 * i] += n[0];
      normals[3 * i + 1] += n[1];
      normals[3 * i + 2] += n[2];
    }
  }
  return (i) => {
    const n = [normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]];
    const l = norm(n) || 1;
    return [n[0] / l, n[1] / l, n[2] / l];
  };
}

/** Whether the segment from `from` to `to` crosses a triangle before it gets within `slack` mm of `to`. */
export function occluded(vertices, triangles, from, to, slack = 0.5) {
  const dir = sub(to, from);
  const length = norm(dir);
  const d = dir.map((x) => x / length);
  const v = (i) => [vertices[3 * i], vertices[3 * i + 1], vertices[3 * i + 2]];
  for (let t = 0; t < triangles.length; t += 3) {
    const a = v(triangles[t]);
    const e1 = sub(v(triangles[t + 1]), a);
    const e2 = sub(v(triangles[t + 2]), a);
    const p = cross(d, e2);
    const det = dot(e1, p);
    if (Math.abs(det) < 1e-12) continue;
    const s = sub(from, a);
    const u = dot(s, p) / det;
    if (u < 0 || u > 1) continue;
    const q = cross(s, e1);
    const w = dot(d, q) / det;
    if (w < 0 || u + w > 1) continue;
    const hit = dot(e2, q) / det;
    if (hit > 1e-6 && hit < length - slack) return true;
  }
  return false;
}

/** Binary PGM (P5, 8 bit) -> {width, height, data}. */
export function readPgm(file) {
  const bytes = fs.readFileSync(file);
  let offset = 0;
  const fields = [];
  while (fields.length < 4) {
    while (/\s/.test(String.fromCharCode(bytes[offset]))) offset++;
    if (bytes[offset] === 0x23) {
      while (bytes[offset] !== 0x0a) offset++;
      continue;
    }
    let token = '';
    while (!/\s/.test(String.fromCharCode(bytes[offset]))) token += String.fromCharCode(bytes[offset++]);
    fields.push(token);
  }
  offset++; // the one whitespace after maxval
  if (fields[0] !== 'P5') throw new Error(`${file} is not a binary PGM`);
  const width = Number(fields[1]);
  const height = Number(fields[2]);
  return { width, height, data: bytes.subarray(offset, offset + width * height) };
}

// ------------------------------------------------------------------ the register view

/** Clicks the frame at pixel (u, v) (video pixels). */
export async function clickFrame(page, u, v) {
  const at = await page.evaluate(([u, v]) => window.studio.frameToClient(u, v), [u, v]);
  if (!at) throw new Error(`frameToClient(${u}, ${v}) gave nothing`);
  await page.mouse.click(at.x, at.y);
}

/** Clicks the 3D view where model point P shows; false when P is behind the view's camera. */
export async function clickMesh(page, P) {
  const at = await page.evaluate((p) => window.studio.meshToClient(p[0], p[1], p[2]), P);
  if (!at) return false;
  await page.mouse.click(at.x, at.y);
  return true;
}

/** Counts to wait on: pairs on the page and registration answers so far. */
export function pairState(page) {
  return page.evaluate(() => ({ pairs: window.studio.pairs().length, answers: window.studio.registrations }));
}

/** Waits until the page has `pairs` pairs and an answer newer than `before`. */
export async function waitAnswer(page, before, pairs, timeoutMs = 15000) {
  await page.waitForFunction(
    ([answers, pairs]) => window.studio.pairs().length === pairs && window.studio.registrations > answers,
    [before.answers, pairs],
    { timeout: timeoutMs, polling: 50 },
  );
}

/**
 * Adds a pair: a click on the frame at `pixel`, then on the mesh at P.
 * Resolves with the pair the page made (its model point is the ray cast's), or
 * null when P is not in the 3D view (behind its camera, or outside the view).
 */
export async function addPair(page, pixel, P) {
  const before = await pairState(page);
  const onView = await page.evaluate((p) => {
    const at = window.studio.meshToClient(p[0], p[1], p[2]);
    const rect = document.getElementById('mesh-view').getBoundingClientRect();
    return at !== null && at.x > rect.left && at.x < rect.right && at.y > rect.top && at.y < rect.bottom &&
      at.y < window.innerHeight && at.x < window.innerWidth;
  }, P);
  if (!onView) return null;
  await clickFrame(page, pixel.u, pixel.v);
  await clickMesh(page, P);
  await waitAnswer(page, before, before.pairs + 1);
  const pairs = await page.evaluate(() => window.studio.pairs());
  return pairs[pairs.length - 1];
}

/** Removes pair `index` (0-based) with its remove button and waits for the answer. */
export async function removePair(page, index) {
  const before = await pairState(page);
  await page.click(`#pairs tr.pair:nth-child(${index + 1}) button.remove`);
  await waitAnswer(page, before, before.pairs - 1);
}

/** The mesh the page shows: {vertices: Float32Array, triangles: Uint32Array}. */
export async function pageMesh(page) {
  const mesh = await page.evaluate(() => ({
    vertices: Array.from(window.studio.meshVertices()),
    triangles: Array.from(window.studio.meshTriangles()),
  }));
  return { vertices: Float32Array.from(mesh.vertices), triangles: Uint32Array.from(mesh.triangles) };
}

/**
 * Mesh vertices that frame 0's true camera sees: facing it (normal within
 * `maxAngleDeg` of the direction to the camera), not hidden by the mesh,
 * projecting at least `margin` px inside the image. Each: {index, P, pixel}.
 * Spread: farthest-point order in the image, at least `minSeparationPx` apart.
 */
export function visibleVertices(mesh, T_camera_model, camera, { maxAngleDeg = 60, margin = 25, minSeparationPx = 40, count = 20 } = {}) {
  const { vertices, triangles } = mesh;
  const normalOf = vertexNormals(vertices, triangles);
  const centre = cameraCentre(T_camera_model);
  const cosLimit = Math.cos((maxAngleDeg * Math.PI) / 180);
  const facing = [];
  for (let i = 0; i < vertices.length / 3; i++) {
    const P = [vertices[3 * i], vertices[3 * i + 1], vertices[3 * i + 2]];
    const toCamera = sub(centre, P);
    if (dot(normalOf(i), toCamera) < cosLimit * norm(toCamera)) continue;
    const pixel = project(T_camera_model, camera, P);
    if (!pixel || pixel.u < margin || pixel.v < margin || pixel.u > camera.width - 1 - margin || pixel.v > camera.height - 1 - margin) continue;
    facing.push({ index: i, P, pixel });
  }
  // Farthest-point order in the image, from the point nearest the image centre.
  const chosen = [];
  const remaining = [...facing];
  const cx = camera.width / 2;
  const cy = camera.height / 2;
  remaining.sort((a, b) => Math.hypot(a.pixel.u - cx, a.pixel.v - cy) - Math.hypot(b.pixel.u - cx, b.pixel.v - cy));
  while (chosen.length < count && remaining.length) {
    let best = 0;
    let bestDistance = -1;
    if (chosen.length) {
      remaining.forEach((c, k) => {
        const d = Math.min(...chosen.map((o) => Math.hypot(o.pixel.u - c.pixel.u, o.pixel.v - c.pixel.v)));
        if (d > bestDistance) {
          bestDistance = d;
          best = k;
        }
      });
      if (bestDistance < minSeparationPx) break;
    }
    const [candidate] = remaining.splice(best, 1);
    if (!occluded(vertices, triangles, centre, candidate.P)) chosen.push(candidate);
  }
  return chosen;
}
