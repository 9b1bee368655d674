// window.studio: the values and functions the browser tests read.

import type { Pair, RegistrationMessage } from './protocol';

export interface WatchHook {
  hello: boolean;
  poses: number; // PoseUpdates received in this run
  coloured: number; // distinct triangles coloured by ColourDelta
  fps: number; // the last Health.fps
  link: string; // the last link state
  path: number; // points on the scope's path
}

export interface StudioHooks {
  ready: boolean;
  mode: 'register' | 'watch' | null;
  lastMessage: string;
  lastRegistration: RegistrationMessage | null;
  registrations: number; // registration answers received so far
  shown: { frame: number; state: string } | null;
  watch: WatchHook;
  meshVertices(): Float32Array;
  meshTriangles(): Uint32Array;
  meshToClient(x: number, y: number, z: number): { x: number; y: number } | null;
  frameToClient(u: number, v: number): { x: number; y: number } | null;
  pairs(): Pair[];
  overlayAlpha(): Uint8Array;
  /** Sends a raw text command to the server (for tests); false when not connected. */
  send(command: string): boolean;
}

export const hooks: StudioHooks = {
  ready: false,
  mode: null,
  lastMessage: '',
  lastRegistration: null,
  registrations: 0,
  shown: null,
  watch: { hello: false, poses: 0, coloured: 0, fps: 0, link: 'connecting', path: 0 },
  meshVertices: () => new Float32Array(0),
  meshTriangles: () => new Uint32Array(0),
  meshToClient: () => null,
  frameToClient: () => null,
  pairs: () => [],
  overlayAlpha: () => new Uint8Array(0),
  send: () => false,
};

declare global {
  interface Window {
    studio: StudioHooks;
  }
}

window.studio = hooks;
