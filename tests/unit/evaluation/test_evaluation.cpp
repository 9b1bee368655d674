#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>

#include "core/evaluation/evaluation.h"

using namespace st;

namespace {

CameraModel test_camera() {
  Distortion d;
  d.count = 5;
  d.k = {-0.2, 0.05, 0, 0, 0, 0, 0, 0};
  return CameraModel(Pinhole{800, 800, 479.5, 269.5, 960, 540}, d);
}

// Camera 100 mm in front of the origin, looking at it, slowly moving.
SE3 gt_pose(int i) {
  const Vec3 eye(10.0 * std::sin(0.05 * i), -5.0, -100.0 + 0.2 * i);
  return SE3(so3_exp(Vec3(0.0, 0.02 * std::sin(0.1 * i), 0.0)), eye);  // T_model_camera
}

EvalInput make_input(int frames) {
  EvalInput in;
  in.frames = frames;
  in.camera = test_camera();
  in.markers_model = {Vec3(-20, -10, 0), Vec3(15, 5, 5), Vec3(0, 20, -3)};
  for (int i = 0; i < frames; ++i) {
    in.groundtruth.push_back(gt_pose(i));
    in.estimated.push_back(gt_pose(i));
  }
  return in;
}

}  // namespace

TEST_CASE("evaluating the ground truth itself gives TRE 0 and lost 0") {
  const EvalResult r = evaluate(make_input(60));
  CHECK(r.frames == 60);
  CHECK(r.reported_frames == 60);
  CHECK(r.init_ok);
  CHECK(r.lost_pct == 0.0);
  CHECK(r.wrong_pct == 0.0);
  CHECK(r.tre_samples == 180);
  CHECK(r.tre_max_px < 1e-9);
  CHECK(r.rot_err_median_deg < 1e-9);
  CHECK(r.rot_err_max_deg < 1e-9);
  CHECK(r.trans_err_median_mm < 1e-9);
}

TEST_CASE("evaluation of a perturbed trajectory with missing frames matches an independent count") {
  EvalInput in = make_input(50);
  // Frames 0-6 missing (init fails), every 10th missing, frames 20-24 shifted
  // by 2 mm sideways, frame 30 grossly wrong (rotated 30 deg).
  for (int i = 0; i < 7; ++i) in.estimated[i].reset();
  for (int i = 10; i < 50; i += 10) in.estimated[i].reset();
  for (int i = 20; i < 25; ++i)
    if (in.estimated[i]) in.estimated[i]->translation() += Vec3(2.0, 0, 0);
  in.estimated[31] = SE3(so3_exp(Vec3(0, 0.5236, 0)), in.groundtruth[31]->translation()) ;
  const EvalResult r = evaluate(in);

  // Independent expectations: 7 + 4 missing (10,20,30,40) = 11 lost of 50.
  CHECK(r.reported_frames == 39);
  CHECK_FALSE(r.init_ok);
  CHECK(r.lost_pct == doctest::Approx(22.0));
  // 2 mm sideways at ~100 mm depth with f = 800 is ~16 px: below 50 px, so
  // not wrong; the 30 deg rotation is far beyond 50 px: one wrong frame.
  CHECK(r.wrong_frames == 1);
  CHECK(r.wrong_pct == doctest::Approx(2.0));
  // Frames 21-24 are shifted (20 is missing): 4 frames x 3 markers with
  // errors of ~16 px, one wrong frame, the rest exact. The median is 0.
  CHECK(r.tre_median_px < 1e-9);
  int shifted = 0;
  for (int i = 21; i < 25; ++i) {
    for (const Vec3& m : in.markers_model) {
      Vec2 a, b;
      REQUIRE(project_marker(in.camera, *in.groundtruth[i], m, &a));
      REQUIRE(project_marker(in.camera, *in.estimated[i], m, &b));
      CHECK((a - b).norm() > 10.0);
      CHECK((a - b).norm() < 25.0);
      ++shifted;
    }
  }
  CHECK(shifted == 12);
  CHECK(r.tre_samples == 39 * 3);
  CHECK(r.tre_p95_px > 10.0);
  CHECK(r.trans_err_median_mm < 1e-9);
  // The largest rotation error is frame 31's: its rotation replaced by 30 deg about y.
  const Eigen::AngleAxisd frame31(in.groundtruth[31]->rotation().transpose() * in.estimated[31]->rotation());
  CHECK(r.rot_err_max_deg == doctest::Approx(frame31.angle() * 180.0 / M_PI));
  CHECK(r.rot_err_max_deg > 25.0);
}

TEST_CASE("a marker the estimate puts behind the camera is a wrong frame, not a missing one") {
  EvalInput in = make_input(10);
  in.estimated[3] = SE3(so3_exp(Vec3(0, M_PI, 0)), in.groundtruth[3]->translation());
  const EvalResult r = evaluate(in);
  CHECK(r.wrong_frames == 1);
  CHECK(r.tre_max_px == kBehindCameraTrePx);
  CHECK(std::isfinite(r.tre_mean_px));
}

TEST_CASE("timestamps map to frames within a quarter period") {
  CHECK(frame_for_timestamp(0.0, 30.0, 10) == 0);
  CHECK(frame_for_timestamp(3.0 / 30.0 + 1e-9, 30.0, 10) == 3);
  CHECK(frame_for_timestamp(3.5 / 30.0, 30.0, 10) == -1);
  CHECK(frame_for_timestamp(10.0 / 30.0, 30.0, 10) == -1);
  CHECK(frame_for_timestamp(-1.0 / 30.0, 30.0, 10) == -1);
  CHECK(frame_for_timestamp(NAN, 30.0, 10) == -1);
  CHECK(frame_for_timestamp(0.1, 0.0, 10) == -1);
}
