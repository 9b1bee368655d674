// The register view: pairs of (frame pixel, mesh point) picked by hand, sent
// to the server, which answers with the registration and its overlay.

import type { Connection } from './connection';
import { decodeImage, FrameView } from './frame-view';
import { isMat4, projectPoint, type Camera, type Vec3 } from './geometry';
import { hooks } from './hooks';
import { linearColour, MeshView } from './mesh-view';
import {
  BinaryKind,
  decodeMesh,
  frameCommand,
  registerCommand,
  saveCommand,
  type BinaryMessage,
  type InfoMessage,
  type Pair,
  type RegistrationMessage,
  type ServerJson,
} from './protocol';
import { byId, formatNumber, setText, showMessage } from './ui';
import type { View } from './view';

const ORGAN_COLOUR = linearColour(214, 150, 138);
const MARKER_RADIUS_CSS_PX = 7;

/**
 * A pair selected in the table: frame clicks move its pixel, mesh clicks its
 * model point; the selection ends once both were moved (or on Esc, or a
 * click on its row).
 */
interface Selection {
  index: number;
  movePixel: boolean; // its pixel has not been moved yet
  movePoint: boolean; // its model point has not been moved yet
}

export class RegisterView implements View {
  private readonly camera: Camera;
  private pairs: Pair[] = [];
  private pendingPixel: { u: number; v: number } | null = null;
  private pendingPoint: Vec3 | null = null;
  private selection: Selection | null = null;
  private registration: RegistrationMessage | null = null;
  private shownFrame = -1;
  private hasMesh = false;
  private commandsSent = 0; // 0: a registration is the server's last one, from an earlier page
  private frameSerial = 0; // order of FRAME messages, so that a slow decode never overwrites a newer frame
  private overlaySerial = 0;
  private readonly tableBody: HTMLTableSectionElement;

  constructor(
    private readonly info: InfoMessage,
    private readonly connection: Connection,
    private readonly frame: FrameView,
    private readonly mesh: MeshView | null,
  ) {
    this.camera = { K: info.K, distortion: info.distortion };
    const table = byId<HTMLTableElement>('pairs');
    this.tableBody = table.tBodies[0] ?? table.createTBody();
    byId('register-panel').hidden = false;
    const frameInput = byId<HTMLInputElement>('frame-index');
    frameInput.value = String(Math.max(0, info.frame));
    if (info.frames > 0) frameInput.max = String(info.frames - 1);

    hooks.pairs = () => this.pairs.map((p) => ({ ...p }));
    hooks.frameToClient = (u, v) => this.frame.frameToClient(u, v);
    if (mesh) {
      hooks.meshToClient = (x, y, z) => mesh.toClient(x, y, z);
      hooks.meshVertices = () => mesh.meshData?.vertices.slice() ?? new Float32Array(0);
      hooks.meshTriangles = () => mesh.meshData?.triangles.slice() ?? new Uint32Array(0);
      mesh.onClick((x, y) => this.meshClicked(x, y));
      // Once a pose exists, the mesh can be seen from the registered scope.
      byId('view-result').addEventListener('click', () => {
        if (this.registration?.ok) mesh.frameMesh(this.registration.T_camera_model);
      });
    }
    frame.listen({
      markerAt: (u, v, radius) => this.markerAt(u, v, radius),
      click: (u, v) => this.frameClicked(u, v),
      drag: (index, u, v, done) => this.markerDragged(index, u, v, done),
    });
    new ResizeObserver(() => this.drawMarks()).observe(frame.frameCanvas);

    byId('load-frame').addEventListener('click', () => this.loadFrame());
    frameInput.addEventListener('keydown', (event) => {
      if (event.key === 'Enter') this.loadFrame();
    });
    byId('save').addEventListener('click', () => this.save());
    window.addEventListener('keydown', (event) => {
      if (event.target instanceof HTMLInputElement) return;
      if (event.key === 'Escape') this.cancelPicks();
      if (event.key === 'Delete' && this.selection) this.removePair(this.selection.index);
    });

    this.renderTable();
    this.renderResult();
    if (mesh) {
      showMessage(
        'info',
        'Click a point on the frame, then the same point on the mesh: at least 4 pairs, spread over the organ.',
        info.check ? [`The sequence's current pose: ${info.check}`] : [],
      );
    }
  }

  // ------------------------------------------------------------ server messages

  json(message: ServerJson): void {
    switch (message.type) {
      case 'registration':
        this.registration = message;
        hooks.lastRegistration = message;
        hooks.registrations++;
        this.showRegistration();
        break;
      case 'saved':
        showMessage('ok', `Saved the registration into ${message.yaml}.`, [
          `The previous file is kept as ${message.backup}.`,
          `The pairs are in ${message.pairs}.`,
        ]);
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
        void this.receiveFrame(message);
        break;
      case BinaryKind.Overlay:
        void this.receiveOverlay(message);
        break;
      default:
        break; // the console stream is for the watch view
    }
  }

  private receiveMesh(message: BinaryMessage): void {
    if (!this.mesh) return;
    try {
      this.mesh.setMesh(decodeMesh(message.payload), ORGAN_COLOUR);
    } catch (error) {
      showMessage('error', `The mesh from the server cannot be read: ${(error as Error).message}.`);
      return;
    }
    this.mesh.frameMesh(isMat4(this.info.T_camera_model_init) ? this.info.T_camera_model_init : null);
    this.hasMesh = true;
    this.drawMeshMarkers();
    this.updateReady();
  }

  private async receiveFrame(message: BinaryMessage): Promise<void> {
    const serial = ++this.frameSerial;
    let image: ImageBitmap;
    try {
      image = await decodeImage(message.payload, 'image/jpeg');
    } catch {
      showMessage('error', `Frame ${message.frame} from the server is not a readable JPEG.`);
      return;
    }
    if (serial !== this.frameSerial) {
      image.close();
      return;
    }
    const changed = this.shownFrame >= 0 && message.frame !== this.shownFrame;
    this.frame.showFrame(image);
    image.close();
    this.shownFrame = message.frame;
    byId<HTMLInputElement>('frame-index').value = String(message.frame);
    setText('frame-caption', `frame ${message.frame}${this.info.frames > 0 ? ` of ${this.info.frames}` : ''}`);
    if (changed && this.pairs.length) {
      showMessage('info', `Frame ${message.frame} shown. The pairs' pixels were picked on another frame: select a pair and click the frame to move its pixel.`);
    }
    this.drawMarks();
    this.updateReady();
  }

  private async receiveOverlay(message: BinaryMessage): Promise<void> {
    const serial = ++this.overlaySerial;
    let image: ImageBitmap | null = null;
    if (message.payload.byteLength > 0) {
      try {
        image = await decodeImage(message.payload, 'image/png');
      } catch {
        showMessage('error', `The overlay of frame ${message.frame} from the server is not a readable PNG.`);
        return;
      }
    }
    if (serial !== this.overlaySerial) {
      image?.close();
      return;
    }
    this.frame.showOverlay(image);
    image?.close();
  }

  private updateReady(): void {
    hooks.ready = this.hasMesh && this.shownFrame >= 0;
  }

  private showRegistration(): void {
    const r = this.registration;
    if (!r) return;
    byId('view-result').hidden = !r.ok;
    if (r.ok && this.commandsSent === 0) {
      showMessage('info', `The server's last registration (${r.pairs} pairs, from an earlier page): ${r.inliers} inliers, RMS ${formatNumber(r.rms_px, 2)} px.`, [
        'Its pairs are not on this page: add pairs here to register again.',
      ]);
    } else if (r.ok) {
      const outliers = r.inlier
        .map((inlier, i) => (inlier ? 0 : i + 1))
        .filter((n) => n > 0);
      const detail = [...(r.warnings ?? [])];
      if (outliers.length) {
        detail.unshift(`Pair${outliers.length > 1 ? 's' : ''} ${outliers.join(', ')} disagree${outliers.length > 1 ? '' : 's'} with the pose (outlier${outliers.length > 1 ? 's' : ''}): check or remove ${outliers.length > 1 ? 'them' : 'it'}.`);
      }
      showMessage('ok', `Registered from ${r.pairs} pairs: ${r.inliers} inliers, RMS ${formatNumber(r.rms_px, 2)} px.`, detail);
    } else {
      // Fewer than 4 pairs is the normal way to start, not a mistake.
      showMessage(this.pairs.length < 4 ? 'info' : 'error', r.message);
    }
    this.renderTable();
    this.renderResult();
    this.drawMarks();
  }

  // ------------------------------------------------------------ picking

  private frameClicked(u: number, v: number): void {
    if (!this.insideFrame(u, v)) return;
    const selection = this.selection;
    if (selection) {
      this.pairs[selection.index] = { ...this.pairs[selection.index], u, v };
      selection.movePixel = false;
      this.finishMove(selection, 'pixel');
      return;
    }
    this.pendingPixel = { u, v };
    if (this.pendingPoint) {
      this.addPair();
    } else {
      showMessage('info', `Pixel (${formatNumber(u, 1)}, ${formatNumber(v, 1)}) chosen: now click the same point on the mesh.`);
      this.drawMarks();
    }
  }

  private meshClicked(clientX: number, clientY: number): void {
    if (!this.mesh) return;
    const point = this.mesh.pick(clientX, clientY);
    if (!point) {
      showMessage('error', "That click is not on the mesh: click on the organ's surface.");
      return;
    }
    const selection = this.selection;
    if (selection) {
      const [x, y, z] = point;
      this.pairs[selection.index] = { ...this.pairs[selection.index], x, y, z };
      selection.movePoint = false;
      this.finishMove(selection, 'model point');
      return;
    }
    this.pendingPoint = point;
    if (this.pendingPixel) {
      this.addPair();
    } else {
      showMessage('info', 'Model point chosen: now click the same point on the frame.');
      this.drawMeshMarkers();
    }
  }

  private addPair(): void {
    if (!this.pendingPixel || !this.pendingPoint) return;
    const [x, y, z] = this.pendingPoint;
    this.pairs.push({ ...this.pendingPixel, x, y, z });
    this.pendingPixel = null;
    this.pendingPoint = null;
    showMessage('info', `Pair ${this.pairs.length} added: registering...`);
    this.pairsChanged();
  }

  private finishMove(selection: Selection, what: string): void {
    const n = selection.index + 1;
    if (!selection.movePixel && !selection.movePoint) this.selection = null;
    showMessage('info', `Moved the ${what} of pair ${n}: registering...`);
    this.pairsChanged();
  }

  private markerAt(u: number, v: number, radius: number): number | null {
    let best: number | null = null;
    let bestDistance = radius;
    this.pairs.forEach((p, i) => {
      const d = Math.hypot(p.u - u, p.v - v);
      if (d <= bestDistance) {
        best = i;
        bestDistance = d;
      }
    });
    return best;
  }

  private markerDragged(index: number, u: number, v: number, done: boolean): void {
    const pair = this.pairs[index];
    if (!pair) return;
    const clamped = {
      u: Math.min(Math.max(u, -0.5), this.frame.width - 0.5),
      v: Math.min(Math.max(v, -0.5), this.frame.height - 0.5),
    };
    this.pairs[index] = { ...pair, ...clamped };
    if (done) {
      showMessage('info', `Moved the pixel of pair ${index + 1}: registering...`);
      this.pairsChanged();
    } else {
      this.drawMarks();
    }
  }

  private insideFrame(u: number, v: number): boolean {
    return u >= -0.5 && v >= -0.5 && u <= this.frame.width - 0.5 && v <= this.frame.height - 0.5;
  }

  private select(index: number): void {
    if (this.selection?.index === index) {
      this.selection = null;
      showMessage('info', `Pair ${index + 1} deselected.`);
    } else {
      this.selection = { index, movePixel: true, movePoint: true };
      this.pendingPixel = null;
      this.pendingPoint = null;
      showMessage('info', `Pair ${index + 1} selected: click the frame to move its pixel, the mesh to move its model point (Esc to stop, Delete to remove it).`);
    }
    this.renderTable();
    this.drawMarks();
    this.drawMeshMarkers();
  }

  private cancelPicks(): void {
    this.selection = null;
    this.pendingPixel = null;
    this.pendingPoint = null;
    this.renderTable();
    this.drawMarks();
    this.drawMeshMarkers();
  }

  private removePair(index: number): void {
    this.pairs.splice(index, 1);
    this.selection = null;
    showMessage('info', `Pair ${index + 1} removed: registering...`);
    this.pairsChanged();
  }

  private pairsChanged(): void {
    this.renderTable();
    this.drawMarks();
    this.drawMeshMarkers();
    this.send(registerCommand(this.pairs));
  }

  private send(command: string): boolean {
    if (!this.connection.send(command)) {
      this.connectionLost();
      return false;
    }
    this.commandsSent++;
    return true;
  }

  private loadFrame(): void {
    const value = Number(byId<HTMLInputElement>('frame-index').value);
    const last = this.info.frames > 0 ? this.info.frames - 1 : Infinity;
    if (!Number.isInteger(value) || value < 0 || value > last) {
      showMessage('error', `There is no frame ${byId<HTMLInputElement>('frame-index').value}: choose a frame from 0 to ${last}.`);
      return;
    }
    if (this.send(frameCommand(value))) showMessage('info', `Loading frame ${value}...`);
  }

  private save(): void {
    if (this.send(saveCommand(this.pairs))) showMessage('info', 'Saving...');
  }

  private connectionLost(): void {
    showMessage('error', 'Not connected to scopetrack-studio: restart it, then reload this page.');
  }

  // ------------------------------------------------------------ drawing

  private currentResult(): { inlier: boolean[]; residual: number[] } | null {
    const r = this.registration;
    if (!r || !r.ok || r.residual_px.length !== this.pairs.length) return null;
    return { inlier: r.inlier, residual: r.residual_px };
  }

  private renderTable(): void {
    const result = this.currentResult();
    const rows = this.pairs.map((p, i) => {
      const row = document.createElement('tr');
      row.className = 'pair';
      row.dataset.index = String(i);
      if (this.selection?.index === i) row.classList.add('selected');
      const cell = (text: string, className = '') => {
        const td = document.createElement('td');
        td.textContent = text;
        if (className) td.className = className;
        row.append(td);
        return td;
      };
      cell(String(i + 1), 'number');
      cell(`${formatNumber(p.u, 1)}, ${formatNumber(p.v, 1)}`, 'pixel');
      cell(`${formatNumber(p.x, 1)}, ${formatNumber(p.y, 1)}, ${formatNumber(p.z, 1)}`, 'point');
      const residual = cell(result ? formatNumber(result.residual[i], 1) : '-', 'residual');
      if (result && !result.inlier[i]) {
        row.classList.add('outlier');
        residual.title = 'outlier: this pair disagrees with the pose';
        residual.textContent += ' outlier';
      }
      const remove = document.createElement('button');
      remove.className = 'remove';
      remove.type = 'button';
      remove.textContent = 'remove';
      remove.title = `Remove pair ${i + 1}`;
      remove.addEventListener('click', (event) => {
        event.stopPropagation();
        this.removePair(i);
      });
      const td = document.createElement('td');
      td.append(remove);
      row.append(td);
      row.addEventListener('click', () => this.select(i));
      return row;
    });
    this.tableBody.replaceChildren(...rows);
    byId('pairs-empty').hidden = this.pairs.length > 0;
  }

  private renderResult(): void {
    const r = this.registration;
    let text: string;
    if (!r) {
      text = 'No registration yet: add at least 4 pairs.';
    } else if (r.ok) {
      text =
        `${r.inliers} of ${r.pairs} pairs agree, RMS ${formatNumber(r.rms_px, 2)} px; ` +
        `change from the sequence's pose: ${formatNumber(r.change_deg, 2)} deg, ${formatNumber(r.change_mm, 1)} mm.`;
    } else {
      text = `No pose: ${r.message}`;
    }
    setText('result', text);
    byId('result').dataset.ok = String(!!r?.ok);
  }

  /** Pair markers, pending pixel, and each pick's projection at the registered pose. */
  private drawMarks(): void {
    const g = this.frame.marksContext;
    const { width, height } = this.frame;
    g.clearRect(0, 0, width, height);
    const s = this.frame.scale(); // frame pixels per CSS pixel: markers keep their size on screen
    const r = MARKER_RADIUS_CSS_PX * s;
    const result = this.currentResult();
    const registration = this.registration;
    const T = registration?.ok && isMat4(registration.T_camera_model) ? registration.T_camera_model : null;
    g.lineWidth = 1.5 * s;
    g.font = `bold ${13 * s}px sans-serif`;
    g.textBaseline = 'middle';
    this.pairs.forEach((p, i) => {
      const x = p.u + 0.5;
      const y = p.v + 0.5;
      const outlier = result ? !result.inlier[i] : false;
      const colour = this.selection?.index === i ? '#ffd400' : outlier ? '#ff4d4d' : '#35c3ff';
      if (T && result) {
        const q = projectPoint(T, this.camera, [p.x, p.y, p.z]);
        if (q) {
          g.strokeStyle = outlier ? '#ff4d4d' : '#7dff8a';
          g.beginPath();
          g.moveTo(x, y);
          g.lineTo(q.u + 0.5, q.v + 0.5);
          g.stroke();
          g.beginPath();
          g.moveTo(q.u + 0.5 - r / 2, q.v + 0.5 - r / 2);
          g.lineTo(q.u + 0.5 + r / 2, q.v + 0.5 + r / 2);
          g.moveTo(q.u + 0.5 + r / 2, q.v + 0.5 - r / 2);
          g.lineTo(q.u + 0.5 - r / 2, q.v + 0.5 + r / 2);
          g.stroke();
        }
      }
      g.strokeStyle = 'rgba(0, 0, 0, 0.7)';
      g.lineWidth = 3.5 * s;
      g.beginPath();
      g.arc(x, y, r, 0, 2 * Math.PI);
      g.stroke();
      g.strokeStyle = colour;
      g.lineWidth = 1.5 * s;
      g.stroke();
      g.beginPath();
      g.arc(x, y, 1.2 * s, 0, 2 * Math.PI);
      g.fillStyle = colour;
      g.fill();
      const label = String(i + 1);
      g.lineWidth = 3 * s;
      g.strokeStyle = 'rgba(0, 0, 0, 0.8)';
      g.strokeText(label, x + r + 2 * s, y - r);
      g.fillText(label, x + r + 2 * s, y - r);
    });
    if (this.pendingPixel) {
      const x = this.pendingPixel.u + 0.5;
      const y = this.pendingPixel.v + 0.5;
      g.strokeStyle = '#ffffff';
      g.lineWidth = 1.5 * s;
      g.setLineDash([3 * s, 3 * s]);
      g.beginPath();
      g.arc(x, y, r, 0, 2 * Math.PI);
      g.moveTo(x - 2 * r, y);
      g.lineTo(x + 2 * r, y);
      g.moveTo(x, y - 2 * r);
      g.lineTo(x, y + 2 * r);
      g.stroke();
      g.setLineDash([]);
    }
  }

  private drawMeshMarkers(): void {
    if (!this.mesh) return;
    const markers = this.pairs.map((p, i) => ({
      position: [p.x, p.y, p.z] as Vec3,
      label: String(i + 1),
      highlight: this.selection?.index === i,
    }));
    if (this.pendingPoint) markers.push({ position: this.pendingPoint, label: '?', highlight: true });
    this.mesh.setMarkers(markers);
  }
}
