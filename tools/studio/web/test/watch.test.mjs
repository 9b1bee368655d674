// scopetrack-studio watch in a browser: a tracker run streamed live. What
// the page shows (frame number, state, overlay) belongs to one frame, and a
// page that connects late catches up.

import assert from 'node:assert/strict';
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { test } from 'node:test';
import * as h from './studio-helpers.mjs';

/** frames.csv -> Map(frame -> state). */
function readStates(runDir) {
  const [header, ...rows] = fs.readFileSync(path.join(runDir, 'frames.csv'), 'utf8').trim().split('\n');
  const columns = header.split(',');
  const frameColumn = columns.indexOf('frame');
  const stateColumn = columns.indexOf('state');
  return new Map(rows.map((row) => {
    const cells = row.split(',');
    return [Number(cells[frameColumn]), cells[stateColumn]];
  }));
}

/** The overlay's alpha with the frame it belongs to, read in one go. */
function grabOverlay(page) {
  return page.evaluate(() => {
    const shown = window.studio.shown;
    if (!shown) return null;
    const alpha = window.studio.overlayAlpha();
    let binary = '';
    for (let i = 0; i < alpha.length; i += 0x8000) binary += String.fromCharCode(...alpha.subarray(i, i + 0x8000));
    return { frame: shown.frame, state: shown.state, alpha: btoa(binary) };
  });
}

test('watch: a live run, frame by frame, and a late console', { timeout: 150000 }, async (t) => {
  const dir = h.workDir('studio-watch');
  const seq = await h.makeSequence(dir, { frames: 90, size: '640x360' });
  const runDir = path.join(dir, 'run');
  const port = await h.freePort();
  const endpoint = `tcp://127.0.0.1:${port}`;

  const studio = await h.startStudio(['watch', seq, '--stream', endpoint, '--port', '0']);
  t.after(() => studio.stop());
  const browser = await h.launchBrowser();
  t.after(() => browser.close());
  const page = await h.openPage(browser, studio.url);
  await page.waitForFunction(() => window.studio.mode === 'watch' && window.studio.meshVertices().length > 0, null, { timeout: 20000 });
  assert.equal(await page.evaluate(() => window.studio.shown), null, 'nothing shown before the run');

  // The tracker, paced at the video's frame rate: ~3 s of frames.
  const trackerArgs = ['--sequence', seq, '--out', runDir, '--stream', endpoint, '--stream-wait', '1', '--realtime'];
  const tracker = spawn(h.env.tracker, trackerArgs, { stdio: ['ignore', 'pipe', 'pipe'] });
  let trackerLog = '';
  tracker.stdout.on('data', (d) => (trackerLog += d));
  tracker.stderr.on('data', (d) => (trackerLog += d));
  const trackerDone = new Promise((resolve) => tracker.on('exit', (code) => resolve(code)));
  let trackerExit = null;
  let trackerExitTime = 0;
  trackerDone.then((code) => {
    trackerExit = code;
    trackerExitTime = Date.now();
  });
  t.after(() => {
    if (trackerExit === null) tracker.kill('SIGKILL');
  });

  const samples = [];
  let grab = null;
  let late = null;
  const deadline = Date.now() + 60000;
  // Sample during the run, and for a moment after it: the page may lag the tracker a little.
  while ((trackerExit === null || Date.now() - trackerExitTime < 1500) && Date.now() < deadline) {
    const shown = await page.evaluate(() => window.studio.shown && { ...window.studio.shown });
    if (shown) samples.push(shown);
    if (!grab && shown && shown.state === 'tracking' && shown.frame >= 10) {
      const g = await grabOverlay(page);
      if (g && g.state === 'tracking') grab = g;
    }
    if (!late && shown && shown.frame >= 20) late = h.openPage(browser, studio.url); // a console that connects late (not awaited: sampling goes on)
    await h.sleep(120);
  }
  assert.equal(await trackerDone, 0, `the tracker failed:\n${trackerLog}`);

  // What was on screen: advancing frames, each with its own frame's state.
  const states = readStates(runDir);
  const frames = samples.map((s) => s.frame);
  t.diagnostic(`${samples.length} samples, frames ${frames[0]}..${frames[frames.length - 1]}`);
  assert.ok(new Set(frames).size >= 5, `the frame number hardly moved: ${frames.join(' ')}`);
  for (let i = 1; i < frames.length; i++) assert.ok(frames[i] >= frames[i - 1], `frames went back: ${frames.join(' ')}`);
  for (const s of samples) assert.equal(s.state, states.get(s.frame), `frame ${s.frame} shown as ${s.state}, frames.csv says ${states.get(s.frame)}`);

  // The overlay drawn for one tracked frame against the organ's true mask.
  assert.ok(grab, 'an overlay of a tracked frame was grabbed');
  const maskFile = path.join(dir, `mask-${grab.frame}.pgm`);
  await h.mustRun(h.env.studio, ['mask', seq, '--frame', String(grab.frame), '--out', maskFile]);
  const mask = h.readPgm(maskFile);
  const alpha = Buffer.from(grab.alpha, 'base64');
  assert.equal(alpha.length, mask.width * mask.height, 'the overlay has the frame size');
  let both = 0;
  let either = 0;
  for (let i = 0; i < alpha.length; i++) {
    const drawn = alpha[i] > 0;
    const organ = mask.data[i] > 0;
    if (drawn && organ) both++;
    if (drawn || organ) either++;
  }
  const iou = both / either;
  t.diagnostic(`frame ${grab.frame}: IoU ${iou.toFixed(3)} of the overlay and the true mask`);
  assert.ok(iou >= 0.9, `IoU ${iou.toFixed(3)} < 0.9 on frame ${grab.frame}`);

  // The page after the run: the last frame, its state, the link.
  await page.waitForFunction(() => window.studio.watch.link !== 'connected', null, { timeout: 10000 });
  await h.sleep(500); // the last frame may still be on its way
  const watch = await page.evaluate(() => ({
    ...window.studio.watch,
    shown: window.studio.shown,
    stateText: document.getElementById('state').textContent.trim(),
    frameText: document.getElementById('frame-number').textContent.trim(),
  }));
  assert.equal(watch.hello, true);
  assert.ok(watch.poses >= 80, `${watch.poses} poses`);
  assert.ok(watch.coloured > 0, 'triangles coloured');
  assert.ok(watch.path > 0, 'the path has points');
  assert.equal(watch.stateText, watch.shown.state, '#state shows the state of the frame shown');
  assert.equal(watch.frameText, String(watch.shown.frame), '#frame-number shows the frame shown');
  assert.equal(watch.shown.state, states.get(watch.shown.frame));
  await h.screenshot(page, 'studio-watch.png');

  // The late console caught up.
  assert.ok(late, 'a second page was opened during the run');
  late = await late;
  await late.waitForFunction(
    () => window.studio.watch.hello && window.studio.watch.coloured > 0 && window.studio.watch.path > 0 && window.studio.shown !== null,
    null,
    { timeout: 20000 },
  );
  const caught = await late.evaluate(() => ({ ...window.studio.watch, shown: window.studio.shown }));
  t.diagnostic(`late page: ${JSON.stringify(caught)}`);
  assert.equal(caught.shown.state, states.get(caught.shown.frame));

  assert.deepEqual(page.errors, []);
  assert.deepEqual(late.errors, []);
  assert.ok(studio.alive(), `scopetrack-studio stopped\n${studio.output()}`);
});
