// The watch view: the tracker's live run as a console sees it. The frame and
// its overlay are swapped together, with the state of the same frame's pose;
// the 3D view shows the mesh coloured by ColourDelta, the scope's path and
// the current camera.

import * as THREE from 'three';
import { decodeImage, FrameView } from './frame-view';
import { cameraModelFromPose, isMat4 } from './geometry';
import { hooks } from './hooks';
import { linearColour, MeshView } from './mesh-view';
import {
  BinaryKind,
  decodeMesh,
  decodeStream,
  meshChecksum,
  type BinaryMessage,
  type ColoursEvent,
  type HealthEvent,
  type HelloEvent,
  type InfoMessage,
  type LinkMessage,
  type PoseEvent,
  type ServerJson,
} from './protocol';
import { byId, formatNumber, setText, showMessage } from './ui';
import type { View } from './view';

const UNCOLOURED = linearColour(150, 150, 150);
const PROTOCOL_MAJOR = 1;
const MAX_PENDING_IMAGES = 90; // frames or overlays waiting for their partner
const MAX_POSES = 100000;
const NO_POSE_WAIT_MS = 1000; // a complete frame whose pose never came is shown after this

export class WatchView implements View {
  private readonly frames = new Map<number, ImageBitmap>();
  private readonly overlays = new Map<number, ImageBitmap | null>();
  private readonly poses = new Map<number, PoseEvent>();
  private shownFrame = -1;
  private run = 0; // bumped by every Hello: images decoded for an older run are dropped
  private hello: HelloEvent | null = null;
  private meshMatches: boolean | null = null; // the tracker's mesh checksum against the mesh we show
  private coloured = new Uint8Array(0);
  private pendingColours: ColoursEvent[] = [];
  private readonly path: ScopePath | null;
  private readonly frustum: THREE.LineSegments | null;
  private noPoseTimer = 0;
  private framedOnPose = false; // the 3D view was pointed from this run's first pose
  private frameCount: number;

  constructor(
    private readonly info: InfoMessage,
    private readonly frame: FrameView,
    private readonly mesh: MeshView | null,
  ) {
    byId('watch-panel').hidden = false;
    this.frameCount = info.frames;
    hooks.shown = null;
    if (mesh) {
      this.path = new ScopePath(mesh.scene);
      this.frustum = makeFrustum(info);
      this.frustum.visible = false;
      mesh.scene.add(this.frustum);
      hooks.meshVertices = () => mesh.meshData?.vertices.slice() ?? new Float32Array(0);
      hooks.meshTriangles = () => mesh.meshData?.triangles.slice() ?? new Uint32Array(0);
      hooks.meshToClient = (x, y, z) => mesh.toClient(x, y, z);
    } else {
      this.path = null;
      this.frustum = null;
    }
    hooks.frameToClient = (u, v) => this.frame.frameToClient(u, v);
    setText('frame-caption', 'waiting for the tracker');
    this.showLink({ type: 'link', state: 'connecting', endpoint: info.endpoint });
  }

  // ------------------------------------------------------------ server messages

  json(message: ServerJson): void {
    switch (message.type) {
      case 'link':
        this.showLink(message);
        break;
      case 'frames':
        this.frameCount = message.count;
        break;
      case 'error':
        showMessage('error', message.message);
        break;
      default:
        break;
    }
  }

  binary(message: BinaryMessage): void {
    switch (message.kind) {
      case BinaryKind.Mesh:
        this.receiveMesh(message);
        break;
      case BinaryKind.Frame:
      case BinaryKind.Overlay:
        void this.receiveImage(message);
        break;
      case BinaryKind.Stream:
        this.receiveStream(message);
        break;
      default:
        break;
    }
  }

  private receiveMesh(message: BinaryMessage): void {
    if (!this.mesh) return;
    try {
      const data = decodeMesh(message.payload);
      this.mesh.setMesh(data, UNCOLOURED);
    } catch (error) {
      showMessage('error', `The mesh from the server cannot be read: ${(error as Error).message}.`);
      return;
    }
    this.mesh.frameMesh(isMat4(this.info.T_camera_model_init) ? this.info.T_camera_model_init : null);
    this.coloured = new Uint8Array(this.mesh.triangleCount);
    this.checkMesh();
    for (const delta of this.pendingColours) this.applyColours(delta);
    this.pendingColours = [];
    this.updateReady();
  }

  private receiveStream(message: BinaryMessage): void {
    let event;
    try {
      event = decodeStream(message.payload);
    } catch (error) {
      console.warn(`scopetrack-studio: a console-stream message could not be read (${(error as Error).message})`);
      return;
    }
    if (!event) return;
    switch (event.kind) {
      case 'hello':
        this.startRun(event);
        break;
      case 'pose':
        this.receivePose(event);
        break;
      case 'colours':
        if (!this.mesh) break; // no 3D view (no WebGL): nothing to colour
        if (this.mesh.meshData) this.applyColours(event);
        else this.pendingColours.push(event); // before the mesh: applied when it comes
        break;
      case 'health':
        this.showHealth(event);
        break;
    }
  }

  private async receiveImage(message: BinaryMessage): Promise<void> {
    const run = this.run;
    const isFrame = message.kind === BinaryKind.Frame;
    let image: ImageBitmap | null = null;
    if (isFrame || message.payload.byteLength > 0) {
      try {
        image = await decodeImage(message.payload, isFrame ? 'image/jpeg' : 'image/png');
      } catch {
        console.warn(`scopetrack-studio: the ${isFrame ? 'frame' : 'overlay'} of frame ${message.frame} is not a readable image`);
        return;
      }
    }
    if (run !== this.run || message.frame <= this.shownFrame) {
      image?.close();
      return;
    }
    const store: Map<number, ImageBitmap | null> = isFrame ? this.frames : this.overlays;
    store.get(message.frame)?.close();
    store.set(message.frame, image);
    prune(store, MAX_PENDING_IMAGES);
    this.showLatest();
  }

  // ------------------------------------------------------------ the run

  private startRun(hello: HelloEvent): void {
    this.run++;
    this.hello = hello;
    for (const image of [...this.frames.values(), ...this.overlays.values()]) image?.close();
    this.frames.clear();
    this.overlays.clear();
    this.poses.clear();
    this.shownFrame = -1;
    hooks.shown = null;
    hooks.watch.hello = true;
    hooks.watch.poses = 0;
    hooks.watch.coloured = 0;
    this.coloured.fill(0);
    this.mesh?.resetColours();
    this.path?.clear();
    hooks.watch.path = 0;
    this.framedOnPose = false;
    if (hello.protocolVersion !== PROTOCOL_MAJOR) {
      showMessage('error', `The tracker speaks console-stream protocol ${hello.protocolVersion}; this page reads version ${PROTOCOL_MAJOR}. Update scopetrack-studio or the tracker.`);
    } else {
      showMessage('ok', `The tracker's run started: ${hello.width}x${hello.height}${hello.fps > 0 ? ` at ${formatNumber(hello.fps, 0)} fps` : ''}.`);
    }
    this.checkMesh();
  }

  private checkMesh(): void {
    const data = this.mesh?.meshData;
    if (!this.hello || !data) return;
    this.meshMatches = data.triangles.length / 3 === this.hello.meshTriangles && meshChecksum(data) === this.hello.meshChecksum;
    if (!this.meshMatches) {
      showMessage('error', "The tracker tracks another mesh than this sequence's organ.ply (its checksum differs): the mesh is not coloured.", [
        'Start scopetrack-studio watch with the sequence folder the tracker replays.',
      ]);
    }
  }

  private receivePose(pose: PoseEvent): void {
    this.poses.set(pose.frame, pose);
    prune(this.poses, MAX_POSES);
    hooks.watch.poses++;
    if (pose.state !== 'lost' && this.path) {
      this.path.add(pose.t);
      hooks.watch.path = this.path.length;
      this.mesh?.requestRender();
    }
    if (pose.state !== 'lost' && this.mesh?.meshData && !this.framedOnPose && !this.mesh.userMoved) {
      // Look from the scope's side, far enough to see the scope too.
      this.framedOnPose = true;
      const c = this.mesh.centroid;
      const reach = Math.hypot(pose.t[0] - c.x, pose.t[1] - c.y, pose.t[2] - c.z);
      this.mesh.frameMesh(cameraModelFromPose(pose.q, pose.t), reach);
    }
    this.showLatest();
  }

  private applyColours(delta: ColoursEvent): void {
    if (!this.mesh || this.meshMatches === false) return;
    for (let i = 0; i < delta.triangles.length; i++) {
      const t = delta.triangles[i];
      if (!this.mesh.setTriangleColour(t, delta.rgb[3 * i], delta.rgb[3 * i + 1], delta.rgb[3 * i + 2])) continue;
      if (!this.coloured[t]) {
        this.coloured[t] = 1;
        hooks.watch.coloured++;
      }
    }
    this.mesh.commitColours();
  }

  /**
   * Shows the newest frame whose FRAME, OVERLAY and pose have all arrived
   * (frames after the one shown only), then forgets the older ones.
   */
  private showLatest(): void {
    let best = -1;
    let bestWithoutPose = -1;
    for (const index of this.frames.keys()) {
      if (index <= this.shownFrame || !this.overlays.has(index)) continue;
      if (this.poses.has(index)) best = Math.max(best, index);
      else bestWithoutPose = Math.max(bestWithoutPose, index);
    }
    window.clearTimeout(this.noPoseTimer);
    if (best >= 0) {
      this.show(best);
    } else if (bestWithoutPose >= 0) {
      // Its pose may still be on the way; if it never comes, show the frame anyway.
      this.noPoseTimer = window.setTimeout(() => this.show(bestWithoutPose), NO_POSE_WAIT_MS);
    }
  }

  private show(index: number): void {
    const image = this.frames.get(index);
    const overlay = this.overlays.get(index);
    if (!image || overlay === undefined) return;
    const pose = this.poses.get(index) ?? null;
    this.frame.showFrame(image);
    this.frame.showOverlay(overlay);
    this.shownFrame = index;
    for (const store of [this.frames, this.overlays] as Map<number, ImageBitmap | null>[]) {
      for (const [key, bitmap] of store) {
        if (key <= index) {
          bitmap?.close();
          store.delete(key);
        }
      }
    }
    const state = pose ? pose.state : 'unknown';
    hooks.shown = { frame: index, state };
    this.frame.setLost(state === 'lost');
    const stateBox = byId('state');
    stateBox.textContent = pose ? state : 'no pose received';
    stateBox.dataset.state = state;
    setText('frame-number', String(index));
    setText('frame-caption', `frame ${index}${this.frameCount > 0 ? ` of ${this.frameCount}` : ''}`);
    setText('latency', pose ? `${formatNumber(pose.latencyMs, 1)} ms` : '-');
    setText('source', pose && pose.state !== 'lost' ? (pose.source ?? 'features') : '-');
    setText('inliers', pose && pose.state !== 'lost' ? `${pose.inliers} (${formatNumber(100 * pose.quality, 0)} %)` : '-');
    if (this.frustum) {
      this.frustum.visible = !!pose && pose.state !== 'lost';
      if (pose) {
        this.frustum.position.set(...pose.t);
        this.frustum.quaternion.set(...pose.q).normalize();
      }
      this.mesh?.requestRender();
    }
    this.updateReady();
  }

  private updateReady(): void {
    hooks.ready = !!this.mesh?.meshData && this.shownFrame >= 0;
  }

  private showHealth(health: HealthEvent): void {
    hooks.watch.fps = health.fps;
    setText('fps', `${formatNumber(health.fps, 1)} fps`);
    const calibration = health.calibrationSuspect
      ? `calibration suspect: focal x${formatNumber(health.calibrationFocalScale, 2)}`
      : 'calibration ok';
    setText('health', `overruns ${health.overruns}, dropped messages ${health.droppedMessages}, ${calibration}`);
    byId('health').dataset.suspect = String(health.calibrationSuspect);
  }

  private showLink(link: LinkMessage): void {
    hooks.watch.link = link.state;
    const endpoint = link.endpoint ?? this.info.endpoint ?? 'the tracker';
    const box = byId('link');
    box.dataset.state = link.state;
    switch (link.state) {
      case 'connected':
        box.textContent = `connected to ${endpoint}`;
        break;
      case 'connecting':
        box.textContent = `waiting for the tracker at ${endpoint}`;
        if (!this.hello) {
          showMessage('info', `Waiting for the tracker to stream on ${endpoint}.`, [
            `Start it with: scopetrack --sequence SEQ --out RUN --stream ${endpoint}`,
          ]);
        }
        break;
      case 'disconnected':
        box.textContent = `disconnected from ${endpoint}${link.message ? `: ${link.message}` : ''}`;
        showMessage('info', `The tracker's stream ended${link.message ? `: ${link.message}` : ''}.`, [
          'The last frame stays on screen; a new run shows up here when it starts.',
        ]);
        break;
    }
  }
}

/** Drops the smallest keys of a map that holds more than `limit` entries, down to 90 % of it. */
function prune<V>(map: Map<number, V>, limit: number): void {
  if (map.size <= limit) return;
  const keys = [...map.keys()].sort((a, b) => a - b);
  for (const key of keys.slice(0, map.size - Math.floor(0.9 * limit))) {
    const value = map.get(key);
    if (value instanceof ImageBitmap) value.close();
    map.delete(key);
  }
}

/** The scope's path: a line through the camera centres of the poses. */
class ScopePath {
  private positions = new Float32Array(3 * 1024);
  private count = 0;
  private readonly geometry = new THREE.BufferGeometry();
  private readonly line: THREE.Line;

  constructor(scene: THREE.Scene) {
    this.geometry.setAttribute('position', new THREE.BufferAttribute(this.positions, 3));
    this.geometry.setDrawRange(0, 0);
    this.line = new THREE.Line(this.geometry, new THREE.LineBasicMaterial({ color: 0xffd400 }));
    this.line.frustumCulled = false;
    scene.add(this.line);
  }

  get length(): number {
    return this.count;
  }

  add(t: [number, number, number]): void {
    if (3 * (this.count + 1) > this.positions.length) {
      const grown = new Float32Array(this.positions.length * 2);
      grown.set(this.positions);
      this.positions = grown;
      this.geometry.setAttribute('position', new THREE.BufferAttribute(this.positions, 3));
    }
    this.positions.set(t, 3 * this.count);
    this.count++;
    this.geometry.getAttribute('position').needsUpdate = true;
    this.geometry.setDrawRange(0, this.count);
  }

  clear(): void {
    this.count = 0;
    this.geometry.setDrawRange(0, 0);
  }
}

/** The camera as a small frustum in its own frame (x right, y down, z forward), 20 mm deep. */
function makeFrustum(info: InfoMessage): THREE.LineSegments {
  const [fx, fy, cx, cy] = info.K;
  const depth = 20;
  const corner = (u: number, v: number) => new THREE.Vector3(((u - cx) / fx) * depth, ((v - cy) / fy) * depth, depth);
  const c = [corner(0, 0), corner(info.width, 0), corner(info.width, info.height), corner(0, info.height)];
  const o = new THREE.Vector3();
  const points = [o, c[0], o, c[1], o, c[2], o, c[3], c[0], c[1], c[1], c[2], c[2], c[3], c[3], c[0]];
  // A tick on the image's top edge tells up from down.
  const top = corner(info.width / 2, -0.15 * info.height);
  points.push(c[0].clone().lerp(c[1], 0.35), top, top, c[0].clone().lerp(c[1], 0.65));
  const geometry = new THREE.BufferGeometry().setFromPoints(points);
  return new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: 0x7dff8a }));
}
