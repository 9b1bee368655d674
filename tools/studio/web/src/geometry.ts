// Small rigid-transform and camera helpers (row-major 4x4 matrices as plain arrays).

import type { Mat4 } from './protocol';

export type Vec3 = [number, number, number];

export interface Camera {
  K: [number, number, number, number]; // fx, fy, cx, cy
  distortion: [number, number, number, number, number]; // k1, k2, p1, p2, k3 (OpenCV)
}

export function isMat4(value: unknown): value is Mat4 {
  return Array.isArray(value) && value.length === 16 && value.every((x) => typeof x === 'number' && Number.isFinite(x));
}

/** Applies a rigid transform to a point. */
export function transformPoint(T: Mat4, p: Vec3): Vec3 {
  return [
    T[0] * p[0] + T[1] * p[1] + T[2] * p[2] + T[3],
    T[4] * p[0] + T[5] * p[1] + T[6] * p[2] + T[7],
    T[8] * p[0] + T[9] * p[1] + T[10] * p[2] + T[11],
  ];
}

/** The camera centre in the model frame of T_camera_model: -R^T t. */
export function cameraCentre(T: Mat4): Vec3 {
  const t: Vec3 = [T[3], T[7], T[11]];
  return [
    -(T[0] * t[0] + T[4] * t[1] + T[8] * t[2]),
    -(T[1] * t[0] + T[5] * t[1] + T[9] * t[2]),
    -(T[2] * t[0] + T[6] * t[1] + T[10] * t[2]),
  ];
}

/** Row `i` of the rotation of T (for T_camera_model: the camera's axis i in model coordinates). */
export function rotationRow(T: Mat4, i: number): Vec3 {
  return [T[4 * i], T[4 * i + 1], T[4 * i + 2]];
}

/**
 * Projects a model point with T_camera_model, the pinhole K and the OpenCV
 * distortion; null when the point is not in front of the camera.
 * Pixel centres are at integer coordinates.
 */
export function projectPoint(T: Mat4, camera: Camera, p: Vec3): { u: number; v: number } | null {
  const [X, Y, Z] = transformPoint(T, p);
  if (Z <= 1e-9) return null;
  const x = X / Z;
  const y = Y / Z;
  const [k1, k2, p1, p2, k3] = camera.distortion;
  const r2 = x * x + y * y;
  const radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
  const yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  const [fx, fy, cx, cy] = camera.K;
  return { u: fx * xd + cx, v: fy * yd + cy };
}

export function sub(a: Vec3, b: Vec3): Vec3 {
  return [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
}

export function norm(a: Vec3): number {
  return Math.hypot(a[0], a[1], a[2]);
}

/** T_camera_model of a pose given as T_model_camera: quaternion (x, y, z, w) and the camera centre t. */
export function cameraModelFromPose(q: [number, number, number, number], t: Vec3): Mat4 {
  const [x, y, z, w] = q.map((v) => v / (Math.hypot(...q) || 1));
  // R = R_model_camera; T_camera_model = [R^T, -R^T t].
  const R = [
    [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
  ];
  const T: Mat4 = new Array(16).fill(0);
  for (let i = 0; i < 3; i++) {
    for (let k = 0; k < 3; k++) T[4 * i + k] = R[k][i];
    T[4 * i + 3] = -(R[0][i] * t[0] + R[1][i] * t[1] + R[2][i] * t[2]);
  }
  T[15] = 1;
  return T;
}
