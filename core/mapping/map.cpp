#include "core/mapping/map.h"

#include <algorithm>
#include <string>

#include "core/base/capacity.h"

namespace st {

Status TrackingMap::configure(int max_points, int max_keyframes, int links_per_keyframe) {
  if (max_points < 1 || max_points > kMaxMapPoints)
    return make_error("map: max_map_points " + std::to_string(max_points) + " outside [1, " +
                      std::to_string(kMaxMapPoints) + "]");
  if (max_keyframes < 1 || max_keyframes > kMaxKeyframes)
    return make_error("map: max_keyframes " + std::to_string(max_keyframes) + " outside [1, " +
                      std::to_string(kMaxKeyframes) + "]");
  if (links_per_keyframe < 1 || links_per_keyframe > kMaxKeypoints)
    return make_error("map: links per keyframe " + std::to_string(links_per_keyframe) +
                      " outside [1, " + std::to_string(kMaxKeypoints) + "]");
  const auto np = static_cast<std::size_t>(max_points);
  points_.assign(np, MapPoint{});
  free_points_.assign(np, 0);
  cull_order_.assign(np, 0);
  cull_score_.assign(np, 0.f);
  keyframes_.assign(static_cast<std::size_t>(max_keyframes), Keyframe{});
  links_per_keyframe_ = links_per_keyframe;
  links_.assign(static_cast<std::size_t>(max_keyframes) * static_cast<std::size_t>(links_per_keyframe),
                KeyframeLink{});
  for (int k = 0; k < max_keyframes; ++k)
    keyframes_[static_cast<std::size_t>(k)].links =
        links_.data() + static_cast<std::size_t>(k) * static_cast<std::size_t>(links_per_keyframe);
  clear();
  return Status::Ok();
}

void TrackingMap::clear() {
  const int n = point_capacity();
  for (int i = 0; i < n; ++i) {
    points_[static_cast<std::size_t>(i)].alive = false;
    // Stack popped from the top: the lowest slots are used first.
    free_points_[static_cast<std::size_t>(i)] = n - 1 - i;
  }
  free_top_ = n;
  for (Keyframe& k : keyframes_) {
    k.alive = false;
    k.link_count = 0;
  }
  point_count_ = keyframe_count_ = high_water_ = 0;
  culled_points_ = 0;
}

// Higher is more useful: the share of frames in which the point was found
// when it should have been visible, discounted by how long it was not seen.
double TrackingMap::usefulness(const MapPoint& p) const {
  const double ratio = (p.found + 1.0) / (p.visible + 2.0);
  const double age = std::max(0, newest_frame_ - p.last_seen_frame);
  return ratio / (1.0 + age / 100.0);
}

// Frees the least useful ~10% of the pool (never points seen in
// protect_frame). Returns how many were freed.
int TrackingMap::cull_points(int protect_frame) {
  int n = 0;
  for (int i = 0; i < high_water_; ++i) {
    const MapPoint& p = points_[static_cast<std::size_t>(i)];
    if (!p.alive || p.last_seen_frame >= protect_frame) continue;
    cull_score_[static_cast<std::size_t>(i)] = static_cast<float>(usefulness(p));
    cull_order_[static_cast<std::size_t>(n++)] = i;
  }
  if (n == 0) return 0;
  const int k = std::clamp(point_capacity() / 10, 1, n);
  const auto score = [this](std::int32_t a, std::int32_t b) {
    return cull_score_[static_cast<std::size_t>(a)] < cull_score_[static_cast<std::size_t>(b)];
  };
  std::nth_element(cull_order_.begin(), cull_order_.begin() + (k - 1), cull_order_.begin() + n, score);
  for (int j = 0; j < k; ++j) {
    const int id = cull_order_[static_cast<std::size_t>(j)];
    points_[static_cast<std::size_t>(id)].alive = false;
    free_points_[static_cast<std::size_t>(free_top_++)] = id;
    --point_count_;
    ++culled_points_;
  }
  return k;
}

int TrackingMap::add_point(const MapPoint& p, int protect_frame) {
  newest_frame_ = std::max(newest_frame_, protect_frame);
  if (free_top_ == 0 && cull_points(protect_frame) == 0) return -1;
  const int id = free_points_[static_cast<std::size_t>(--free_top_)];
  MapPoint& slot = points_[static_cast<std::size_t>(id)];
  slot = p;
  slot.alive = true;
  ++point_count_;
  high_water_ = std::max(high_water_, id + 1);
  return id;
}

int TrackingMap::add_keyframe(const SE3& T_camera_model, int frame, int keep_id) {
  int slot = -1, oldest = -1;
  for (int k = 0; k < keyframe_capacity(); ++k) {
    const Keyframe& kf = keyframes_[static_cast<std::size_t>(k)];
    if (!kf.alive) {
      slot = k;
      break;
    }
    if (k != keep_id && (oldest < 0 || kf.frame < keyframes_[static_cast<std::size_t>(oldest)].frame))
      oldest = k;
  }
  if (slot < 0) {
    if (oldest < 0) return -1;  // a single-slot pool holding the protected keyframe
    slot = oldest;
    --keyframe_count_;
  }
  Keyframe& kf = keyframes_[static_cast<std::size_t>(slot)];
  kf.T_camera_model = T_camera_model;
  kf.frame = frame;
  kf.tracked_at_insertion = 0;
  kf.alive = true;
  kf.link_count = 0;
  ++keyframe_count_;
  return slot;
}

bool TrackingMap::add_link(int keyframe_id, const KeyframeLink& link) {
  Keyframe& kf = keyframes_[static_cast<std::size_t>(keyframe_id)];
  if (kf.link_count >= links_per_keyframe_) return false;
  kf.links[kf.link_count++] = link;
  return true;
}

}  // namespace st
