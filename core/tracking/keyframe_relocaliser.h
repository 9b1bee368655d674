// The relocaliser's candidates when lost: the keyframes ranked by how
// close their view is to the last good pose (camera centre distance plus
// viewing angle at the last tracked depth: the scope most often comes back
// near where it was lost), handed out one at a time, cycling; and the
// frame's keypoints matched by brute force to one keyframe's map points
// (the descriptors those points carry). The tracker turns the matches into
// a P3P RANSAC pose and tracks from it (tracker_reloc.cpp).
//
// Thread: the tracking thread. configure() allocates the keyframe's
// feature set and the index arrays; nothing else allocates.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/base/capacity.h"
#include "core/base/result.h"
#include "core/features/feature_set.h"
#include "core/features/orb_matcher.h"
#include "core/mapping/map.h"

namespace st {

class KeyframeRelocaliser {
 public:
  // width, height: the frame size (the keyframe's feature set's).
  Status configure(int width, int height);
  // Forgets the ranking (the next lost spell ranks again) and the cursor.
  void reset();
  void forget_ranking() { order_count_ = 0; }
  bool ranked() const { return order_count_ > 0; }

  // Ranks the alive keyframes against T_last (depth_mm: the last tracked
  // depth, which turns the viewing angle into a distance).
  void rank(const TrackingMap& map, const SE3& T_last, double depth_mm);
  // The next keyframe of the ranking (cycling), skipping culled ones; -1
  // when there is none.
  int next(const TrackingMap& map);

  // Matches frame's keypoints to the map points keyframe_id links, by
  // brute force, when it links at least min_points of them. Returns how
  // many it links (no matching below min_points).
  int match(const TrackingMap& map, int keyframe_id, const FeatureSet& frame, int min_points, OrbMatcher* matcher);
  // After match(): the map point frame's keypoint q matched (-1: none).
  int matched_point(int q) const;

 private:
  int width_ = 0, height_ = 0;
  std::unique_ptr<FeatureSet> train_;            // the keyframe's map points as features
  std::vector<std::int32_t> train_point_;        // map point of each train_ keypoint
  std::vector<std::int32_t> match_of_query_;     // per frame keypoint: train_ index or -1
  std::array<std::int32_t, kMaxKeyframes> order_{};  // keyframes by closeness to the last pose
  int order_count_ = 0;
  int cursor_ = 0;
};

}  // namespace st
