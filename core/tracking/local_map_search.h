// The local map of a frame and its search by projection: the map points
// the camera can see at a pose (in front, inside the image, within the
// scale range and 60 degrees of the view that made them, not hidden behind
// the mesh), projected into the frame with their predicted octave, and
// matched to the frame's keypoints within a radius that grows with the
// octave. The tracker selects once at the prediction, searches, and
// searches again after the pose moved (reproject keeps the selection).
//
// Thread: the tracking thread. configure() sizes every array; select(),
// reproject() and search() allocate nothing.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/base/result.h"
#include "core/features/feature_grid.h"
#include "core/features/feature_set.h"
#include "core/features/orb_matcher.h"
#include "core/geometry/camera.h"
#include "core/mapping/map.h"
#include "core/raster/rasterizer.h"

namespace st {

// "This point is the visible surface" at a render's depth: within 3 % plus
// 2 mm (raster quantisation, a prediction a few mm off).
inline bool visible_at_depth(double z_mm, float raster_depth_mm) {
  return raster_depth_mm > 0.f && z_mm <= 1.03 * static_cast<double>(raster_depth_mm) + 2.0;
}

class LocalMapSearch {
 public:
  // max_points: the map's point pool; scale_factor and levels: the ORB
  // pyramid's (octave prediction and radii).
  Status configure(int max_points, const CameraModel& camera, float scale_factor, int levels);

  // Selects the local map at T_camera_model. raster: a render near that
  // pose for the occlusion test (nullptr: no test). Returns its size.
  int select(const TrackingMap& map, const SE3& T_camera_model, const MeshRasterizer* raster);
  // Moves the selection to T_camera_model without repeating its tests.
  void reproject(const TrackingMap& map, const SE3& T_camera_model);
  // Search by projection, radius_px scaled by each point's predicted
  // octave. A point whose circle lies inside the one its last search of
  // this selection covered, and which found no candidate within the
  // matcher's max_distance there, is not searched again (its candidates
  // are a subset: the matches are the same).
  void search(float radius_px, const FeatureSet& features, const FeatureGrid& grid, OrbMatcher* matcher);

  int size() const { return count_; }
  int point_id(int i) const { return ids_[static_cast<std::size_t>(i)]; }
  // The keypoint the last search matched to point i of the selection (-1: none).
  int match(int i) const { return match_of_point_[static_cast<std::size_t>(i)]; }

 private:
  CameraModel camera_;
  Pinhole K_;
  bool distorted_ = false;
  double log_scale_ = 0;
  int levels_ = 1;
  std::vector<float> octave_scale_;        // per octave: scale_factor^octave
  std::vector<std::int32_t> ids_;          // map point of each selected slot
  std::vector<ProjectedPoint> projected_;  // their projections at the current pose
  std::vector<std::int32_t> match_of_point_, dist_of_point_;
  // Where the last search of this selection looked (its radii stay in
  // projected_) and, for the next one, which points still need it.
  std::vector<float> searched_x_, searched_y_;
  std::vector<std::uint8_t> search_active_;
  bool searched_valid_ = false;  // the arrays describe the last search of the current selection
  int count_ = 0;
};

}  // namespace st
