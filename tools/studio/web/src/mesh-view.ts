// The 3D view (#mesh-view): the organ mesh in three.js with orbit, zoom and
// pan, ray-cast picking, numbered pair markers, and per-triangle colours.
// Model units are millimetres.

import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import type { Mat4, MeshData } from './protocol';
import { cameraCentre, rotationRow, transformPoint, type Vec3 } from './geometry';

/** Thrown when the browser cannot give a WebGL context. */
export class WebGLUnavailable extends Error {}

const CLICK_SLOP_PX = 4; // a pointer that moves more between down and up is an orbit drag, not a click
const FIELD_OF_VIEW_DEG = 40;

export interface MeshMarker {
  position: Vec3;
  label: string;
  highlight: boolean;
}

/** sRGB byte -> linear float, as three.js works in linear sRGB. */
const SRGB_TO_LINEAR = Float32Array.from({ length: 256 }, (_, i) => {
  const c = i / 255;
  return c <= 0.04045 ? c / 12.92 : Math.pow((c + 0.055) / 1.055, 2.4);
});

/** Linear RGB of an 8-bit sRGB colour. */
export function linearColour(r: number, g: number, b: number): [number, number, number] {
  return [SRGB_TO_LINEAR[r], SRGB_TO_LINEAR[g], SRGB_TO_LINEAR[b]];
}

export class MeshView {
  readonly scene = new THREE.Scene();
  readonly camera = new THREE.PerspectiveCamera(FIELD_OF_VIEW_DEG, 1, 0.1, 10000);
  private readonly renderer: THREE.WebGLRenderer;
  private readonly controls: OrbitControls;
  private readonly raycaster = new THREE.Raycaster();
  private readonly markers = new THREE.Group();
  private readonly labelTextures = new Map<string, THREE.CanvasTexture>();
  private mesh: THREE.Mesh<THREE.BufferGeometry, THREE.MeshLambertMaterial> | null = null;
  private data: MeshData | null = null;
  private baseColour: [number, number, number] = [0.6, 0.6, 0.6];
  private renderQueued = false;
  /** The user has orbited, zoomed or panned: the page no longer moves the view by itself. */
  userMoved = false;
  /** Radius of the mesh's bounding sphere, mm (1 until a mesh is set). */
  radius = 1;
  centroid = new THREE.Vector3();

  constructor(private readonly container: HTMLElement) {
    let renderer: THREE.WebGLRenderer;
    try {
      renderer = new THREE.WebGLRenderer({ antialias: true });
    } catch (error) {
      throw new WebGLUnavailable(error instanceof Error ? error.message : String(error));
    }
    this.renderer = renderer;
    renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    renderer.setClearColor(0x1d2126);
    container.append(renderer.domElement);
    renderer.domElement.addEventListener('webglcontextlost', (event) => {
      event.preventDefault();
      container.dataset.webgl = 'lost';
    });

    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x303030, 1.2));
    const headlight = new THREE.DirectionalLight(0xffffff, 1.8);
    headlight.position.set(0.2, 0.4, 0);
    headlight.target.position.set(0, 0, -1);
    this.camera.add(headlight, headlight.target);
    this.scene.add(this.camera, this.markers);

    this.controls = new OrbitControls(this.camera, renderer.domElement);
    this.controls.addEventListener('change', () => this.requestRender());
    this.controls.addEventListener('start', () => {
      this.userMoved = true;
    });

    new ResizeObserver(() => this.resize()).observe(container);
    this.resize();
  }

  private resize(): void {
    const width = Math.max(1, this.container.clientWidth);
    const height = Math.max(1, this.container.clientHeight);
    this.renderer.setSize(width, height);
    this.camera.aspect = width / height;
    this.camera.updateProjectionMatrix();
    this.requestRender();
  }

  requestRender(): void {
    if (this.renderQueued) return;
    this.renderQueued = true;
    requestAnimationFrame(() => {
      this.renderQueued = false;
      this.renderer.render(this.scene, this.camera);
    });
  }

  /** Shows the mesh, every triangle in `colour` (linear RGB 0..1) until coloured. */
  setMesh(data: MeshData, colour: [number, number, number]): void {
    this.data = data;
    this.baseColour = colour;
    const nt = data.triangles.length / 3;
    const positions = new Float32Array(9 * nt);
    for (let i = 0; i < 3 * nt; i++) {
      const v = data.triangles[i];
      positions[3 * i] = data.vertices[3 * v];
      positions[3 * i + 1] = data.vertices[3 * v + 1];
      positions[3 * i + 2] = data.vertices[3 * v + 2];
    }
    const colours = new Float32Array(9 * nt);
    for (let i = 0; i < 3 * nt; i++) colours.set(colour, 3 * i);
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
    geometry.setAttribute('color', new THREE.BufferAttribute(colours, 3));
    geometry.computeVertexNormals(); // non-indexed: one flat normal per triangle
    geometry.computeBoundingSphere();
    if (this.mesh) {
      this.scene.remove(this.mesh);
      this.mesh.geometry.dispose();
      this.mesh.material.dispose();
    }
    const material = new THREE.MeshLambertMaterial({ vertexColors: true, side: THREE.DoubleSide });
    this.mesh = new THREE.Mesh(geometry, material);
    this.scene.add(this.mesh);

    this.centroid.set(0, 0, 0);
    const nv = data.vertices.length / 3;
    for (let i = 0; i < nv; i++) {
      this.centroid.x += data.vertices[3 * i] / nv;
      this.centroid.y += data.vertices[3 * i + 1] / nv;
      this.centroid.z += data.vertices[3 * i + 2] / nv;
    }
    this.radius = 1;
    for (let i = 0; i < nv; i++) {
      const d = Math.hypot(
        data.vertices[3 * i] - this.centroid.x,
        data.vertices[3 * i + 1] - this.centroid.y,
        data.vertices[3 * i + 2] - this.centroid.z,
      );
      this.radius = Math.max(this.radius, d);
    }
    this.requestRender();
  }

  get meshData(): MeshData | null {
    return this.data;
  }

  get triangleCount(): number {
    return this.data ? this.data.triangles.length / 3 : 0;
  }

  /**
   * Points the view at the mesh from the side of the camera of T_camera_model
   * (when the mesh's centroid is in front of that camera), else from +z,
   * far enough back to frame the whole mesh (and a sphere of `fitRadius`
   * around its centroid, if larger).
   */
  frameMesh(T_camera_model: Mat4 | null, fitRadius = 0): void {
    const c = this.centroid;
    let direction = new THREE.Vector3(0, 0, 1);
    let up = new THREE.Vector3(0, 1, 0);
    let distance = 0;
    if (T_camera_model && transformPoint(T_camera_model, [c.x, c.y, c.z])[2] > 0) {
      const centre = new THREE.Vector3(...cameraCentre(T_camera_model));
      distance = centre.distanceTo(c);
      if (distance > 1e-6) {
        direction = centre.sub(c).normalize();
        up = new THREE.Vector3(...rotationRow(T_camera_model, 1)).negate(); // image up = -y of the camera
      }
    }
    this.place(direction, up, distance, fitRadius);
  }

  /** Looks at the whole mesh from along a model axis (e.g. [0, 0, -1]: from -z). */
  viewAlong(axis: Vec3): void {
    const direction = new THREE.Vector3(...axis).normalize();
    // Up: the model's +y unless the view is along y, then -z.
    const up = Math.abs(direction.y) > 0.9 ? new THREE.Vector3(0, 0, -Math.sign(direction.y)) : new THREE.Vector3(0, 1, 0);
    this.place(direction, up, 0, 0);
  }

  private place(direction: THREE.Vector3, up: THREE.Vector3, minDistance: number, fitRadius: number): void {
    const c = this.centroid;
    let distance = minDistance;
    const halfFov = THREE.MathUtils.degToRad(FIELD_OF_VIEW_DEG / 2);
    const halfFovX = Math.atan(Math.tan(halfFov) * this.camera.aspect);
    const fit = (Math.max(this.radius, fitRadius) * 1.08) / Math.sin(Math.min(halfFov, halfFovX));
    distance = Math.max(distance, fit);
    this.camera.position.copy(c).addScaledVector(direction, distance);
    this.camera.up.copy(up);
    this.camera.near = Math.max(0.01, distance / 200);
    this.camera.far = distance * 20;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(c);
    this.controls.update();
    this.requestRender();
  }

  /** Colours triangle `index` from 8-bit sRGB; call commitColours() after a batch. */
  setTriangleColour(index: number, r: number, g: number, b: number): boolean {
    if (!this.mesh || index >= this.triangleCount) return false;
    const colours = this.mesh.geometry.getAttribute('color') as THREE.BufferAttribute;
    const array = colours.array as Float32Array;
    const lr = SRGB_TO_LINEAR[r];
    const lg = SRGB_TO_LINEAR[g];
    const lb = SRGB_TO_LINEAR[b];
    for (let k = 0; k < 3; k++) {
      array[9 * index + 3 * k] = lr;
      array[9 * index + 3 * k + 1] = lg;
      array[9 * index + 3 * k + 2] = lb;
    }
    return true;
  }

  resetColours(): void {
    if (!this.mesh) return;
    const colours = this.mesh.geometry.getAttribute('color') as THREE.BufferAttribute;
    const array = colours.array as Float32Array;
    for (let i = 0; i < array.length; i += 3) array.set(this.baseColour, i);
    this.commitColours();
  }

  commitColours(): void {
    if (!this.mesh) return;
    this.mesh.geometry.getAttribute('color').needsUpdate = true;
    this.requestRender();
  }

  /** Calls `handler` for a click (not an orbit drag) on the view. */
  onClick(handler: (clientX: number, clientY: number) => void): void {
    const canvas = this.renderer.domElement;
    let down: { x: number; y: number; id: number } | null = null;
    canvas.addEventListener('pointerdown', (event) => {
      down = event.button === 0 ? { x: event.clientX, y: event.clientY, id: event.pointerId } : null;
    });
    canvas.addEventListener('pointerup', (event) => {
      if (!down || down.id !== event.pointerId) return;
      const moved = Math.hypot(event.clientX - down.x, event.clientY - down.y);
      down = null;
      if (moved <= CLICK_SLOP_PX) handler(event.clientX, event.clientY);
    });
  }

  /** The model point under a client position, or null when the ray misses the mesh. */
  pick(clientX: number, clientY: number): Vec3 | null {
    if (!this.mesh) return null;
    const rect = this.renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(
      ((clientX - rect.left) / rect.width) * 2 - 1,
      -((clientY - rect.top) / rect.height) * 2 + 1,
    );
    this.camera.updateMatrixWorld();
    this.raycaster.setFromCamera(ndc, this.camera);
    const hit = this.raycaster.intersectObject(this.mesh, false)[0];
    return hit ? [hit.point.x, hit.point.y, hit.point.z] : null;
  }

  /** Client coordinates of a model point, or null when it is behind the view's camera. */
  toClient(x: number, y: number, z: number): { x: number; y: number } | null {
    this.camera.updateMatrixWorld();
    const p = new THREE.Vector3(x, y, z);
    if (p.clone().applyMatrix4(this.camera.matrixWorldInverse).z >= 0) return null;
    p.project(this.camera);
    const rect = this.renderer.domElement.getBoundingClientRect();
    return {
      x: rect.left + ((p.x + 1) / 2) * rect.width,
      y: rect.top + ((1 - p.y) / 2) * rect.height,
    };
  }

  /** Replaces the numbered markers (a small sphere and a label each). */
  setMarkers(markers: MeshMarker[]): void {
    for (const child of [...this.markers.children]) {
      this.markers.remove(child);
      if (child instanceof THREE.Mesh) {
        child.geometry.dispose();
        (child.material as THREE.Material).dispose();
      } else if (child instanceof THREE.Sprite) {
        child.material.dispose();
      }
    }
    const size = this.radius * 0.016;
    for (const marker of markers) {
      const colour = marker.highlight ? 0xffd400 : 0x35c3ff;
      const sphere = new THREE.Mesh(
        new THREE.SphereGeometry(size, 16, 12),
        new THREE.MeshBasicMaterial({ color: colour }),
      );
      sphere.position.set(...marker.position);
      const label = new THREE.Sprite(
        new THREE.SpriteMaterial({ map: this.labelTexture(marker.label, marker.highlight), depthTest: false }),
      );
      label.center.set(-0.15, -0.15); // beside the sphere, up and to the right
      label.scale.set(size * 4, size * 4, 1);
      label.position.copy(sphere.position);
      label.renderOrder = 1;
      this.markers.add(sphere, label);
    }
    this.requestRender();
  }

  private labelTexture(text: string, highlight: boolean): THREE.CanvasTexture {
    const key = `${text}/${highlight}`;
    let texture = this.labelTextures.get(key);
    if (!texture) {
      const canvas = document.createElement('canvas');
      canvas.width = canvas.height = 64;
      const context = canvas.getContext('2d')!;
      context.fillStyle = 'rgba(0, 0, 0, 0.65)';
      context.beginPath();
      context.arc(32, 32, 30, 0, 2 * Math.PI);
      context.fill();
      context.fillStyle = highlight ? '#ffd400' : '#ffffff';
      context.font = 'bold 34px sans-serif';
      context.textAlign = 'center';
      context.textBaseline = 'middle';
      context.fillText(text, 32, 34);
      texture = new THREE.CanvasTexture(canvas);
      texture.colorSpace = THREE.SRGBColorSpace;
      this.labelTextures.set(key, texture);
    }
    return texture;
  }
}
