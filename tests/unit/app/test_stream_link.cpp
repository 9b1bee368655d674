// The console's pose message from a tracker result (firmware_app/stream_link.h,
// pose_sample): a pose carried by the outline and the shading says so and
// what they saw; a lost frame says what they saw and carries no pose; a
// feature pose carries no outline evidence.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>

#include "firmware_app/stream_link.h"

using namespace st;

namespace {

TrackResult outline_result() {
  TrackResult r;
  r.state = TrackState::kTracking;
  r.pose_valid = true;
  r.T_camera_model = SE3(Mat3::Identity(), Vec3(1, 2, 150));
  r.outline_tried = true;
  r.by_outline = true;
  r.contour_lines = 187;
  r.contour_sigma_px = 2.4;
  r.joint_sigma_px = 0.3;
  r.modality_agreement_px = 1.9;
  return r;
}

}  // namespace

TEST_CASE("stream link: the console learns which modality carried a pose and what the outline saw") {
  FrameRef frame;
  frame.index = 30;
  const PoseSample p = app::pose_sample(frame, outline_result(), 4.0, 30.0);
  CHECK(p.state == TrackState::kTracking);
  CHECK(p.by_outline);
  CHECK(p.inliers == 0);
  CHECK(p.quality == 0.f);
  CHECK(p.outline_lines == 187);
  CHECK(p.outline_sigma_px == doctest::Approx(2.4));
  CHECK(p.joint_sigma_px == doctest::Approx(0.3));
  CHECK(p.outline_shading_px == doctest::Approx(1.9));
  CHECK(p.timestamp_ns == 1'000'000'000);
  CHECK(std::abs(p.t_mm[2] + 150.0) < 1e-9);  // T_model_camera: the camera centre

  // Lost: the outline was measured but too loose to fix anything; the
  // shading gave no pose to compare with.
  TrackResult lost = outline_result();
  lost.state = TrackState::kLost;
  lost.pose_valid = false;
  lost.by_outline = false;
  lost.contour_sigma_px = std::numeric_limits<double>::infinity();
  lost.joint_sigma_px = std::numeric_limits<double>::infinity();
  lost.modality_agreement_px = -1;
  const PoseSample l = app::pose_sample(frame, lost, 4.0, 30.0);
  CHECK(l.state == TrackState::kLost);
  CHECK_FALSE(l.by_outline);
  CHECK(l.outline_lines == 187);
  CHECK(l.outline_sigma_px == 1e6f);
  CHECK(l.joint_sigma_px == -1.f);
  CHECK(l.outline_shading_px == -1.f);

  // A feature pose: the outline was not measured.
  TrackResult features;
  features.state = TrackState::kTracking;
  features.pose_valid = true;
  features.inliers = 400;
  features.inlier_ratio = 0.8;
  features.T_camera_model = SE3(Mat3::Identity(), Vec3(0, 0, 100));
  const PoseSample f = app::pose_sample(frame, features, 4.0, 0.0);
  CHECK_FALSE(f.by_outline);
  CHECK(f.inliers == 400);
  CHECK(f.quality == doctest::Approx(0.8));
  CHECK(f.outline_lines == 0);
  CHECK(f.outline_sigma_px == -1.f);
  CHECK(f.timestamp_ns == 0);

  // A non-finite pose is never sent as one.
  TrackResult nan = outline_result();
  nan.T_camera_model = SE3(Mat3::Identity(), Vec3(std::nan(""), 0, 0));
  CHECK(app::pose_sample(frame, nan, 4.0, 30.0).state == TrackState::kLost);
  CHECK_FALSE(app::pose_sample(frame, nan, 4.0, 30.0).by_outline);
}
