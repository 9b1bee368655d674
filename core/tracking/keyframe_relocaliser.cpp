#include "core/tracking/keyframe_relocaliser.h"

#include <algorithm>
#include <cmath>

namespace st {

Status KeyframeRelocaliser::configure(int width, int height) {
  if (width < 1 || height < 1) return make_error("relocaliser: bad frame size");
  width_ = width;
  height_ = height;
  train_ = std::make_unique<FeatureSet>();
  train_point_.assign(static_cast<std::size_t>(kMaxKeypoints), -1);
  match_of_query_.assign(static_cast<std::size_t>(kMaxKeypoints), -1);
  reset();
  return Status::Ok();
}

void KeyframeRelocaliser::reset() {
  order_count_ = 0;
  cursor_ = 0;
}

void KeyframeRelocaliser::rank(const TrackingMap& map, const SE3& T_last, double depth_mm) {
  const Vec3 centre = -(T_last.rotation().transpose() * T_last.translation());
  int n = 0;
  for (int id = 0; id < map.keyframe_capacity() && n < kMaxKeyframes; ++id)
    if (map.keyframe(id).alive) order_[static_cast<std::size_t>(n++)] = id;
  const auto cost = [&](int id) {
    const SE3& T = map.keyframe(id).T_camera_model;
    const Vec3 c = -(T.rotation().transpose() * T.translation());
    return (c - centre).norm() + depth_mm * pose_delta(T, T_last).angle_deg * M_PI / 180.0;
  };
  std::sort(order_.begin(), order_.begin() + n, [&](int a, int b) { return cost(a) < cost(b); });
  order_count_ = n;
  cursor_ = 0;
}

int KeyframeRelocaliser::next(const TrackingMap& map) {
  for (int tries = 0; tries < order_count_; ++tries) {
    const int id = order_[static_cast<std::size_t>(cursor_)];
    cursor_ = (cursor_ + 1) % order_count_;
    if (map.keyframe(id).alive) return id;
  }
  return -1;
}

int KeyframeRelocaliser::match(const TrackingMap& map, int keyframe_id, const FeatureSet& frame, int min_points,
                               OrbMatcher* matcher) {
  const Keyframe& kf = map.keyframe(keyframe_id);
  FeatureSet& train = *train_;
  train.clear();
  train.width = width_;
  train.height = height_;
  int n = 0;
  for (int i = 0; i < kf.link_count && n < kMaxKeypoints; ++i) {
    const KeyframeLink& l = kf.links[i];
    const MapPoint* p = map.linked_point(l);
    if (!p) continue;
    const auto ns = static_cast<std::size_t>(n++);
    train.keypoints[ns] = Keypoint{l.x, l.y, l.angle_deg, 0.f, l.octave};
    train.descriptors[ns] = p->descriptor;
    train_point_[ns] = l.point;
  }
  train.count = n;
  if (n < min_points) return n;
  matcher->match_brute_force(frame, train, match_of_query_.data(), nullptr);
  return n;
}

int KeyframeRelocaliser::matched_point(int q) const {
  const int m = match_of_query_[static_cast<std::size_t>(q)];
  return m < 0 ? -1 : train_point_[static_cast<std::size_t>(m)];
}

}  // namespace st
