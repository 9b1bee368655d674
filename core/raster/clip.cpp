#include "core/raster/clip.h"

namespace st::raster {
namespace {

ClipPoint crossing(const ClipPoint& in, double d_in, const ClipPoint& out, double d_out) {
  const double t = d_in / (d_in - d_out);
  return {in.x + t * (out.x - in.x), in.y + t * (out.y - in.y), in.z + t * (out.z - in.z)};
}

int clip_one(const ClipPoint* src, int n, const ClipPlane& plane, ClipPoint* dst) {
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const ClipPoint& a = src[i];
    const ClipPoint& b = src[i + 1 == n ? 0 : i + 1];
    const double da = plane.distance(a), db = plane.distance(b);
    const bool a_in = da >= 0.0, b_in = db >= 0.0;
    // A convex polygon crosses a plane twice at most (m <= 8); the guard
    // only matters for numerically degenerate input.
    if (m + 2 > kMaxClipVertices) break;
    if (a_in) dst[m++] = a;
    if (a_in && !b_in) dst[m++] = crossing(a, da, b, db);
    if (!a_in && b_in) dst[m++] = crossing(b, db, a, da);
  }
  return m;
}

}  // namespace

int clip_polygon(ClipPoint* poly, int n, const ClipPlane* planes, unsigned plane_bits) {
  ClipPoint tmp[kMaxClipVertices];
  for (int p = 0; p < kMaxClipPlanes && n >= 3; ++p) {
    if (!(plane_bits & (1u << p))) continue;
    n = clip_one(poly, n, planes[p], tmp);
    for (int i = 0; i < n; ++i) poly[i] = tmp[i];
  }
  return n >= 3 ? n : 0;
}

}  // namespace st::raster
