// The WebSocket protocol between scopetrack-studio and this page (see the
// contract in the studio's design notes): JSON text messages, binary messages
// with an 8-byte header, and the console stream's FlatBuffers.

import * as flatbuffers from 'flatbuffers';
import {
  ColourDelta,
  Health,
  Hello,
  Message,
  Payload,
  PoseSource,
  PoseUpdate,
} from 'studio-gen/console_stream_generated';

// ---------------------------------------------------------------- JSON (server -> page)

export type Mat4 = number[]; // 16 numbers, row-major

export interface InfoMessage {
  type: 'info';
  mode: 'register' | 'watch';
  sequence: string;
  width: number;
  height: number;
  frames: number;
  frame: number;
  fps: number;
  has_groundtruth: boolean;
  endpoint?: string;
  T_camera_model_init: Mat4;
  K: [number, number, number, number];
  distortion: [number, number, number, number, number];
  /** register: what `scopetrack --check` says against the current pose ('' when it passes). */
  check?: string;
}

export interface RegistrationOk {
  type: 'registration';
  ok: true;
  pairs: number;
  inliers: number;
  rms_px: number;
  residual_px: number[];
  inlier: boolean[];
  T_camera_model: Mat4;
  change_deg: number;
  change_mm: number;
  warnings?: string[];
}

export interface RegistrationFailed {
  type: 'registration';
  ok: false;
  message: string;
}

export type RegistrationMessage = RegistrationOk | RegistrationFailed;

export interface SavedMessage {
  type: 'saved';
  yaml: string;
  backup: string;
  pairs: string;
}

export interface ErrorMessage {
  type: 'error';
  message: string;
}

export type LinkState = 'connecting' | 'connected' | 'disconnected';

export interface LinkMessage {
  type: 'link';
  state: LinkState;
  endpoint?: string;
  message?: string;
}

export interface FramesMessage {
  type: 'frames';
  count: number;
}

export type ServerJson =
  | InfoMessage
  | RegistrationMessage
  | SavedMessage
  | ErrorMessage
  | LinkMessage
  | FramesMessage;

/** Parses a text message; null when it is not a JSON object with a string `type`. */
export function parseJson(text: string): ServerJson | null {
  try {
    const value: unknown = JSON.parse(text);
    if (typeof value === 'object' && value !== null && typeof (value as { type?: unknown }).type === 'string') {
      return value as ServerJson;
    }
  } catch {
    // not JSON: handled by the caller
  }
  return null;
}

// ---------------------------------------------------------------- binary (server -> page)

export enum BinaryKind {
  Mesh = 1,
  Frame = 2,
  Overlay = 3,
  Stream = 4,
}

export interface BinaryMessage {
  kind: BinaryKind;
  frame: number;
  payload: Uint8Array;
}

const HEADER_BYTES = 8;

/** Splits a binary message into its header and payload; null if it is too short. */
export function parseBinary(data: ArrayBuffer): BinaryMessage | null {
  if (data.byteLength < HEADER_BYTES) return null;
  const view = new DataView(data);
  return {
    kind: view.getUint8(0) as BinaryKind,
    frame: view.getUint32(4, true),
    payload: new Uint8Array(data, HEADER_BYTES),
  };
}

export interface MeshData {
  vertices: Float32Array; // 3 per vertex, model mm
  triangles: Uint32Array; // 3 vertex indices per triangle
}

/** Decodes a MESH payload; throws with a clear text when it is inconsistent. */
export function decodeMesh(payload: Uint8Array): MeshData {
  const view = new DataView(payload.buffer, payload.byteOffset, payload.byteLength);
  if (payload.byteLength < 8) throw new Error('the mesh message is too short');
  const nv = view.getUint32(0, true);
  const nt = view.getUint32(4, true);
  const expected = 8 + 12 * nv + 12 * nt;
  if (payload.byteLength !== expected) {
    throw new Error(`the mesh message has ${payload.byteLength} bytes, ${expected} expected for ${nv} vertices and ${nt} triangles`);
  }
  const vertices = new Float32Array(3 * nv);
  for (let i = 0; i < vertices.length; i++) vertices[i] = view.getFloat32(8 + 4 * i, true);
  const triangles = new Uint32Array(3 * nt);
  const base = 8 + 12 * nv;
  for (let i = 0; i < triangles.length; i++) {
    const index = view.getUint32(base + 4 * i, true);
    if (index >= nv) throw new Error(`mesh triangle ${Math.floor(i / 3)} names vertex ${index} of ${nv}`);
    triangles[i] = index;
  }
  return { vertices, triangles };
}

/**
 * FNV-1a 64 of the mesh as the tracker computes it (hal/stream/stream_protocol.cpp):
 * the bytes of all x, then all y, then all z (float32), then the triangle
 * indices (int32), little-endian. Returned as a BigInt.
 */
export function meshChecksum(mesh: MeshData): bigint {
  const nv = mesh.vertices.length / 3;
  const coords = new Float32Array(3 * nv);
  for (let i = 0; i < nv; i++) {
    coords[i] = mesh.vertices[3 * i];
    coords[nv + i] = mesh.vertices[3 * i + 1];
    coords[2 * nv + i] = mesh.vertices[3 * i + 2];
  }
  // 64-bit FNV-1a in two 32-bit halves: h * 0x100000001b3 = h * 0x1b3 + (h << 40).
  let hi = 0xcbf29ce4;
  let lo = 0x84222325;
  const eat = (bytes: Uint8Array) => {
    for (let i = 0; i < bytes.length; i++) {
      lo = (lo ^ bytes[i]) >>> 0;
      const loProduct = lo * 0x1b3; // < 2^41: exact in a double
      const carry = Math.floor(loProduct / 0x100000000);
      hi = (Math.imul(hi, 0x1b3) + carry + (lo << 8)) >>> 0;
      lo = loProduct >>> 0;
    }
  };
  eat(new Uint8Array(coords.buffer));
  eat(new Uint8Array(new Int32Array(mesh.triangles).buffer));
  return (BigInt(hi) << 32n) | BigInt(lo);
}

// ---------------------------------------------------------------- console stream (kind STREAM)

export type TrackingStateName = 'initialised' | 'tracking' | 'relocalised' | 'lost';
export const STATE_NAMES: TrackingStateName[] = ['initialised', 'tracking', 'relocalised', 'lost'];

export function stateName(state: number): TrackingStateName | 'unknown' {
  return STATE_NAMES[state] ?? 'unknown';
}

export interface HelloEvent {
  kind: 'hello';
  protocolVersion: number;
  meshTriangles: number;
  meshChecksum: bigint;
  width: number;
  height: number;
  fps: number;
}

export interface PoseEvent {
  kind: 'pose';
  frame: number;
  state: TrackingStateName | 'unknown';
  inliers: number;
  quality: number;
  latencyMs: number;
  q: [number, number, number, number]; // x, y, z, w of T_model_camera
  t: [number, number, number]; // camera centre, model mm
  source: 'features' | 'outline' | null;
}

export interface ColoursEvent {
  kind: 'colours';
  triangles: Uint32Array;
  rgb: Uint8Array; // 3 per triangle
}

export interface HealthEvent {
  kind: 'health';
  fps: number;
  overruns: number;
  droppedMessages: number;
  frames: number;
  calibrationSuspect: boolean;
  calibrationFocalScale: number;
}

export type StreamEvent = HelloEvent | PoseEvent | ColoursEvent | HealthEvent;

const SIZE_PREFIX = 4;
const IDENTIFIER = 'STCS';

/** Decodes one size-prefixed console-stream buffer; throws on a malformed one. */
export function decodeStream(bytes: Uint8Array): StreamEvent | null {
  if (bytes.byteLength < SIZE_PREFIX + 8) throw new Error('stream message too short');
  const size = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength).getUint32(0, true);
  if (size + SIZE_PREFIX > bytes.byteLength) throw new Error('stream message shorter than its size prefix');
  const bb = new flatbuffers.ByteBuffer(bytes.slice(0, SIZE_PREFIX + size));
  bb.setPosition(SIZE_PREFIX);
  if (!Message.bufferHasIdentifier(bb)) throw new Error(`stream message without the "${IDENTIFIER}" identifier`);
  bb.setPosition(0);
  const message = Message.getSizePrefixedRootAsMessage(bb);
  switch (message.payloadType()) {
    case Payload.Hello: {
      const hello: Hello = message.payload(new Hello());
      return {
        kind: 'hello',
        protocolVersion: hello.protocolVersion(),
        meshTriangles: hello.meshTriangleCount(),
        meshChecksum: hello.meshChecksum(),
        width: hello.imageWidth(),
        height: hello.imageHeight(),
        fps: hello.sourceFps(),
      };
    }
    case Payload.PoseUpdate: {
      const update: PoseUpdate = message.payload(new PoseUpdate());
      const pose = update.pose();
      if (!pose) return null;
      const evidence = update.evidence();
      return {
        kind: 'pose',
        frame: pose.frame(),
        state: stateName(pose.state()),
        inliers: pose.inliers(),
        quality: pose.quality(),
        latencyMs: pose.latencyUs() / 1000,
        q: [pose.qx(), pose.qy(), pose.qz(), pose.qw()],
        t: [pose.tx(), pose.ty(), pose.tz()],
        source: evidence ? (evidence.source() === PoseSource.Outline ? 'outline' : 'features') : null,
      };
    }
    case Payload.ColourDelta: {
      const delta: ColourDelta = message.payload(new ColourDelta());
      const n = delta.coloursLength();
      const triangles = new Uint32Array(n);
      const rgb = new Uint8Array(3 * n);
      for (let i = 0; i < n; i++) {
        const c = delta.colours(i);
        if (!c) continue;
        triangles[i] = c.triangle();
        rgb[3 * i] = c.r();
        rgb[3 * i + 1] = c.g();
        rgb[3 * i + 2] = c.b();
      }
      return { kind: 'colours', triangles, rgb };
    }
    case Payload.Health: {
      const health: Health = message.payload(new Health());
      return {
        kind: 'health',
        fps: health.fps(),
        overruns: health.overruns(),
        droppedMessages: health.droppedMessages(),
        frames: health.frames(),
        calibrationSuspect: health.calibrationSuspect(),
        calibrationFocalScale: health.calibrationFocalScale(),
      };
    }
    default:
      return null;
  }
}

// ---------------------------------------------------------------- commands (page -> server)

export interface Pair {
  u: number; // pixel of the shown frame (video pixels, pixel centres at integers)
  v: number;
  x: number; // model point, mm
  y: number;
  z: number;
}

function pairLines(pairs: Pair[]): string {
  const f = (value: number, digits: number) => value.toFixed(digits);
  return pairs
    .map((p) => `${f(p.u, 3)} ${f(p.v, 3)} ${f(p.x, 4)} ${f(p.y, 4)} ${f(p.z, 4)}`)
    .join('\n');
}

export function registerCommand(pairs: Pair[]): string {
  return pairs.length ? `register\n${pairLines(pairs)}` : 'register';
}

export function saveCommand(pairs: Pair[]): string {
  return pairs.length ? `save\n${pairLines(pairs)}` : 'save';
}

export function frameCommand(frame: number): string {
  return `frame ${frame}`;
}
