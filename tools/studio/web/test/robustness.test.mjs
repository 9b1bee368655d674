// scopetrack-studio survives what a page or the network may throw at it:
// a client gone mid-message, malformed WebSocket frames, malformed commands,
// and a sequence folder the tracker refuses. Also: a browser without WebGL
// gets a clear message instead of an empty 3D view.

import assert from 'node:assert/strict';
import crypto from 'node:crypto';
import fs from 'node:fs';
import net from 'node:net';
import path from 'node:path';
import { test } from 'node:test';
import * as h from './studio-helpers.mjs';

const WS_GUID = '258EAFA5-E914-47DA-95CA-C5AB0DC85B11';

/**
 * A WebSocket client written on a raw TCP socket, so that it can also send
 * what a browser never would. open() does the HTTP upgrade by hand.
 */
class RawWebSocket {
  constructor(url) {
    const u = new URL(url);
    this.host = u.hostname;
    this.port = Number(u.port);
    this.buffer = Buffer.alloc(0);
    this.messages = []; // {opcode, data}
    this.closed = false;
    this.waiters = [];
  }

  open() {
    return new Promise((resolve, reject) => {
      const key = crypto.randomBytes(16).toString('base64');
      const expected = crypto.createHash('sha1').update(key + WS_GUID).digest('base64');
      this.socket = net.connect(this.port, this.host);
      let handshaken = false;
      this.socket.on('error', (error) => {
        if (!handshaken) reject(error);
      });
      this.socket.on('close', () => {
        this.closed = true;
        this.wake();
        if (!handshaken) reject(new Error('closed during the handshake'));
      });
      this.socket.on('connect', () => {
        this.socket.write(
          `GET /ws HTTP/1.1\r\nHost: ${this.host}:${this.port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n` +
            `Sec-WebSocket-Key: ${key}\r\nSec-WebSocket-Version: 13\r\n\r\n`,
        );
      });
      this.socket.on('data', (chunk) => {
        this.buffer = Buffer.concat([this.buffer, chunk]);
        if (!handshaken) {
          const end = this.buffer.indexOf('\r\n\r\n');
          if (end < 0) return;
          const head = this.buffer.subarray(0, end).toString('latin1');
          this.buffer = this.buffer.subarray(end + 4);
          if (!/^HTTP\/1\.1 101/.test(head) || !head.includes(expected)) {
            reject(new Error(`the upgrade was refused:\n${head}`));
            return;
          }
          handshaken = true;
          resolve(this);
        }
        this.parse();
      });
    });
  }

  parse() {
    for (;;) {
      if (this.buffer.length < 2) return;
      const opcode = this.buffer[0] & 0x0f;
      let length = this.buffer[1] & 0x7f;
      let offset = 2;
      if (length === 126) {
        if (this.buffer.length < 4) return;
        length = this.buffer.readUInt16BE(2);
        offset = 4;
      } else if (length === 127) {
        if (this.buffer.length < 10) return;
        length = Number(this.buffer.readBigUInt64BE(2));
        offset = 10;
      }
      if (this.buffer.length < offset + length) return;
      this.messages.push({ opcode, data: this.buffer.subarray(offset, offset + length) });
      this.buffer = this.buffer.subarray(offset + length);
      this.wake();
    }
  }

  wake() {
    for (const w of this.waiters.splice(0)) w();
  }

  /** Waits until `predicate(messages)` holds or the socket closes; resolves with the predicate's value. */
  async until(predicate, timeoutMs = 10000) {
    const deadline = Date.now() + timeoutMs;
    for (;;) {
      const value = predicate(this.messages);
      if (value || this.closed || Date.now() > deadline) return value;
      await new Promise((resolve) => {
        this.waiters.push(resolve);
        setTimeout(resolve, 100);
      });
    }
  }

  /** One frame: FIN set, `opcode`, masked unless told otherwise. */
  static frame(opcode, payload, { mask = true } = {}) {
    const data = Buffer.from(payload);
    const head = [0x80 | opcode];
    const maskBit = mask ? 0x80 : 0;
    if (data.length < 126) head.push(maskBit | data.length);
    else head.push(maskBit | 126, data.length >> 8, data.length & 0xff);
    const parts = [Buffer.from(head)];
    if (mask) {
      const key = crypto.randomBytes(4);
      parts.push(key, Buffer.from(data.map((b, i) => b ^ key[i % 4])));
    } else {
      parts.push(data);
    }
    return Buffer.concat(parts);
  }

  send(bytes) {
    this.socket.write(bytes);
  }

  textMessages() {
    return this.messages.filter((m) => m.opcode === 1).map((m) => JSON.parse(m.data.toString('utf8')));
  }

  destroy() {
    this.socket.destroy();
  }
}

async function assertServes(browser, studio, what) {
  assert.ok(studio.alive(), `scopetrack-studio stopped after ${what}\n${studio.output()}`);
  const page = await h.openPage(browser, studio.url);
  await h.waitReady(page, 30000);
  await page.close();
}

test('robustness: the server outlives bad clients and bad sequences', { timeout: 150000 }, async (t) => {
  const dir = h.workDir('studio-robustness');
  const seq = await h.makeSequence(dir, { frames: 3, size: '640x360' });
  const studio = await h.startStudio(['register', seq, '--port', '0']);
  t.after(() => studio.stop());
  const browser = await h.launchBrowser();
  t.after(() => browser.close());
  const wsUrl = studio.url.replace(/^http/, 'ws') + 'ws';

  await t.test('a client that disconnects in the middle of a message', async () => {
    const ws = await new RawWebSocket(wsUrl).open();
    await ws.until((m) => m.some((x) => x.opcode === 1)); // the info
    const whole = RawWebSocket.frame(1, 'register\n' + '1 2 3 4 5\n'.repeat(60));
    ws.send(whole.subarray(0, Math.floor(whole.length / 2)));
    await h.sleep(100);
    ws.destroy();
    await h.sleep(300);
    await assertServes(browser, studio, 'a half message');
  });

  await t.test('malformed WebSocket frames end only their connection', async () => {
    const cases = {
      'an unmasked client frame': RawWebSocket.frame(1, 'register', { mask: false }),
      'a reserved opcode': RawWebSocket.frame(0x3, 'register'),
      'a text frame that is not UTF-8': RawWebSocket.frame(1, Buffer.from([0x66, 0xff, 0xfe, 0x0a])),
    };
    for (const [what, bytes] of Object.entries(cases)) {
      const ws = await new RawWebSocket(wsUrl).open();
      await ws.until((m) => m.some((x) => x.opcode === 1));
      ws.send(bytes);
      const ended = await ws.until((m) => ws.closed || m.some((x) => x.opcode === 8), 10000);
      assert.ok(ended, `the server kept a connection that sent ${what}`);
      ws.destroy();
    }
    await assertServes(browser, studio, 'malformed frames');
  });

  await t.test('a malformed command: an error, and the connection stays', async () => {
    // On a raw connection.
    const ws = await new RawWebSocket(wsUrl).open();
    await ws.until((m) => m.some((x) => x.opcode === 1));
    ws.send(RawWebSocket.frame(1, 'teleport 3 4'));
    const error = await ws.until(() => ws.textMessages().find((m) => m.type === 'error'));
    assert.ok(error, 'an error message came back');
    assert.match(error.message, /unknown command/i);
    const frames = ws.messages.filter((m) => m.opcode === 2 && m.data[0] === 2).length;
    ws.send(RawWebSocket.frame(1, 'frame 1'));
    const more = await ws.until((m) => m.filter((x) => x.opcode === 2 && x.data[0] === 2).length > frames);
    assert.ok(more && !ws.closed, 'the connection still answers');
    ws.destroy();

    // In the page: the error shows in #message, and the page goes on working.
    const page = await h.openPage(browser, studio.url);
    await h.waitReady(page);
    assert.equal(await page.evaluate(() => window.studio.send('frame one')), true);
    await page.waitForFunction(() => document.getElementById('message').dataset.kind === 'error', null, { timeout: 10000 });
    assert.match((await h.message(page)).text, /frame/i);
    await page.evaluate(() => window.studio.send('nonsense'));
    await page.waitForFunction(() => /unknown command/i.test(window.studio.lastMessage), null, { timeout: 10000 });
    await page.fill('#frame-index', '2');
    await page.click('#load-frame');
    await page.waitForFunction(() => /frame 2/.test(document.getElementById('frame-caption').textContent), null, { timeout: 10000 });
    assert.deepEqual(page.errors, []);
    await page.close();
  });

  await t.test('sequence folders the tracker refuses', async (st) => {
    const broken = [
      {
        name: 'missing-mesh',
        mode: 'register',
        words: /organ\.ply|mesh/i,
        make: (d) => fs.rmSync(path.join(d, 'organ.ply')),
      },
      {
        name: 'bad-camera',
        mode: 'watch',
        words: /camera|fx|focal|intrinsic|matrix/i,
        make: (d) => {
          const yaml = path.join(d, 'sequence.yaml');
          const text = fs.readFileSync(yaml, 'utf8').replace(/data: \[ [-+0-9.eE]+,/, 'data: [ -1.,');
          fs.writeFileSync(yaml, text);
        },
      },
    ];
    for (const b of broken) {
      const d = path.join(dir, b.name);
      fs.cpSync(seq, d, { recursive: true });
      b.make(d);
      const check = await h.run(h.env.tracker, ['--check', d]);
      assert.notEqual(check.code, 0, `scopetrack --check accepts ${b.name}`);
      const args = b.mode === 'watch' ? ['watch', d, '--stream', `tcp://127.0.0.1:${await h.freePort()}`, '--port', '0'] : ['register', d, '--port', '0'];
      const bad = await h.startStudio(args);
      try {
        const page = await h.openPage(browser, bad.url);
        await page.waitForFunction(() => document.getElementById('message').dataset.kind === 'error', null, { timeout: 15000 });
        const { text } = await h.message(page);
        st.diagnostic(`${b.name}: ${text}`);
        assert.match(text, b.words);
        assert.equal(await page.evaluate(() => window.studio.mode), null, 'no view opened');
        await page.reload();
        await page.waitForFunction(() => document.getElementById('message').dataset.kind === 'error', null, { timeout: 15000 });
        await h.sleep(500);
        assert.ok(bad.alive(), `scopetrack-studio stopped on ${b.name}\n${bad.output()}`);
        await page.close();
      } finally {
        await bad.stop();
      }
    }
  });

  await t.test('a browser without WebGL gets a clear message', async () => {
    const noGl = await h.launchBrowser(['--disable-3d-apis', '--disable-webgl']);
    try {
      const page = await h.openPage(noGl, studio.url);
      await page.waitForFunction(() => window.studio.mode === 'register', null, { timeout: 15000 });
      await page.waitForFunction(() => /WebGL/.test(window.studio.lastMessage), null, { timeout: 15000 });
      const { kind } = await h.message(page);
      assert.equal(kind, 'error');
      assert.match(await page.textContent('#mesh-view'), /needs WebGL/);
    } finally {
      await noGl.close();
    }
  });

  await assertServes(browser, studio, 'all of it');
});
