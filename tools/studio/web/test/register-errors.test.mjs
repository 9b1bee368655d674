// scopetrack-studio register in a browser: the picks that cannot give a pose
// are told in #message, each with its own reason.

import assert from 'node:assert/strict';
import { test } from 'node:test';
import * as h from './studio-helpers.mjs';

/** Spread of 3D points along their two main axes (standard deviations, largest first). */
function principalSpread(points) {
  const n = points.length;
  const c = [0, 1, 2].map((k) => points.reduce((s, p) => s + p[k], 0) / n);
  const cov = [0, 1, 2].map((i) => [0, 1, 2].map((j) => points.reduce((s, p) => s + (p[i] - c[i]) * (p[j] - c[j]), 0) / n));
  // Power iteration for the largest axis, then the largest of what is left.
  const axis = (M) => {
    let v = [1, 0.7, 0.3];
    for (let k = 0; k < 200; k++) {
      const w = [0, 1, 2].map((i) => M[i][0] * v[0] + M[i][1] * v[1] + M[i][2] * v[2]);
      const l = h.norm(w) || 1;
      v = w.map((x) => x / l);
    }
    const value = [0, 1, 2].reduce((s, i) => s + v[i] * (M[i][0] * v[0] + M[i][1] * v[1] + M[i][2] * v[2]), 0);
    return { v, value };
  };
  const first = axis(cov);
  const rest = cov.map((row, i) => row.map((x, j) => x - first.value * first.v[i] * first.v[j]));
  const second = axis(rest);
  return [Math.sqrt(Math.max(0, first.value)), Math.sqrt(Math.max(0, second.value))];
}

test('register: bad picks are explained', { timeout: 150000 }, async (t) => {
  const { camera, truth, studio, page } = await h.openRegister(t, 'studio-register-errors', 2);

  const mesh = await h.pageMesh(page);
  const normalOf = h.vertexNormals(mesh.vertices, mesh.triangles);
  const vertex = (i) => [mesh.vertices[3 * i], mesh.vertices[3 * i + 1], mesh.vertices[3 * i + 2]];
  const spread = h.visibleVertices(mesh, truth, camera, { count: 8, minSeparationPx: 60 });
  assert.ok(spread.length >= 4, 'four well-spread vertices face the camera');
  // Vertices the true camera sees, near the image centre first: seeds for small patches.
  const seen = h
    .visibleVertices(mesh, truth, camera, { count: 40, minSeparationPx: 15, maxAngleDeg: 40, margin: 60 })
    .sort((a, b) => Math.hypot(a.pixel.u - 320, a.pixel.v - 180) - Math.hypot(b.pixel.u - 320, b.pixel.v - 180));

  const fresh = async () => {
    await page.reload();
    await h.waitReady(page);
  };
  const lastAnswer = () => page.evaluate(() => window.studio.lastRegistration);

  await t.test('fewer than 4 pairs', async (st) => {
    for (let n = 1; n <= 3; n++) {
      const pair = await h.addPair(page, spread[n - 1].pixel, spread[n - 1].P);
      assert.ok(pair, 'the pair was added');
      const answer = await lastAnswer();
      assert.equal(answer.ok, false);
      const { text } = await h.message(page);
      assert.match(text, /at least 4 pairs/i);
      if (n === 3) st.diagnostic(text);
    }
  });

  await t.test('a click off the mesh', async (st) => {
    const corner = await page.evaluate(() => {
      const r = document.getElementById('mesh-view').getBoundingClientRect();
      return { x: r.left + 4, y: r.top + 4 };
    });
    await page.mouse.click(corner.x, corner.y);
    const { text, kind } = await h.message(page);
    assert.equal(kind, 'error');
    assert.match(text, /not on the mesh/i);
    st.diagnostic(text);
  });

  await t.test('all mesh points on one spot', async (st) => {
    await fresh();
    const spot = spread[0].P;
    const at = await page.evaluate((p) => window.studio.meshToClient(p[0], p[1], p[2]), spot);
    const before = await h.pairState(page);
    const offsets = [[0, 0], [1, 0], [0, 1], [1, 1]];
    for (let k = 0; k < 4; k++) {
      await h.clickFrame(page, spread[k].pixel.u, spread[k].pixel.v);
      await page.mouse.click(at.x + offsets[k][0], at.y + offsets[k][1]);
    }
    await h.waitAnswer(page, { answers: before.answers + 3 }, 4);
    const pairs = await page.evaluate(() => window.studio.pairs());
    for (const p of pairs) assert.ok(h.distance([p.x, p.y, p.z], spot) < 1.5, 'the picks are within ~1 mm');
    const answer = await lastAnswer();
    assert.equal(answer.ok, false);
    const { text, kind } = await h.message(page);
    assert.equal(kind, 'error');
    assert.match(text, /one spot/i);
    st.diagnostic(text);
  });

  await t.test('mesh points on one line', async (st) => {
    // Four points along a short chord of a flat part of the surface.
    let done = false;
    for (const seed of seen) {
      if (done) break;
      const nA = normalOf(seed.index);
      let partner = null;
      for (let i = 0; i < mesh.vertices.length / 3 && !partner; i++) {
        const d = h.distance(vertex(i), seed.P);
        if (d > 10 && d < 14 && h.dot(normalOf(i), nA) > 0.998) partner = vertex(i);
      }
      if (!partner) continue;
      await fresh();
      const before = await h.pairState(page);
      let added = 0;
      for (let k = 0; k < 4; k++) {
        const s = k / 3;
        const Q = [0, 1, 2].map((j) => seed.P[j] + s * (partner[j] - seed.P[j]));
        const pixel = h.project(truth, camera, Q);
        const pair = await h.addPair(page, pixel, Q);
        if (!pair) break;
        added++;
      }
      if (added < 4) continue;
      await h.waitAnswer(page, { answers: before.answers + 3 }, 4);
      const pairs = await page.evaluate(() => window.studio.pairs());
      const [first, second] = principalSpread(pairs.map((p) => [p.x, p.y, p.z]));
      if (second > 0.02 * first) continue; // the surface bends here: try another chord
      const answer = await lastAnswer();
      assert.equal(answer.ok, false, 'collinear picks give no pose');
      const { text, kind } = await h.message(page);
      assert.equal(kind, 'error');
      assert.match(text, /one line/i);
      st.diagnostic(text);
      done = true;
    }
    assert.ok(done, 'found a flat chord to pick four collinear points on');
  });

  await t.test('mirrored picks put the camera behind the surface', async (st) => {
    // Five points of a ~15 mm near-planar patch, their true pixels mirrored left-right.
    let done = false;
    for (const seed of seen.slice(0, 10)) {
      const n0 = normalOf(seed.index);
      const patch = [];
      for (let i = 0; i < mesh.vertices.length / 3; i++) {
        const P = vertex(i);
        if (h.distance(P, seed.P) < 7.5 && h.dot(normalOf(i), n0) > 0.99) patch.push(P);
      }
      // Farthest-point choice of 5 from the patch, from its seed.
      const chosen = [seed.P];
      while (chosen.length < 5 && patch.length) {
        let best = null;
        let bestD = -1;
        for (const P of patch) {
          const d = Math.min(...chosen.map((c) => h.distance(c, P)));
          if (d > bestD) {
            bestD = d;
            best = P;
          }
        }
        if (bestD < 3) break;
        chosen.push(best);
      }
      if (chosen.length < 5) continue;
      const pixels = chosen.map((P) => h.project(truth, camera, P));
      const meanU = pixels.reduce((s, p) => s + p.u, 0) / pixels.length;
      await fresh();
      const before = await h.pairState(page);
      let added = 0;
      for (let k = 0; k < 5; k++) {
        const pair = await h.addPair(page, { u: 2 * meanU - pixels[k].u, v: pixels[k].v }, chosen[k]);
        if (!pair || h.distance([pair.x, pair.y, pair.z], chosen[k]) > 1.5) break;
        added++;
      }
      if (added < 5) continue;
      await h.waitAnswer(page, { answers: before.answers + 4 }, 5);
      const answer = await lastAnswer();
      const { text, kind } = await h.message(page);
      assert.equal(answer.ok, false, `mirrored picks were accepted: ${JSON.stringify(answer)}`);
      assert.equal(kind, 'error');
      assert.match(text, /behind|inside/i);
      st.diagnostic(text);
      done = true;
      break;
    }
    assert.ok(done, 'found a flat patch of five points');
  });

  assert.deepEqual(page.errors, []);
  assert.ok(studio.alive(), `scopetrack-studio stopped\n${studio.output()}`);
});
