// scopetrack-studio register in a browser: pairs picked by clicking the
// frame and the mesh give frame 0's true pose; Save writes it where the
// tracker accepts it.

import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { test } from 'node:test';
import * as h from './studio-helpers.mjs';

const WANTED_PAIRS = 7;
const PICK_TOLERANCE_MM = 2;

test('register: clicked pairs recover the true pose, and Save writes it', { timeout: 120000 }, async (t) => {
  const { seq, camera, truth, studio, page } = await h.openRegister(t, 'studio-register', 3);
  assert.equal(await page.evaluate(() => window.studio.mode), 'register');

  const mesh = await h.pageMesh(page);
  assert.ok(mesh.vertices.length > 0 && mesh.triangles.length > 0, 'the page has the mesh');
  const candidates = h.visibleVertices(mesh, truth, camera, { count: 16, minSeparationPx: 45 });
  assert.ok(candidates.length >= WANTED_PAIRS, `only ${candidates.length} well-spread vertices face the camera`);

  let added = 0;
  const dropped = [];
  for (const c of candidates) {
    if (added === WANTED_PAIRS) break;
    const pair = await h.addPair(page, c.pixel, c.P);
    if (!pair) {
      dropped.push(`vertex ${c.index}: behind the 3D view's camera`);
      continue;
    }
    const offBy = h.distance([pair.x, pair.y, pair.z], c.P);
    assert.ok(Math.abs(pair.u - c.pixel.u) < 0.6 && Math.abs(pair.v - c.pixel.v) < 0.6, `pixel ${pair.u},${pair.v} for ${c.pixel.u},${c.pixel.v}`);
    if (offBy > PICK_TOLERANCE_MM) {
      // Hidden from the 3D view's side, or at a grazing angle: drop it.
      dropped.push(`vertex ${c.index}: picked ${offBy.toFixed(2)} mm away`);
      await h.removePair(page, added);
      continue;
    }
    added++;
  }
  assert.ok(added >= 6, `only ${added} pairs could be picked (${dropped.join('; ')})`);

  const registration = await page.evaluate(() => window.studio.lastRegistration);
  assert.equal(registration.ok, true, `registration failed: ${registration.message}`);
  assert.equal(registration.pairs, added);
  const rotationError = h.rotationDifferenceDeg(registration.T_camera_model, truth);
  const centreError = h.distance(h.cameraCentre(registration.T_camera_model), h.cameraCentre(truth));
  t.diagnostic(`${added} pairs (${dropped.length} dropped), RMS ${registration.rms_px.toFixed(3)} px, ` +
    `error ${rotationError.toFixed(3)} deg, ${centreError.toFixed(3)} mm`);
  assert.ok(rotationError < 1, `rotation off by ${rotationError.toFixed(3)} deg`);
  assert.ok(centreError < 2, `camera centre off by ${centreError.toFixed(3)} mm`);
  assert.equal(await page.locator('#pairs tr.pair').count(), added);
  const message = await h.message(page);
  assert.equal(message.kind, 'ok', message.text);

  // Editing: select pair 2's row and click the frame 30 px off (its pixel
  // moves, the pair turns outlier), then drag its marker back.
  const pairsNow = await page.evaluate(() => window.studio.pairs());
  const right = { u: pairsNow[1].u, v: pairsNow[1].v };
  const wrong = { u: right.u + (right.u > camera.width / 2 ? -30 : 30), v: right.v };
  let before = await h.pairState(page);
  await page.click('#pairs tr.pair:nth-child(2) td.number');
  assert.equal(await page.locator('#pairs tr.pair.selected').count(), 1, 'the row is selected');
  await h.clickFrame(page, wrong.u, wrong.v);
  await h.waitAnswer(page, before, added);
  const moved = await page.evaluate(() => ({ pair: window.studio.pairs()[1], answer: window.studio.lastRegistration }));
  assert.ok(Math.abs(moved.pair.u - wrong.u) < 0.6, 'the selected pair took the new pixel');
  assert.ok(!moved.answer.ok || moved.answer.inlier[1] === false || moved.answer.rms_px > 1, 'the moved pair spoils the fit');
  before = await h.pairState(page);
  const from = await page.evaluate(([u, v]) => window.studio.frameToClient(u, v), [wrong.u, wrong.v]);
  const to = await page.evaluate(([u, v]) => window.studio.frameToClient(u, v), [right.u, right.v]);
  await page.mouse.move(from.x, from.y);
  await page.mouse.down();
  await page.mouse.move(to.x, to.y, { steps: 8 });
  await page.mouse.up();
  await h.waitAnswer(page, before, added);
  const back = await page.evaluate(() => ({ pair: window.studio.pairs()[1], answer: window.studio.lastRegistration }));
  assert.ok(Math.abs(back.pair.u - right.u) < 0.6 && Math.abs(back.pair.v - right.v) < 0.6, 'the dragged marker is back');
  assert.equal(back.answer.ok, true);
  assert.equal(back.answer.inliers, added);
  // The row is still selected for its model point: Esc ends that.
  await page.keyboard.press('Escape');
  assert.equal(await page.locator('#pairs tr.pair.selected').count(), 0);

  // The overlay shows the organ at the result.
  const drawn = await page.evaluate(() => window.studio.overlayAlpha().reduce((n, a) => n + (a > 0 ? 1 : 0), 0));
  assert.ok(drawn > 0.05 * camera.width * camera.height, `the overlay covers only ${drawn} pixels`);
  await h.screenshot(page, 'studio-register.png');

  // The 3D view from an axis, then from the registered scope: the first
  // pick's model point comes back to where it was seen from the scope.
  const P = await page.evaluate(() => window.studio.pairs()[0]);
  await page.click('#view-buttons button[data-axis="0,0,-1"]');
  const fromAxis = await page.evaluate(([x, y, z]) => window.studio.meshToClient(x, y, z), [P.x, P.y, P.z]);
  assert.ok(await page.locator('#view-result').isVisible(), 'the view from the registered scope is offered');
  await page.click('#view-result');
  const fromScope = await page.evaluate(([x, y, z]) => window.studio.meshToClient(x, y, z), [P.x, P.y, P.z]);
  assert.ok(fromAxis && fromScope && Math.hypot(fromAxis.x - fromScope.x, fromAxis.y - fromScope.y) > 1,
    'the view buttons move the 3D view');

  await page.click('#save');
  await page.waitForFunction(() => /Saved/.test(window.studio.lastMessage), null, { timeout: 15000 });
  const saved = await h.message(page);
  assert.equal(saved.kind, 'ok', saved.text);
  assert.ok(fs.existsSync(path.join(seq, 'sequence.yaml.bak')), 'sequence.yaml.bak kept');
  const pairsFile = fs.readFileSync(path.join(seq, 'registration_pairs.txt'), 'utf8');
  assert.equal(pairsFile.split('\n').filter((l) => l.trim() && !l.startsWith('#')).length, added);
  const check = await h.run(h.env.tracker, ['--check', seq]);
  assert.equal(check.code, 0, `scopetrack --check refuses the saved sequence:\n${check.stdout}${check.stderr}`);

  assert.deepEqual(page.errors, []);
  assert.ok(studio.alive(), `scopetrack-studio stopped\n${studio.output()}`);
});
