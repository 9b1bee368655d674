// The frame: the video frame (#frame-canvas), the server's overlay on top of
// it (#overlay-canvas) and the pair markers (#marks-canvas), three canvases of
// the video's pixel size, CSS-scaled together.
//
// Frame pixel coordinates follow OpenCV: (0, 0) is the centre of the top-left
// pixel, which covers the canvas square [0, 1) x [0, 1): canvas = frame + 0.5.

import { byId } from './ui';

export interface FramePointerHandlers {
  /** The index of a marker near (u, v) that can be dragged, or null. `radius` in frame pixels. */
  markerAt(u: number, v: number, radius: number): number | null;
  click(u: number, v: number): void;
  drag(marker: number, u: number, v: number, done: boolean): void;
}

const CLICK_SLOP_PX = 4; // CSS pixels a click may move and stay a click
const MARKER_GRAB_PX = 10; // CSS pixels around a marker that start a drag

export class FrameView {
  readonly wrap = byId('frame-wrap');
  readonly frameCanvas = byId<HTMLCanvasElement>('frame-canvas');
  readonly overlayCanvas = byId<HTMLCanvasElement>('overlay-canvas');
  readonly marksCanvas = byId<HTMLCanvasElement>('marks-canvas');
  private readonly frameContext: CanvasRenderingContext2D;
  private readonly overlayContext: CanvasRenderingContext2D;
  readonly marksContext: CanvasRenderingContext2D;
  width = 0;
  height = 0;

  constructor() {
    this.frameContext = this.context(this.frameCanvas, false);
    this.overlayContext = this.context(this.overlayCanvas, true);
    this.marksContext = this.context(this.marksCanvas, false);
  }

  private context(canvas: HTMLCanvasElement, willReadFrequently: boolean): CanvasRenderingContext2D {
    const context = canvas.getContext('2d', { willReadFrequently });
    if (!context) throw new Error('this browser cannot draw on a canvas');
    return context;
  }

  /** Sizes the three canvases to the video's pixels. */
  setSize(width: number, height: number): void {
    this.width = width;
    this.height = height;
    for (const canvas of [this.frameCanvas, this.overlayCanvas, this.marksCanvas]) {
      canvas.width = width;
      canvas.height = height;
    }
    this.wrap.style.setProperty('--aspect', String(width / height));
    this.frameContext.fillStyle = '#111';
    this.frameContext.fillRect(0, 0, width, height);
  }

  showFrame(image: ImageBitmap): void {
    this.frameContext.drawImage(image, 0, 0, this.width, this.height);
  }

  /** Draws the overlay; null clears it (no pose for the frame). */
  showOverlay(image: ImageBitmap | null): void {
    this.overlayContext.clearRect(0, 0, this.width, this.height);
    if (image) this.overlayContext.drawImage(image, 0, 0, this.width, this.height);
  }

  /** The overlay's alpha channel, one byte per pixel, row by row. */
  overlayAlpha(): Uint8Array {
    if (!this.width || !this.height) return new Uint8Array(0);
    const rgba = this.overlayContext.getImageData(0, 0, this.width, this.height).data;
    const alpha = new Uint8Array(this.width * this.height);
    for (let i = 0; i < alpha.length; i++) alpha[i] = rgba[4 * i + 3];
    return alpha;
  }

  /** Frame pixels per CSS pixel of the displayed frame. */
  scale(): number {
    const rect = this.frameCanvas.getBoundingClientRect();
    return rect.width > 0 ? this.width / rect.width : 1;
  }

  clientToFrame(clientX: number, clientY: number): { u: number; v: number } {
    const rect = this.frameCanvas.getBoundingClientRect();
    return {
      u: ((clientX - rect.left) * this.width) / rect.width - 0.5,
      v: ((clientY - rect.top) * this.height) / rect.height - 0.5,
    };
  }

  frameToClient(u: number, v: number): { x: number; y: number } | null {
    if (!this.width) return null;
    const rect = this.frameCanvas.getBoundingClientRect();
    return {
      x: rect.left + ((u + 0.5) * rect.width) / this.width,
      y: rect.top + ((v + 0.5) * rect.height) / this.height,
    };
  }

  setLost(lost: boolean): void {
    this.wrap.classList.toggle('lost', lost);
  }

  /** Clicks and marker drags on the frame (register view). */
  listen(handlers: FramePointerHandlers): void {
    let down: { x: number; y: number; id: number; marker: number | null; dragging: boolean } | null = null;
    const canvas = this.frameCanvas;
    canvas.addEventListener('pointerdown', (event) => {
      if (event.button !== 0) return;
      const p = this.clientToFrame(event.clientX, event.clientY);
      const marker = handlers.markerAt(p.u, p.v, MARKER_GRAB_PX * this.scale());
      down = { x: event.clientX, y: event.clientY, id: event.pointerId, marker, dragging: false };
      canvas.setPointerCapture(event.pointerId);
    });
    canvas.addEventListener('pointermove', (event) => {
      if (!down || event.pointerId !== down.id || down.marker === null) return;
      if (!down.dragging && Math.hypot(event.clientX - down.x, event.clientY - down.y) <= CLICK_SLOP_PX) return;
      down.dragging = true;
      canvas.classList.add('dragging');
      const p = this.clientToFrame(event.clientX, event.clientY);
      handlers.drag(down.marker, p.u, p.v, false);
    });
    const finish = (event: PointerEvent, cancelled: boolean) => {
      if (!down || event.pointerId !== down.id) return;
      const gesture = down;
      down = null;
      canvas.classList.remove('dragging');
      const p = this.clientToFrame(event.clientX, event.clientY);
      if (gesture.dragging && gesture.marker !== null) {
        handlers.drag(gesture.marker, p.u, p.v, true);
      } else if (!cancelled && Math.hypot(event.clientX - gesture.x, event.clientY - gesture.y) <= CLICK_SLOP_PX) {
        handlers.click(p.u, p.v);
      }
    };
    canvas.addEventListener('pointerup', (event) => finish(event, false));
    canvas.addEventListener('pointercancel', (event) => finish(event, true));
  }
}

/** Decodes a JPEG or PNG payload into a bitmap (its pixels as sent: no colour-space conversion). */
export function decodeImage(payload: Uint8Array, type: 'image/jpeg' | 'image/png'): Promise<ImageBitmap> {
  return createImageBitmap(new Blob([payload as BlobPart], { type }), {
    colorSpaceConversion: 'none',
    premultiplyAlpha: 'none',
  });
}
