// TrackingMap: the bounded map of the tracker. Two fixed pools sized once in
// configure(): map points (a model-frame point on the mesh surface, its ORB
// descriptor, viewing direction, distance range and usage counters) and
// keyframes (pose plus a compact copy of the keypoints that observed map
// points: position, angle, octave and the point's id).
//
// Memory never grows with sequence length: when a pool is full the least
// useful entries are culled (points: lowest found/visible ratio, then the
// longest unseen; keyframes: the oldest that is not the reference one).
//
// Why the points carry no per-observation lists: every point lies on the
// mesh (its position never changes, there is no triangulation), so the
// tracker only needs what makes matching and culling work: descriptor,
// scale range, viewing direction and counters.
//
// Thread: the tracking thread. configure() allocates; everything else
// allocates nothing.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/features/feature_set.h"
#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

struct MapPoint {
  Vec3 p_model = Vec3::Zero();         // mm, on the mesh surface
  // The reference observation: the keyframe observation the descriptor came
  // from (the creating one, or the latest keyframe inlier one: the
  // tracker's refresh_descriptors).
  Vec3 view_dir_model = Vec3::UnitZ(); // unit, from that camera centre to the point
  Descriptor descriptor{};
  float ref_distance_mm = 0.f;         // camera distance then
  float ref_angle_deg = 0.f;           // keypoint angle then (orientation check)
  std::int16_t ref_octave = 0;         // octave then (scale prediction)
  bool alive = false;
  int visible = 0;                     // frames it projected into the view
  int found = 0;                       // frames it was a pose inlier
  int last_seen_frame = -1;
  int created_frame = -1;
  bool anchored = true;                // made by a keyframe of a frame that passed the normal gates
};

// One keypoint of a keyframe linked to a map point.
struct KeyframeLink {
  std::int32_t point = -1;  // map point id
  std::int32_t point_created_frame = -1;  // the link is stale if the slot was reused since
  float x = 0.f, y = 0.f;   // level-0 (distorted) pixel
  float x_ideal = 0.f, y_ideal = 0.f;  // the same, undistorted (bundle adjustment)
  float angle_deg = 0.f;
  std::int16_t octave = 0;
};

struct Keyframe {
  SE3 T_camera_model;
  int frame = -1;
  int tracked_at_insertion = 0;  // links when inserted (reference for "tracked points fell")
  bool alive = false;
  int link_count = 0;
  KeyframeLink* links = nullptr;  // into the map's link pool, capacity = links_per_keyframe
};

class TrackingMap {
 public:
  // Sizes both pools (allocates). max_points in [1, kMaxMapPoints],
  // max_keyframes in [1, kMaxKeyframes], links_per_keyframe in [1, kMaxKeypoints].
  Status configure(int max_points, int max_keyframes, int links_per_keyframe);
  // Forgets every point and keyframe (keeps the pools).
  void clear();

  // A free point slot, culling the least useful points when the pool is
  // full; -1 only if every slot is protected (seen in protect_frame).
  int add_point(const MapPoint& p, int protect_frame);
  // A keyframe slot (the oldest keyframe other than keep_id is culled when
  // full), with its link array emptied.
  int add_keyframe(const SE3& T_camera_model, int frame, int keep_id);
  // Appends a link; false when the keyframe's link array is full.
  bool add_link(int keyframe_id, const KeyframeLink& link);

  MapPoint& point(int id) { return points_[static_cast<std::size_t>(id)]; }
  const MapPoint& point(int id) const { return points_[static_cast<std::size_t>(id)]; }
  Keyframe& keyframe(int id) { return keyframes_[static_cast<std::size_t>(id)]; }
  const Keyframe& keyframe(int id) const { return keyframes_[static_cast<std::size_t>(id)]; }

  int point_capacity() const { return static_cast<int>(points_.size()); }
  int keyframe_capacity() const { return static_cast<int>(keyframes_.size()); }
  int links_per_keyframe() const { return links_per_keyframe_; }
  int point_count() const { return point_count_; }
  int keyframe_count() const { return keyframe_count_; }
  // Ids of the alive points in slot order [0, high_water) (some may be dead).
  int point_high_water() const { return high_water_; }
  // The point a link refers to, or nullptr if it was culled since.
  const MapPoint* linked_point(const KeyframeLink& l) const {
    const MapPoint& p = points_[static_cast<std::size_t>(l.point)];
    return p.alive && p.created_frame == l.point_created_frame ? &p : nullptr;
  }
  // Points culled so far (diagnostics, tests).
  long culled_points() const { return culled_points_; }

 private:
  int cull_points(int protect_frame);
  double usefulness(const MapPoint& p) const;

  std::vector<MapPoint> points_;
  std::vector<Keyframe> keyframes_;
  std::vector<KeyframeLink> links_;
  std::vector<std::int32_t> free_points_;  // stack of free slots
  std::vector<std::int32_t> cull_order_;   // scratch: candidate ids
  std::vector<float> cull_score_;          // scratch: usefulness per slot
  int free_top_ = 0;
  int point_count_ = 0, keyframe_count_ = 0, high_water_ = 0;
  int links_per_keyframe_ = 0;
  int newest_frame_ = 0;
  long culled_points_ = 0;
};

}  // namespace st
