#include "core/tracking/local_map_search.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "core/base/capacity.h"

namespace st {

namespace {
Vec3 camera_centre(const SE3& T_camera_model) {
  return -(T_camera_model.rotation().transpose() * T_camera_model.translation());
}
}  // namespace

Status LocalMapSearch::configure(int max_points, const CameraModel& camera, float scale_factor, int levels) {
  if (max_points < 1 || max_points > kMaxMapPoints || levels < 1 || levels > kMaxPyramidLevels ||
      !(scale_factor > 1.f))
    return make_error("local map search: " + std::to_string(max_points) + " points, " + std::to_string(levels) +
                      " levels out of range");
  camera_ = camera;
  K_ = camera.pinhole();
  distorted_ = !camera.distortion().is_zero();
  log_scale_ = std::log(static_cast<double>(scale_factor));
  levels_ = levels;
  octave_scale_.assign(static_cast<std::size_t>(kMaxPyramidLevels), 1.f);
  for (int o = 0; o < kMaxPyramidLevels; ++o)
    octave_scale_[static_cast<std::size_t>(o)] = std::pow(scale_factor, static_cast<float>(o));
  const auto np = static_cast<std::size_t>(max_points);
  ids_.assign(np, -1);
  projected_.assign(np, ProjectedPoint{});
  match_of_point_.assign(np, -1);
  dist_of_point_.assign(np, 0);
  searched_x_.assign(np, 0.f);
  searched_y_.assign(np, 0.f);
  search_active_.assign(np, 1);
  searched_valid_ = false;
  count_ = 0;
  return Status::Ok();
}

// The occlusion test reads the depth buffer at scattered pixels (0.9 MB at
// 1280x720's half-size raster, beyond the core's fastest caches): that read
// was ~60 % of this loop's samples. So a point that passes the cheap tests
// waits in a short queue while its depth is prefetched, and is tested and
// slotted when it leaves; the queue keeps id order, so the selection is the
// same as testing each point at once.
int LocalMapSearch::select(const TrackingMap& map, const SE3& T_camera_model, const MeshRasterizer* raster) {
  searched_valid_ = false;  // a new selection: no earlier search covers it
  const Vec3 centre = camera_centre(T_camera_model);
  const int capacity = static_cast<int>(projected_.size());
  const ImageView<const float> depth = raster ? raster->depth() : ImageView<const float>{};
  int n = 0;
  struct Pending {
    int id;
    double z_mm, dist;
    Vec2 ideal;
    const float* raster_depth;  // null: no occlusion test
  };
  constexpr int kQueue = 8;
  std::array<Pending, kQueue> queue;
  int head = 0, queued = 0;
  const auto admit = [&](const Pending& c) {
    if (n >= capacity) return;  // full: where the unqueued loop stopped
    if (c.raster_depth && !visible_at_depth(c.z_mm, *c.raster_depth)) return;
    const MapPoint& p = map.point(c.id);
    const int slot = n++;
    const Vec2 px = distorted_ ? camera_.distort_pixel(c.ideal) : c.ideal;
    const double ref = static_cast<double>(p.ref_distance_mm);
    const int octave =
        std::clamp(p.ref_octave + static_cast<int>(std::lround(std::log(ref / c.dist) / log_scale_)), 0, levels_ - 1);
    ProjectedPoint& q = projected_[static_cast<std::size_t>(slot)];
    q.x = static_cast<float>(px.x());
    q.y = static_cast<float>(px.y());
    q.predicted_octave = octave;
    q.ref_angle_deg = p.ref_angle_deg;
    q.descriptor = p.descriptor;
    ids_[static_cast<std::size_t>(slot)] = c.id;
  };
  for (int id = 0; id < map.point_high_water() && n < capacity; ++id) {
    const MapPoint& p = map.point(id);
    if (!p.alive) continue;
    const Vec3 p_camera = T_camera_model * p.p_model;
    if (p_camera.z() < 1.0) continue;
    const Vec3 ray = p.p_model - centre;
    const double dist = ray.norm(), ref = static_cast<double>(p.ref_distance_mm);
    if (dist < 0.4 * ref || dist > 2.5 * ref || ray.dot(p.view_dir_model) < 0.5 * dist) continue;
    const Vec2 ideal = K_.project(p_camera);
    if (!K_.in_image(ideal, 2.0)) continue;
    const float* raster_depth = nullptr;
    if (raster) {
      const Vec2 rp = raster->full_to_raster(ideal);
      const int x = static_cast<int>(std::lround(rp.x())), y = static_cast<int>(std::lround(rp.y()));
      if (!depth.contains(x, y)) continue;
      raster_depth = &depth(x, y);
      __builtin_prefetch(raster_depth);
    }
    if (queued == kQueue) {
      admit(queue[static_cast<std::size_t>(head)]);
      head = (head + 1) % kQueue;
      --queued;
    }
    queue[static_cast<std::size_t>((head + queued) % kQueue)] = Pending{id, p_camera.z(), dist, ideal, raster_depth};
    ++queued;
  }
  for (; queued > 0; --queued, head = (head + 1) % kQueue) admit(queue[static_cast<std::size_t>(head)]);
  count_ = n;
  return n;
}

void LocalMapSearch::reproject(const TrackingMap& map, const SE3& T_camera_model) {
  for (int i = 0; i < count_; ++i) {
    const auto is = static_cast<std::size_t>(i);
    const Vec3 p_camera = T_camera_model * map.point(ids_[is]).p_model;
    ProjectedPoint& q = projected_[is];
    if (p_camera.z() < 1.0) {
      q.x = q.y = -1e6f;  // behind the camera now: no candidate can match
      continue;
    }
    const Vec2 ideal = K_.project(p_camera);
    const Vec2 px = distorted_ ? camera_.distort_pixel(ideal) : ideal;
    q.x = static_cast<float>(px.x());
    q.y = static_cast<float>(px.y());
  }
}

void LocalMapSearch::search(float radius_px, const FeatureSet& features, const FeatureGrid& grid, OrbMatcher* matcher) {
  const bool prune = searched_valid_;
  const std::span<const std::uint16_t> best = matcher->best_distances();
  const int max_distance = matcher->config().max_distance;
  for (int i = 0; i < count_; ++i) {
    const auto is = static_cast<std::size_t>(i);
    ProjectedPoint& q = projected_[is];
    const float searched_radius = q.radius_px;  // the last search's (only this function sets it)
    q.radius_px = radius_px * octave_scale_[static_cast<std::size_t>(q.predicted_octave)];
    if (prune) {
      const float dx = q.x - searched_x_[is], dy = q.y - searched_y_[is];
      const float slack = searched_radius - q.radius_px - 1e-3f;  // how far the circle may move and stay inside
      const bool inside = slack >= 0.f && dx * dx + dy * dy <= slack * slack;
      search_active_[is] = !(inside && best[is] > max_distance);
    }
    searched_x_[is] = q.x;
    searched_y_[is] = q.y;
  }
  searched_valid_ = true;
  matcher->search_by_projection(projected_.data(), count_, features, grid, match_of_point_.data(),
                                dist_of_point_.data(), prune ? search_active_.data() : nullptr);
}

}  // namespace st
