// The page of scopetrack-studio: connects to the server, and on its `info`
// message opens the register or the watch view.

import { Connection } from './connection';
import { FrameView } from './frame-view';
import { hooks } from './hooks';
import type { Vec3 } from './geometry';
import { MeshView, WebGLUnavailable } from './mesh-view';
import type { BinaryMessage, InfoMessage, ServerJson } from './protocol';
import { RegisterView } from './register';
import { byId, setText, showMessage } from './ui';
import type { View } from './view';
import { WatchView } from './watch';

function start(): void {
  showMessage('info', 'Connecting to scopetrack-studio...');
  const frame = new FrameView();
  hooks.overlayAlpha = () => frame.overlayAlpha();
  let view: View | null = null;
  let refused = false;
  const early: BinaryMessage[] = []; // binary messages that came before `info`

  const connection = new Connection({
    json(message: ServerJson) {
      if (view) {
        view.json(message);
      } else if (message.type === 'info' && message.mode !== 'register' && message.mode !== 'watch') {
        showMessage('error', `This page does not know the studio's mode "${String(message.mode)}": rebuild the page with the server.`);
      } else if (message.type === 'info') {
        view = openView(message, connection, frame);
        for (const binary of early.splice(0)) view.binary(binary);
      } else if (message.type === 'error') {
        // Before `info`: the server refuses the sequence; nothing else will come.
        refused = true;
        document.body.dataset.state = 'refused';
        showMessage('error', message.message, ['Fix the sequence folder, restart scopetrack-studio, then reload this page.']);
        setText('status', 'scopetrack-studio refused the sequence');
      }
    },
    binary(message: BinaryMessage) {
      if (view) view.binary(message);
      else if (early.length < 16) early.push(message);
    },
    garbled(what: string) {
      console.warn(`scopetrack-studio sent ${what}`);
    },
    closed(wasOpen: boolean) {
      hooks.ready = false;
      document.body.dataset.connection = 'closed';
      setText('status', 'not connected');
      if (refused) return;
      showMessage(
        'error',
        wasOpen
          ? 'The connection to scopetrack-studio was lost: restart it if it stopped, then reload this page.'
          : 'Cannot connect to scopetrack-studio: is it running? Start it, then reload this page.',
      );
    },
  });
  hooks.send = (command) => connection.send(command);
}

function openView(info: InfoMessage, connection: Connection, frame: FrameView): View {
  hooks.mode = info.mode;
  document.body.dataset.mode = info.mode;
  document.title = `ScopeTrack Studio: ${info.mode} ${info.sequence}`;
  setText('sequence-name', info.sequence);
  setText('mode-name', info.mode === 'register' ? 'register' : 'watch');
  const frames = info.frames >= 0 ? `${info.frames} frames` : 'frame count unknown';
  setText(
    'status',
    `${info.sequence}: ${info.width}x${info.height}, ${frames}, ${info.fps > 0 ? `${info.fps} fps` : 'fps unknown'}` +
      (info.mode === 'watch' && info.endpoint ? `; stream ${info.endpoint}` : ''),
  );
  frame.setSize(info.width, info.height);

  let mesh: MeshView | null = null;
  let webglError: string | null = null;
  try {
    mesh = new MeshView(byId('mesh-view'));
    // Orienting the mesh like the frame is the slow part of a first
    // registration: views along the model's axes.
    for (const button of document.querySelectorAll<HTMLButtonElement>('#view-buttons button[data-axis]')) {
      const axis = (button.dataset.axis ?? '0,0,1').split(',').map(Number) as Vec3;
      const view3d = mesh;
      button.addEventListener('click', () => view3d.viewAlong(axis));
    }
  } catch (error) {
    if (!(error instanceof WebGLUnavailable)) throw error;
    webglError = error.message;
  }
  const view =
    info.mode === 'register'
      ? new RegisterView(info, connection, frame, mesh)
      : new WatchView(info, frame, mesh);
  if (webglError !== null) showNoWebGL(info, webglError);
  return view;
}

/** Says why the 3D view is empty: in the view itself and in #message. */
function showNoWebGL(info: InfoMessage, reason: string): void {
  const box = byId('mesh-view');
  const note = document.createElement('p');
  note.className = 'no-webgl';
  note.textContent = 'The 3D view needs WebGL, which this browser could not start.';
  box.append(note);
  box.dataset.webgl = 'unavailable';
  showMessage('error', 'The 3D view needs WebGL, which this browser could not start: the mesh cannot be shown.', [
    info.mode === 'register'
      ? 'Picking points on the mesh is not possible: open this page in a browser with WebGL 2 (or turn on hardware acceleration).'
      : 'The frame and the tracking state still show; open this page in a browser with WebGL 2 to see the mesh.',
    `(${reason})`,
  ]);
}

try {
  start();
} catch (error) {
  showMessage('error', `The page could not start: ${(error as Error).message}`);
}
