// Convex polygon clipping in the camera frame (Sutherland-Hodgman), for the
// rare triangles that cross the near plane or leave the guard band.
// Internal to the rasteriser; no allocation (fixed arrays).
#pragma once

namespace st::raster {

struct ClipPoint {
  double x, y, z;  // camera frame, mm
};

// Inside where a x + b y + c z + d >= 0.
struct ClipPlane {
  double a, b, c, d;
  double distance(const ClipPoint& p) const { return a * p.x + b * p.y + c * p.z + d; }
};

// A triangle gains at most one vertex per plane (3 + 5); the arrays hold
// twice that so numerically degenerate cases never run out of room.
inline constexpr int kMaxClipPlanes = 5;
inline constexpr int kMaxClipVertices = 16;

// Clips the convex polygon poly[0..n) against every plane i with bit i set in
// plane_bits, in plane order, in place; returns the new vertex count (0 if
// nothing is left). A crossing point is always computed from the inside
// endpoint towards the outside one, so an edge shared by two triangles is
// cut at the bit-identical point in both (no cracks along clipped edges).
int clip_polygon(ClipPoint* poly, int n, const ClipPlane* planes, unsigned plane_bits);

}  // namespace st::raster
